"""Success tables in the paper's layout: per-task success (%) in the paper's column order plus
Avg12 / Avg16 where every member task is present, as text, markdown or a chart, with the rows'
labels and order. One home for the evaluation results, the report
and the CLIs' printed tables; no JAX or simulator import, so the report reads results without them."""

from __future__ import annotations

import re
from pathlib import Path

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


def columns(rows: dict[str, dict[str, float]]) -> list[str]:
    """The columns some row fills, in the paper's order (PC RT PB ... | Avg Avg12 Avg16)."""
    return [c for c in list(AVG16) + ["Avg", "Avg12", "Avg16"] if any(c in r for r in rows.values())]


def format_table(rows: dict[str, dict[str, float]]) -> str:
    """Methods x tasks in the paper's column order (PC RT PB ... | Avg12 Avg16), as plain text."""
    cols = columns(rows)
    width = max([6] + [len(m) for m in rows])
    head = f"{'method':<{width}} " + " ".join(f"{c:>6}" for c in cols)
    lines = [head, "-" * len(head)]
    for m, r in rows.items():
        lines.append(f"{m:<{width}} " + " ".join(f"{r[c]:6.1f}" if c in r else f"{'-':>6}" for c in cols))
    return "\n".join(lines)


def markdown_table(table: dict[str, dict[str, float]]) -> str:
    """Methods x tasks in the paper's column order, as a markdown table (the report's)."""
    cols = columns(table)
    lines = ["| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for label, r in table.items():
        lines.append(f"| {label} | " + " | ".join(f"{r[c]:.1f}" if c in r else "–" for c in cols) + " |")
    return "\n".join(lines)


BARS_UP_TO = 8  # rows a grouped bar chart stays readable with; more rows are drawn as a heat map


def success_chart(table: dict[str, dict[str, float]], path: Path) -> None:
    """The success table as a picture: grouped bars (a colour per row) for up to ``BARS_UP_TO`` rows,
    beyond that a heat map (a line per row, the value written in each cell; blank where a row did
    not run a task), whose height grows with the rows so every label stays legible."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = columns(table)
    labels = list(table)
    if len(labels) > BARS_UP_TO:
        grid = np.array([[table[lb].get(c, np.nan) for c in cols] for lb in labels], dtype=float)
        fig, ax = plt.subplots(figsize=(max(6.0, 0.55 * len(cols) + 0.09 * max(map(len, labels)) + 1.5),
                                        0.22 * len(labels) + 1.2))
        ax.imshow(np.ma.masked_invalid(grid), cmap="RdYlGn", vmin=0, vmax=100, aspect="auto")
        for (i, j), v in np.ndenumerate(grid):
            if np.isfinite(v):
                ax.text(j, i, f"{v:.0f}", ha="center", va="center", fontsize=6)
        ax.set_xticks(np.arange(len(cols)), cols, fontsize=7)
        ax.xaxis.tick_top()
        ax.set_yticks(np.arange(len(labels)), labels, fontsize=6)
        ax.set_title("success (%)", fontsize=8, pad=14)
    else:
        width = 0.8 / max(len(labels), 1)
        fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(cols) + 2), 3.8))
        x = np.arange(len(cols))
        colors = plt.get_cmap("tab10")  # one distinct colour per row
        for i, label in enumerate(labels):
            ax.bar(x + i * width - 0.4 + width / 2, [table[label].get(c, 0.0) for c in cols], width, label=label,
                   color=colors(i % colors.N))
        ax.set_xticks(x, cols)
        ax.set_ylabel("success (%)")
        ax.set_ylim(0, 105)
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")  # long row labels stay whole
    plt.close(fig)


def row_label(r: dict) -> str:
    """A result's row in the tables: its run's label (``_run_name``, set by ``report.collect``) and
    its evaluation's name; a run's own retrieval (SPE, N = 0) and a one-pass method read as such."""
    name = r.get("name", "eval")
    cfg = r.get("eval_config", {})
    run = r["_run_name"] + suite_mark(r)
    if cfg.get("N") == 0 and cfg.get("retrieval") == "spe":
        return f"{run}: retrieval only (N=0)"
    if name == "direct":  # a one-pass method without retrieval (Deterministic)
        return run
    return f"{run}: {name}"


def suite_mark(r: dict) -> str:
    """" [suite k]" for a result of another suite version than the current tasks' (an older, easier
    benchmark: its rows never mix with the current suite's), "" otherwise."""
    suite = tasks.suite_of(r)
    return "" if suite == tasks.SUITE_VERSION else f" [suite {suite}]"


def of_suite(results: list[dict], suite: int) -> list[dict]:
    """The results measured on suite version ``suite`` (tables never mix suites)."""
    return [r for r in results if tasks.suite_of(r) == suite]


def natural_key(text: str) -> tuple:
    """Row order: by run (plain text order, so ``runs/...`` stays before ``runs1k/...``), then by
    the evaluation name with numbers by value (cheat3 before cheat10, N10 before N100)."""
    run, _, name = text.partition(":")
    return run, [(0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", name)]


def suite_note(suite: int) -> str:
    """What a table's suite version is, in one line (the current suite, or an older, easier one)."""
    what = tasks.SUITES.get(suite, "unknown")
    if suite == tasks.SUITE_VERSION:
        return f"Suite {suite}, the current tasks: {what}."
    return (f"**Suite {suite}: an earlier, easier version of the tasks** ({what}); its numbers are not comparable "
            f"with suite {tasks.SUITE_VERSION}'s.")
