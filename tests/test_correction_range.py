"""How far from the answer refinement can start: per-rank and per-start-error summaries of
``refine_report`` results, the training pairs' distances, the plot."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from readjax.lab import correction_range
from readjax import motion as motion_lib
from readjax.sim.camera import CameraParams


def _report(rank: int, start: list[float], end: list[float]) -> dict:
    rows = [{"split": split, "N": n, "err_cm": errs} for split in ("train", "test") for n, errs in ((0, start), (100, end))]
    return {"rank": rank, "rows": rows}


REPORTS = [_report(1, [1.0, 2.0, 4.0], [0.5, 1.0, 1.0]), _report(500, [25.0, 35.0, 12.0], [24.0, 40.0, 2.0])]


def test_by_rank_and_by_start_pool_every_plan():
    ranks = correction_range.by_rank(REPORTS)
    assert [r["rank"] for r in ranks] == [1, 500] and ranks[0]["N"] == 100
    assert ranks[0]["start_cm_median"] == 2.0 and ranks[0]["end_cm_median"] == 1.0 and ranks[0]["within_3cm"] == 1.0
    assert ranks[1]["closer"] == pytest.approx(2 / 3) and ranks[1]["within_3cm"] == pytest.approx(1 / 3)
    bins = {tuple(r["start_cm"]): r for r in correction_range.by_start(REPORTS)}
    assert set(bins) == {(0, 3), (3, 6), (10, 15), (20, 30), (30, 1000)}  # empty bins are left out
    assert bins[(0, 3)]["plans"] == 2 and bins[(0, 3)]["reduction_cm_median"] == 0.75
    assert bins[(10, 15)]["end_cm_median"] == 2.0 and bins[(30, 1000)]["within_3cm"] == 0.0
    with pytest.raises(ValueError, match="N = 0"):
        correction_range.by_rank([{"rank": 1, "rows": [{"split": "test", "N": 0, "err_cm": [1.0]}]}])


def test_training_pairs_span_the_distances_between_neighbouring_demos():
    """Ten demos standing still 1 cm apart on a line: with K = 2, every demo's nearest is 1 cm away and
    the ends' second nearest 2 cm."""
    cam = CameraParams(np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]]), np.eye(4), 64, 64)
    pos = np.zeros((10, 101, 3))
    pos[:, :, 0] = np.arange(10)[:, None] * 0.01
    pos[:, :, 2] = 1.0
    rot = np.broadcast_to(np.eye(3), (10, 101, 3, 3))
    motions = np.asarray(motion_lib.encode(cam, jnp.asarray(pos), jnp.asarray(rot), jnp.ones((10, 101))))
    d = correction_range.pair_distances(cam, motions, k=2)
    assert d["K"] == 2 and d["median_cm_at_rank"] == {"1": pytest.approx(1.0, abs=1e-3)}
    assert d["max_cm"] == pytest.approx(2.0, abs=1e-3) and d["median_cm"] == pytest.approx(1.0, abs=1e-3)


def test_the_tables_and_the_plot(tmp_path):
    pairs = {"K": 50, "median_cm_at_rank": {"1": 2.4, "50": 11.2}, "median_cm": 8.6, "p90_cm": 11.3, "max_cm": 18.0}
    result = {"split": "test", "by_rank": correction_range.by_rank(REPORTS), "by_start": correction_range.by_start(REPORTS),
              "training_pairs": pairs}
    text = "\n".join(correction_range.format_lines(result))
    assert "| 500 | 25.0 | 24.0 | 33 % | 67 % |" in text and "| 30- | 1 | 40.0 | 0 % | -5.0 |" in text
    assert "largest 18.0 cm" in text
    correction_range.plot(REPORTS, tmp_path / "range.png", pairs=pairs)
    assert (tmp_path / "range.png").stat().st_size > 1000
