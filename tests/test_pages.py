"""Generated pages equal what results/ says: each page rebuilt from the committed results/ in a copy of
the repository is the committed page, character for character."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from readjax.lab import pages

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module")
def rebuilt(tmp_path_factory):
    copy = tmp_path_factory.mktemp("repo")
    shutil.copytree(ROOT / "results", copy / "results")
    (copy / "docs").mkdir()
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
