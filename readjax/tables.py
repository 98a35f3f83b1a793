"""Success tables in the paper's layout: per-task success (%) in the paper's column order plus
Avg12 / Avg16 where every member task is present. One home for the evaluation results, the report
and the CLIs' printed tables; no JAX or simulator import, so the report reads results without them."""

from __future__ import annotations

import numpy as np

from readjax import tasks

AVG12 = tasks.AVG12
AVG16 = tasks.AVG16


def success_table(rates: dict[str, float]) -> dict[str, float]:
    """Per-task success (%) plus Avg12 / Avg16 where every member task is present (paper layout)."""
    by_code = {tasks.code_of(t): 100.0 * r for t, r in rates.items()}
    table = {c: by_code[c] for c in AVG16 if c in by_code}
    if all(c in by_code for c in AVG12):
        table["Avg12"] = float(np.mean([by_code[c] for c in AVG12]))
    if all(c in by_code for c in AVG16):
        table["Avg16"] = float(np.mean([by_code[c] for c in AVG16]))
    if "Avg12" not in table and by_code:
        table["Avg"] = float(np.mean(list(by_code.values())))
    return table


def format_table(rows: dict[str, dict[str, float]]) -> str:
    """Methods x tasks in the paper's column order (PC RT PB ... | Avg12 Avg16)."""
    cols = [c for c in list(AVG16) + ["Avg", "Avg12", "Avg16"] if any(c in r for r in rows.values())]
    width = max([6] + [len(m) for m in rows])
    head = f"{'method':<{width}} " + " ".join(f"{c:>6}" for c in cols)
    lines = [head, "-" * len(head)]
    for m, r in rows.items():
        lines.append(f"{m:<{width}} " + " ".join(f"{r[c]:6.1f}" if c in r else f"{'-':>6}" for c in cols))
    return "\n".join(lines)
