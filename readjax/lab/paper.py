"""The paper's published success rates (%), per task in the paper's column order, for side-by-side
rows in our tables. Source: ``shared/paper/READ-supplement.txt``. One home for every number we quote
from the paper, so a table never carries a hand-typed copy.
"""

from __future__ import annotations

from readjax.tasks import AVG16

# Table 7, setting A (N = 100, K = 3, L = 0.5, T = 2.0): READ's default, the row whose averages the
# paper's main table reports (Avg16 70.2, Avg12 88.8).
READ_TABLE7_A = dict(zip(AVG16, (96, 99, 72, 88, 100, 98, 97, 57, 91, 86, 82, 100, 16, 36, 4, 1)))
READ_TABLE7_A_AVERAGES = {"Avg12": 88.8, "Avg16": 70.2}  # as printed (rounded to 0.1)

READ_LABEL = "READ, paper (Table 7 A: N=100, K=3)"


def mean_over(rates: dict[str, float], codes) -> float:
    """The mean of ``rates`` over the task codes ``codes`` (all of which must be present)."""
    codes = list(codes)
    missing = [c for c in codes if c not in rates]
    if missing:
        raise KeyError(f"no rate for {', '.join(missing)}")
    return sum(rates[c] for c in codes) / len(codes)

