"""A Table-7 sweep's record written out: sweep.json, the table in the paper's layout (``format_table7``:
each setting against A on the same episodes, the episodes solved by start, the failures by mode) and
a plot of success against each swept value (``plot_sweep``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from readjax.lab.claims import VERSION_MARK, split_versions_differ
from readjax.lab.paired import discordant
from readjax.lab.sweep_grid import DEFAULTS, value_label


def write_sweep(sweep: dict, folder: Path) -> None:
    """sweep.json (every cell's settings, success and per-episode outcomes), table.md and sweep.png
    in ``folder``: the run folder's copy, or the one under results/ that is committed and that
    ``experiments.report --runs results/`` shows."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sweep.json").write_text(json.dumps(sweep, indent=2))
    (folder / "table.md").write_text(format_table7(sweep))
    plot_sweep(sweep, folder / "sweep.png")


START_BINS_CM = (3.0, 10.0)  # a cell's episodes by how far its own retrieval started: < 3, 3-10, > 10 cm


def solved_by_start(cell: dict) -> str:
    """``solved / episodes`` from starts in each of START_BINS_CM's ranges, e.g. ``29/30, 46/47, 11/23``."""
    start, won = np.asarray(cell["start_error_cm"], float), np.asarray(cell["outcomes"], bool)
    bins = np.digitize(start, START_BINS_CM)
    return ", ".join(f"{int(won[bins == b].sum())}/{int((bins == b).sum())}" for b in range(len(START_BINS_CM) + 1))


def _has_starts(cell: dict) -> bool:
    return "start_error_cm" in cell and "outcomes" in cell


def _modes(cell: dict) -> str:
    counts = cell.get("failure_modes")
    if counts is None:
        return ""
    return ", ".join(f"{m} {n}" for m, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))) or "none"


def _is_default(cell: dict, reference: dict) -> bool:
    return all(cell[k] == v for k, v in reference.items())


def format_table7(sweep: dict) -> str:
    """The layout of the paper's Table 7: setting, N, K, L, T, success (%); where the cells carry
    their per-episode outcomes and the sweep holds its setting A (``reference``: its preset's values
    at N = 100; the paper's A for a sweep recorded without one), each other cell against A on the
    same episodes (+ episodes only it solves / - only A solves, exact McNemar p). Where the cells keep
    their evaluations' failure records (:func:`readjax.lab.sweep_cells.cell_diagnostics`): the episodes solved from near,
    middling and far starts, and the failures by mode."""
    code = sweep["code"]
    reference = sweep.get("reference", DEFAULTS)
    a = next((c for c in sweep["cells"] if _is_default(c, reference) and "outcomes" in c), None)
    starts = any(_has_starts(c) for c in sweep["cells"])
    modes = any("failure_modes" in c for c in sweep["cells"])
    lo, hi = (value_label(x) for x in START_BINS_CM)
    lines = [f"| setting | N | K | L | T | {code} |" + (" vs A |" if a else "")
             + (f" solved from starts < {lo} / {lo}-{hi} / > {hi} cm |" if starts else "")
             + (" failures by mode |" if modes else ""),
             "|---|---|---|---|---|---|" + ("---|" if a else "") + ("---|" if starts else "") + ("---|" if modes else "")]
    others = 0  # the other settings are lettered B, C, ... in order, A's place skipped
    across_versions = False
    for c in sweep["cells"]:
        if _is_default(c, reference):
            tag = "A (default)"
        else:
            tag = chr(ord("B") + others) if others < 25 else str(others + 1)
            others += 1
        row = f"| {tag} | {c['N']} | {c['K']} | {value_label(c['L'])} | {value_label(c['T'])} | {100 * c['success']:.1f} |"
        if a:
            vs = ("–" if c is a or "outcomes" not in c else
                  discordant({"seeds": c["seeds"], "success": c["outcomes"]}, {"seeds": a["seeds"], "success": a["outcomes"]}))
            if vs != "–" and split_versions_differ(c, a):
                vs += f" {VERSION_MARK}"
                across_versions = True
            row += f" {vs} |"
        if starts:
            row += f" {solved_by_start(c) if _has_starts(c) else ''} |"
        if modes:
            row += f" {_modes(c)} |"
        lines.append(row)
    if across_versions:
        lines += ["", f"{VERSION_MARK} This cell and A ran the same seeds (the same scenes and images) on different "
                  "versions of the test split: generated on different CPUs, their expert motions differ at float "
                  "precision (`test_fingerprint` in each cell)."]
    return "\n".join(lines) + "\n"


def plot_sweep(sweep: dict, path: Path) -> None:
    """Success against each swept value (one panel per key; other keys' values as separate lines)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(sweep["grid"])
    fig, axes = plt.subplots(1, len(keys), figsize=(4 * len(keys), 3.2), squeeze=False)
    reference = sweep.get("reference", DEFAULTS)
    for ax, key in zip(axes[0], keys):
        others = [k for k in keys if k != key]
        groups: dict = {}
        for c in sweep["cells"]:
            if sweep.get("vary") == "one" and any(c[k] != reference[k] for k in others):
                continue  # Table 7's layout: a key's panel shows it varied alone from setting A
            groups.setdefault(tuple(c[k] for k in others), []).append((c[key], 100 * c["success"]))
        for g, pts in groups.items():
            pts.sort()
            xs, ys = zip(*pts)
            label = ", ".join(f"{k}={value_label(v)}" for k, v in zip(others, g)) or None
            ax.plot(range(len(xs)) if key == "N" else xs, ys, marker="o", label=label)
            if key == "N":
                ax.set_xticks(range(len(xs)), [str(x) for x in xs])
        ax.set_xlabel(key)
        ax.set_ylabel(f"{sweep['code']} success (%)")
        ax.set_ylim(-3, 103)
        if len(groups) > 1:
            ax.legend(fontsize=7)
    fig.suptitle(f"{sweep['model']} on {sweep['task']} ({sweep['episodes']} episodes per cell)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def success_matrix(sweep: dict) -> np.ndarray:
    return np.array([c["success"] for c in sweep["cells"]])
