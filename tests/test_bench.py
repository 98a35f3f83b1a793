"""The planner benchmark's cost model for skipping cells that would run too long."""

import pytest

from experiments.bench import _estimate_call_s


def test_estimate_separates_fixed_cost_from_per_step_cost():
    # 4 s fixed (encoding 64 images) + 0.6 s per refinement step
    timed = [(1, 4.6), (10, 10.0)]
    assert _estimate_call_s(timed, 100) == pytest.approx(64.0)
    assert _estimate_call_s([], 100) == 0.0  # nothing timed yet: run the cell
    assert _estimate_call_s([(1, 4.6)], 100) == pytest.approx(4.6)  # a lower bound, never an overestimate
    assert _estimate_call_s([(1, 5.0), (10, 4.0)], 100) == pytest.approx(4.0)  # noise never gives negative steps
