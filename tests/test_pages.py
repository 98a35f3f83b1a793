"""Generated pages equal what results/ says: each page rebuilt from the committed results/ in a copy of
the repository is the committed page, character for character (README.md: its generated blocks; the rest
of it is written by hand and copied as it is)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from readjax.lab import pages, readme_tables

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module")
def rebuilt(tmp_path_factory):
    copy = tmp_path_factory.mktemp("repo")
    shutil.copytree(ROOT / "results", copy / "results")
    (copy / "docs").mkdir()
    shutil.copy(ROOT / "README.md", copy / "README.md")
    return copy, pages.regenerate(copy)


@pytest.mark.parametrize("page", list(pages.PAGES))
def test_committed_page_is_what_results_say(rebuilt, page):
    copy, texts = rebuilt
    committed = (ROOT / page).read_text()
    assert texts[page] == (copy / page).read_text()
    assert committed == texts[page], (f"{page} differs from what results/ says: run "
                                      f"`python -m experiments.report --pages` and commit the pages")


def test_the_count_of_result_files_is_read_from_the_folder(rebuilt):
    _, texts = rebuilt
    n = len(list((ROOT / "results").glob("*/*/eval/*.json")))
    assert f"({n} files:" in texts["results/README.md"]


def test_the_readme_tables_are_filled_from_results(rebuilt):
    _, texts = rebuilt
    text = texts["README.md"]
    for marker in (readme_tables.MAIN_BLOCK, readme_tables.BASELINES_BLOCK):
        block = text.split(marker + "\n", 1)[1].split(readme_tables.END, 1)[0]
        assert block.startswith("| success %"), marker
    main = text.split(readme_tables.MAIN_BLOCK, 1)[1].split(readme_tables.END, 1)[0]
    assert f"| READ, N = 100 | {pages.MAIN_SUITE} |" in main  # each row says its suite
    assert "Avg12" in main and "Avg16" in main


def test_a_stale_readme_block_is_replaced_and_the_rest_kept():
    text = f"intro\n{readme_tables.MAIN_BLOCK}\n| old | table |\n{readme_tables.END}\noutro\n"
    out = readme_tables.splice(text, readme_tables.MAIN_BLOCK, ["| new |"])
    assert out == f"intro\n{readme_tables.MAIN_BLOCK}\n| new |\n{readme_tables.END}\noutro\n"
    with pytest.raises(ValueError, match="no block"):
        readme_tables.splice("no markers here", readme_tables.MAIN_BLOCK, ["| new |"])
