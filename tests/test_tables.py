"""Success tables: percentages in the paper's column order, averages only over complete sets."""

import pytest

from readjax import tables, tasks


def test_success_table_averages_only_complete_sets():
    partial = tables.success_table({"reach_target": 0.65, "pick_up_cup": 1.0})
    assert list(partial) == ["PC", "RT", "Avg"]  # the paper's order, not the input's
    assert partial["RT"] == pytest.approx(65.0) and partial["Avg"] == pytest.approx(82.5)
    twelve = tables.success_table({t: 0.5 for t in tasks.names() if tasks.code_of(t) in tables.AVG12})
    assert twelve["Avg12"] == pytest.approx(50.0) and "Avg16" not in twelve and "Avg" not in twelve
    full = tables.success_table({t: (1.0 if tasks.code_of(t) in tables.AVG12 else 0.0) for t in tasks.names()})
    assert full["Avg12"] == pytest.approx(100.0) and full["Avg16"] == pytest.approx(75.0)


def test_format_table_marks_missing_cells():
    text = tables.format_table({"read": {"RT": 24.0, "PB": 100.0}, "deterministic": {"RT": 65.0}})
    head, rule, read, det = text.splitlines()
    assert head.split() == ["method", "RT", "PB"] and set(rule) == {"-"}
    assert read.split() == ["read", "24.0", "100.0"] and det.split() == ["deterministic", "65.0", "-"]
