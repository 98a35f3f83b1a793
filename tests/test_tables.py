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


def test_rows_sort_numbers_by_value():
    labels = ["read: cheat10_N0", "runs1k/read: spe_N10", "read: cheat1_N100", "read: cheat3_N0", "read: cheat1_N0",
              "read: spe_N10", "read"]
    assert sorted(labels, key=tables.natural_key) == [
        "read", "read: cheat1_N0", "read: cheat1_N100", "read: cheat3_N0", "read: cheat10_N0", "read: spe_N10",
        "runs1k/read: spe_N10"]


def test_the_chart_stays_legible_with_many_rows(tmp_path):
    """Up to BARS_UP_TO rows: grouped bars of fixed height; beyond: a heat map whose height grows
    with the rows (every row label readable), also where a row ran only some tasks."""
    import matplotlib.image as mpimg

    def height(rows: int) -> int:
        table = {f"run_{i}: spe_N100": ({"RT": 50.0 + i, "PB": 90.0} if i % 2 else {"RT": 10.0}) for i in range(rows)}
        path = tmp_path / f"chart_{rows}.png"
        tables.success_chart(table, path)
        return mpimg.imread(path).shape[0]

    few, many, more = height(tables.BARS_UP_TO), height(3 * tables.BARS_UP_TO), height(6 * tables.BARS_UP_TO)
    assert few < many < more
    assert more - many > 0.8 * (many - few)  # about linear in the rows
