"""The paper's Tables 4, 5 and 8 on one READ training (readjax.lab.protocol_tables): each cell is the
run's evaluation from the oracle's i-th neighbour at that N (refined with the setting chosen on the
validation split first), beside the paper's row, and each refinement is paired against its own start."""

import json

import pytest

from readjax import tasks
from readjax.lab import main_table, paper, protocol_tables
from readjax.lab.report import collect
from tests.test_main_table import _write

T, F = True, False


def test_the_papers_rows_average_to_what_it_printed():
    """Within 0.1: the paper cuts some averages off rather than rounding them (Table 4, READ (i = 3): its
    rows' Avg16 is 70.69, printed 70.6)."""
    for rows, printed in ((paper.TABLE4_READ, paper.TABLE4_READ_AVERAGES), (paper.TABLE8, paper.TABLE8_AVERAGES)):
        for key, row in rows.items():
            assert list(row) == list(tasks.AVG16)
            for name, codes in (("Avg12", tasks.AVG12), ("Avg16", tasks.AVG16)):
                assert paper.mean_over(row, codes) == pytest.approx(printed[key][name], abs=0.1)


def test_cells_pairs_and_the_chosen_refinement(tmp_path):
    runs = tmp_path / "results"
    refinement = main_table.refinement_of("cpu")
    _write(runs, "reach_target", "read_s2", "cheat1_N0", [T] * 6 + [F] * 4, N=0, retrieval="cheat", rank=1)
    _write(runs, "reach_target", "read_s2", "cheat1_N100", [T] * 9 + [F], retrieval="cheat", rank=1)
    # refined with another setting, chosen on val: taken before the preset's
    _write(runs, "reach_target", "read_s2", "cheat1_N100_chosen", [T] * 10, retrieval="cheat", rank=1,
           refine_update="renoise", rounds=1)
    f = runs / "reach_target" / "read_s2" / "eval" / "cheat1_N100_chosen.json"
    f.write_text(json.dumps(dict(json.loads(f.read_text()), chosen_on="val",
                                 choice={"chosen": {"refine": "renoise", "rounds": 1, "candidates": 1}})))
    _write(runs, "reach_target", "read_s2", "cheat500_N0", [F] * 10, N=0, retrieval="cheat", rank=500)
    _write(runs, "reach_target", "read_s2", "cheat500_N1", [T] * 2 + [F] * 8, N=1, retrieval="cheat", rank=500)
    _write(runs, "reach_target", "read_s2", "cheat500_N100", [T] * 7 + [F] * 3, retrieval="cheat", rank=500)
    _write(runs, "reach_target", "read_s2", "spe_N100", [F] * 10)  # SPE's start: not a protocol cell
    _write(runs, "reach_target", "other", "cheat3_N0", [T] * 10, N=0, retrieval="cheat", rank=3)  # another run
    results = collect(runs)
    text = "\n".join(protocol_tables.lines(results, "read_s2", refinement))
    assert "| row | RT | Avg (k) | Avg12 | Avg16 |" in text  # only the tasks the run has
    assert "| Cheat (i = 1), N = 0 | 60 / 96 | 60.0 / 96.0 (1) | – / 79.5 | – / 60.6 |" in text
    assert "| READ (i = 1), N = 100 | 100 / 100 | 100.0 / 100.0 (1) | – / 88.6 | – / 70.4 |" in text
    assert "| Cheat (i = 3), N = 0 | – / 81 | – | – / 64.1 | – / 48.7 |" in text
    assert "| READ (i = 500), N = 1 | 20 / 73 |" in text and "| READ (i = 500), N = 100 | 70 / 99 |" in text
    # refinement against its own start: i = 1 N = 100 solves 4 the start misses; i = 500: 7 and 2
    assert "| READ (i = 1), N = 100 | Cheat (i = 1), N = 0 | +4 / -0 | +4 / -0, p=0.12 |" in text
    assert "| READ (i = 500), N = 100 | READ (i = 500), N = 0 | +7 / -0 | +7 / -0, p=0.016 |" in text
    assert "| READ (i = 3), N = 100 | Cheat (i = 3), N = 0 | – | – |" in text
    assert protocol_tables.lines(results, "nobody", refinement) == []
