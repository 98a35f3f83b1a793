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


# Table 5 (retrieval), the oracle rows "Cheat (i)": the i-th nearest training demonstration to the
# ground-truth motion, executed without refinement (N = 0). Printed averages beside them.
CHEAT = {
    1: dict(zip(AVG16, (85, 96, 96, 57, 86, 99, 85, 42, 87, 76, 51, 94, 1, 13, 0, 1))),
    3: dict(zip(AVG16, (67, 81, 83, 35, 71, 92, 70, 30, 86, 38, 36, 80, 0, 7, 2, 1))),
    10: dict(zip(AVG16, (56, 21, 47, 17, 64, 58, 50, 9, 72, 16, 19, 56, 0, 2, 3, 1))),
}
CHEAT_AVERAGES = {1: {"Avg12": 79.5, "Avg16": 60.6}, 3: {"Avg12": 64.1, "Avg16": 48.7},
                  10: {"Avg12": 40.4, "Avg16": 30.7}}
# Table 5, row READ: READ's own retrieval (SPE top-1) executed without refinement.
RETRIEVAL_ONLY = dict(zip(AVG16, (73, 89, 86, 37, 97, 97, 77, 37, 91, 73, 34, 91, 0, 19, 3, 1)))

# Table 4 (refinement), row READ (i): READ refining the oracle's i-th nearest demonstration (N = 100),
# beside Table 5's Cheat (i), the same start executed unrefined. Printed averages beside them.
TABLE4_READ = {
    1: dict(zip(AVG16, (97, 100, 73, 87, 100, 97, 98, 42, 94, 89, 86, 100, 21, 38, 0, 4))),
    3: dict(zip(AVG16, (97, 100, 75, 88, 100, 96, 98, 55, 89, 88, 86, 100, 19, 35, 3, 2))),
    10: dict(zip(AVG16, (97, 100, 75, 90, 99, 97, 98, 55, 92, 88, 86, 100, 19, 36, 2, 3))),
}
TABLE4_READ_AVERAGES = {1: {"Avg12": 88.6, "Avg16": 70.4}, 3: {"Avg12": 89.3, "Avg16": 70.6},
                        10: {"Avg12": 89.8, "Avg16": 71.0}}
# Table 8 (refinement from a poor retrieval): READ from the oracle's 500th neighbour at N = 0, 1, 100.
# Its printed rows carry a 17th value past SB (a stray column); the 16 tasks' values are the first 16,
# which the printed averages confirm.
POOR_RANK = 500
TABLE8 = {
    0: dict(zip(AVG16, (0, 2, 0, 0, 4, 0, 1, 0, 3, 5, 0, 1, 0, 0, 0, 0))),
    1: dict(zip(AVG16, (75, 73, 32, 38, 55, 43, 80, 15, 66, 24, 36, 33, 0, 13, 0, 0))),
    100: dict(zip(AVG16, (95, 99, 77, 85, 100, 96, 97, 55, 89, 80, 83, 100, 17, 27, 5, 2))),
}
TABLE8_AVERAGES = {0: {"Avg12": 1.3, "Avg16": 1.0}, 1: {"Avg12": 47.5, "Avg16": 36.4},
                   100: {"Avg12": 88.0, "Avg16": 69.2}}
