"""Table 7's layout for a sweep: each cell against the paper's setting A on the same episodes."""

from __future__ import annotations

import json

from readjax.lab import sweep_cells, sweep_grid, sweep_table
from readjax.lab.claims import VERSION_MARK


def _cell(n, outcomes, **kw):
    return {**sweep_grid.DEFAULTS, "N": n, **kw, "success": sum(outcomes) / len(outcomes),
            "seeds": list(range(len(outcomes))), "outcomes": outcomes}


def test_cells_are_paired_with_setting_a(tmp_path):
    sw = {"task": "reach_target", "code": "RT", "model": "read", "grid": {"N": [0, 1, 100]}, "episodes": 10,
          "cells": [_cell(0, [0] * 10), _cell(1, [1] * 5 + [0] * 5), _cell(100, [1] * 10)]}
    lines = sweep_table.format_table7(sw).splitlines()
    assert lines[0] == "| setting | N | K | L | T | RT | vs A |"
    assert lines[2] == "| B | 0 | 3 | 0.5 | 2 | 0.0 | +0 / -10, p=0.002 |"
    assert lines[3] == "| C | 1 | 3 | 0.5 | 2 | 50.0 | +0 / -5, p=0.062 |"
    assert lines[4] == "| A (default) | 100 | 3 | 0.5 | 2 | 100.0 | – |"
    # a sweep recorded before the outcomes were (or without setting A): no paired column
    old = {**sw, "cells": [{k: v for k, v in c.items() if k not in ("seeds", "outcomes")} for c in sw["cells"]]}
    assert "vs A" not in sweep_table.format_table7(old)
    no_a = {**sw, "cells": sw["cells"][:2]}
    assert "vs A" not in sweep_table.format_table7(no_a)
    sweep_table.write_sweep(sw, tmp_path / "results" / "reach_target" / "sweep")
    folder = tmp_path / "results" / "reach_target" / "sweep"
    assert json.loads((folder / "sweep.json").read_text()) == sw
    assert (folder / "table.md").read_text() == sweep_table.format_table7(sw) and (folder / "sweep.png").stat().st_size > 0


def test_pairs_across_versions_of_the_test_split_are_marked():
    """A cell measured on another version of the split (same seeds, another CPU's float rounding) is
    paired with A by seed as before, and marked, with a note saying what differs."""
    cells = [_cell(1, [1] * 5 + [0] * 5, test_fingerprint="a" * 16),
             _cell(0, [0] * 10, test_fingerprint="b" * 16), _cell(100, [1] * 10, test_fingerprint="a" * 16)]
    sw = {"task": "reach_target", "code": "RT", "model": "read", "grid": {"N": [0, 1, 100]}, "episodes": 10,
          "cells": cells}
    text = sweep_table.format_table7(sw)
    lines = text.splitlines()
    assert lines[2] == "| B | 1 | 3 | 0.5 | 2 | 50.0 | +0 / -5, p=0.062 |"
    assert lines[3] == f"| C | 0 | 3 | 0.5 | 2 | 0.0 | +0 / -10, p=0.002 {VERSION_MARK} |"
    assert text.count(VERSION_MARK) == 2 and "different versions of the test split" in text
    same = {**sw, "cells": [cells[0], cells[2]]}
    assert VERSION_MARK not in sweep_table.format_table7(same)


def test_committed_cells_on_another_split_version_are_kept_only_when_asked(tmp_path):
    """A fresh machine whose CPU regenerates the test split at another float rounding: by default its
    committed cells do not count (they train again); with ``other_versions`` the cells on the same
    seeds do, each keeping its own fingerprint. Cells on other seeds never do."""
    class _Split:
        fingerprint = "c" * 16
        seeds = list(range(10))
    folder = tmp_path / "results" / "reach_target" / "table7"
    cells = [_cell(100, [1] * 10, test_fingerprint="d" * 16), _cell(1, [1] * 10, test_fingerprint="c" * 16),
             {**_cell(0, [0] * 10, test_fingerprint="d" * 16), "seeds": list(range(1, 11))}]
    sweep_table.write_sweep({"task": "reach_target", "code": "RT", "model": "read", "grid": {"N": [0, 1, 100]},
                       "episodes": 10, "cells": cells}, folder)
    strict = sweep_cells.committed_cells(folder, _Split())
    assert list(strict) == [(1, 3, 0.5, 2.0)]
    loose = sweep_cells.committed_cells(folder, _Split(), other_versions=True)
    assert sorted(loose) == [(1, 3, 0.5, 2.0), (100, 3, 0.5, 2.0)]
    assert loose[(100, 3, 0.5, 2.0)]["test_fingerprint"] == "d" * 16


def test_setting_a_is_the_sweeps_own_preset(tmp_path):
    """A sweep under the cpu preset (K = 50) is paired against its own preset's setting, and a cell
    trained with the paper's K = 3 is one of its departures, not A."""
    ref = {"N": 100, "K": 50, "L": 0.5, "T": 2.0}
    sw = {"task": "push_button", "code": "PB", "model": "read", "grid": {"K": [3, 50]}, "episodes": 4,
          "reference": ref, "cells": [_cell(100, [1, 0, 0, 0], K=3), _cell(100, [1, 1, 1, 1], K=50)]}
    lines = sweep_table.format_table7(sw).splitlines()
    assert lines[2] == "| B | 100 | 3 | 0.5 | 2 | 25.0 | +0 / -3, p=0.25 |"
    assert lines[3] == "| A (default) | 100 | 50 | 0.5 | 2 | 100.0 | – |"
    # settings after A go on from where the letters before it stopped
    later = {**sw, "cells": sw["cells"][::-1] + [_cell(100, [0, 1, 1, 1], K=10)]}
    assert [ln.split(" | ")[0] for ln in sweep_table.format_table7(later).splitlines()[2:]] == ["| A (default)", "| B", "| C"]


def test_table7_settings_vary_one_key_at_a_time():
    ref = {"N": 100, "K": 50, "L": 0.5, "T": 2.0}
    grid = {"N": [1, 100], "K": [1, 3], "L": [0.1, 0.5], "T": [0.1]}
    assert sweep_grid.cell_settings(grid, ref, "one") == [
        {"K": 50, "L": 0.5, "T": 2.0}, {"K": 1, "L": 0.5, "T": 2.0}, {"K": 3, "L": 0.5, "T": 2.0},
        {"K": 50, "L": 0.1, "T": 2.0}, {"K": 50, "L": 0.5, "T": 0.1}]
    assert len(sweep_grid.cell_settings(grid, ref, "all")) == 4
    assert sweep_grid.cell_settings({"N": [1]}, ref, "one") == [{}]


def test_a_reference_runs_evaluation_is_reused_only_for_the_same_cell(tmp_path):
    """Another N, another refinement, another episode count or other episodes: evaluated anew."""
    from readjax.lab.sweep_cells import reusable_evaluation

    sde = {"update": "cold_anchor", "rounds": 2}
    base = {"method": "read", "episodes": 3, "test_fingerprint": "abc", "configs": {"sde": sde},
            "eval_config": {"N": 10, "retrieval": "spe", "rank": 1, "candidates": 1, "rounds": 2,
                            "refine_update": "cold_anchor", "image_noise": 0.0, "brightness": 1.0}}
    test_ds = type("DS", (), {"fingerprint": "abc", "__len__": lambda self: 3})()
    (tmp_path / "eval").mkdir()
    f = tmp_path / "eval" / "x.json"
    f.write_text(json.dumps(base))
    assert reusable_evaluation(tmp_path, "read", 10, test_ds)["reused_from"] == str(f)
    assert reusable_evaluation(tmp_path, "read", 100, test_ds) is None
    assert reusable_evaluation(tmp_path, "read_o", 10, test_ds) is None
    for change in ({"episodes": 4}, {"test_fingerprint": "abd"},
                   {"eval_config": {**base["eval_config"], "rounds": 1}},
                   {"eval_config": {**base["eval_config"], "image_noise": 0.05}}):
        f.write_text(json.dumps({**base, **change}))
        assert reusable_evaluation(tmp_path, "read", 10, test_ds) is None, change


def test_cells_say_why_a_setting_loses_starts_and_failure_modes():
    """A cell keeps its evaluation's failure counts and per-episode starts; the table counts the
    episodes solved from near (< 3 cm), middling and far (> 10 cm) starts, and lists the failures by
    mode, most frequent first. An evaluation without failure records adds nothing."""
    result = {"failures": {"counts": {"depth": 1, "wrong place": 2},
                           "start_keyframe_error_cm": [1.0, 2.9, 3.0, 9.9, 10.0, 50.0]}}
    diag = sweep_cells.cell_diagnostics(result)
    assert diag == {"failure_modes": {"depth": 1, "wrong place": 2}, "start_error_cm": [1.0, 2.9, 3.0, 9.9, 10.0, 50.0]}
    assert sweep_cells.cell_diagnostics({}) == {}
    a = {**_cell(100, [1, 1, 1, 0, 0, 0]), **diag}
    assert sweep_table.solved_by_start(a) == "2/2, 1/2, 0/2"
    b = {**_cell(1, [1, 1, 1, 1, 1, 1]), "failure_modes": {}, "start_error_cm": diag["start_error_cm"]}
    sw = {"task": "reach_target", "code": "RT", "model": "read", "grid": {"N": [1, 100]}, "episodes": 6,
          "cells": [b, a]}
    lines = sweep_table.format_table7(sw).splitlines()
    assert lines[0].endswith("| vs A | solved from starts < 3 / 3-10 / > 10 cm | failures by mode |")
    assert lines[2].endswith("| 2/2, 2/2, 2/2 | none |")
    assert lines[3].endswith("| – | 2/2, 1/2, 0/2 | wrong place 2, depth 1 |")
    old = {**sw, "cells": [_cell(1, [1] * 6), _cell(100, [1] * 6)]}
    assert "failures by mode" not in sweep_table.format_table7(old) and "starts" not in sweep_table.format_table7(old)
