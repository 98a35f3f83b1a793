"""How far from the answer READ's refinement can start and still reach it.

From ``refine_report`` runs started at the oracle's i-th nearest demonstration for several i (Table 8's
protocol, i = 500 a poor start), each plan's 3D end error at the start (N = 0) and after the largest N,
pooled over the ranks and binned by the start's error: where refinement stops correcting. Beside it, for
comparison, the distances READ trained to correct: each training demo against the K nearest demos it is
paired with (``retrieval.training_pairs``). (On RT and PB the edge lies near 16 cm on both, while their
training pairs reach 18 and 10 cm: BENCHMARKS.md 18.) No simulator in the loop."""

from __future__ import annotations

import numpy as np

from readjax import motion as motion_lib
from readjax import retrieval

START_BINS_CM = (0, 3, 6, 10, 15, 20, 30, 1000)
PAIR_RANKS = (1, 5, 10, 25, 50)


def _errors(report: dict, split: str) -> tuple[np.ndarray, np.ndarray, int]:
    """(start errors, end errors after the largest N, that N) of one report's split, per image (cm)."""
    rows = {r["N"]: r for r in report["rows"] if r["split"] == split}
    if 0 not in rows or len(rows) < 2 or "err_cm" not in rows[0]:
        raise ValueError(f"{split}: a correction range needs N = 0 and a larger N, with each image's error "
                         f"(refine_report since 2026-12-04)")
    n = max(rows)
    return np.asarray(rows[0]["err_cm"]), np.asarray(rows[n]["err_cm"]), n


def by_rank(reports: list[dict], split: str = "test") -> list[dict]:
    """Per start (the oracle's rank): the median start and end error, the share within 3 cm after
    refinement, and the share of plans it moved closer."""
    out = []
    for rep in sorted(reports, key=lambda r: r.get("rank", 1)):
        s, e, n = _errors(rep, split)
        out.append({"rank": rep.get("rank", 1), "N": n, "plans": len(s), "start_cm_median": float(np.median(s)),
                    "end_cm_median": float(np.median(e)), "within_3cm": float(np.mean(e < 3.0)),
                    "closer": float(np.mean(e < s))})
    return out


def by_start(reports: list[dict], split: str = "test", bins=START_BINS_CM) -> list[dict]:
    """Every report's plans pooled and binned by their start's error (cm): per bin the plans, the
    median end error after the largest N, the share within 3 cm and the median reduction."""
    s, e = (np.concatenate(x) for x in zip(*[_errors(r, split)[:2] for r in reports]))
    out = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        m = (s >= lo) & (s < hi)
        if m.any():
            out.append({"start_cm": [lo, hi], "plans": int(m.sum()), "end_cm_median": float(np.median(e[m])),
                        "within_3cm": float(np.mean(e[m] < 3.0)), "reduction_cm_median": float(np.median(s[m] - e[m]))})
    return out


def pair_distances(camera, motions: np.ndarray, k: int, pool: int | None = None) -> dict:
    """The 3D end distances (cm) between each training demo and the K nearest demos READ pairs it
    with: the median at a few ranks, over all pairs, the 90th percentile and the largest."""
    import jax.numpy as jnp

    pool = len(motions) if pool is None else pool
    pairs = retrieval.training_pairs(camera, motions, k, clamp=True, pool=pool)
    pos, _, _ = motion_lib.decode(camera, jnp.asarray(motions))
    end = np.asarray(pos)[:, -1]
    d = np.linalg.norm(end[:pool, None] - end[pairs[:pool]], axis=-1) * 100
    k = d.shape[1]
    return {"K": k, "median_cm_at_rank": {str(r): float(np.median(d[:, r - 1])) for r in PAIR_RANKS if r <= k},
            "median_cm": float(np.median(d)), "p90_cm": float(np.percentile(d, 90)), "max_cm": float(d.max())}


def format_lines(result: dict) -> list[str]:
    """The two tables (by start rank, by start error) and the training pairs' range, as markdown."""
    split = result["split"]
    lines = [f"{split} images, refinement from the oracle's i-th nearest demonstration (3D end error, cm):", "",
             "| i | start: median | N = " + str(result["by_rank"][0]["N"]) + ": median | within 3 cm | moved closer |",
             "|---|---|---|---|---|"]
    lines += [f"| {r['rank']} | {r['start_cm_median']:.1f} | {r['end_cm_median']:.1f} | {100 * r['within_3cm']:.0f} % | "
              f"{100 * r['closer']:.0f} % |" for r in result["by_rank"]]
    lines += ["", "all starts pooled, by the start's error:", "",
              "| start error (cm) | plans | end: median (cm) | within 3 cm | reduction: median (cm) |",
              "|---|---|---|---|---|"]
    lines += [f"| {lo}-{hi if hi < 1000 else ''} | {r['plans']} | {r['end_cm_median']:.1f} | {100 * r['within_3cm']:.0f} % | "
              f"{r['reduction_cm_median']:.1f} |" for r in result["by_start"] for lo, hi in [r["start_cm"]]]
    p = result.get("training_pairs")
    if p:
        ranks = ", ".join(f"{k}: {v:.1f}" for k, v in p["median_cm_at_rank"].items())
        lines += ["", f"READ's training pairs (each demo and its K = {p['K']} nearest): median end distance by "
                      f"neighbour rank {ranks} cm; all pairs median {p['median_cm']:.1f}, 90th percentile "
                      f"{p['p90_cm']:.1f}, largest {p['max_cm']:.1f} cm"]
    return lines


def plot(reports: list[dict], path, split: str = "test", pairs: dict | None = None) -> None:
    """Each plan's end error after refinement against its start's error, a colour per start rank,
    the diagonal (no correction) and the 3 cm line; the training pairs' 90th percentile and largest
    distance shaded: the range READ was trained to correct."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    top = 0.0
    colours = plt.get_cmap("viridis")
    for i, rep in enumerate(sorted(reports, key=lambda r: r.get("rank", 1))):
        s, e, n = _errors(rep, split)
        top = max(top, float(s.max()), float(e.max()))
        ax.scatter(s, e, s=8, alpha=0.7, color=colours(i / max(len(reports) - 1, 1)), label=f"i = {rep.get('rank', 1)}")
    ax.plot([0, top], [0, top], "k:", lw=1, label="no correction")
    ax.axhline(3.0, color="tab:green", lw=1, ls="--", label="3 cm")
    if pairs:
        ax.axvspan(0, pairs["p90_cm"], color="tab:orange", alpha=0.12, label=f"training pairs (90 %: {pairs['p90_cm']:.0f} cm)")
        ax.axvline(pairs["max_cm"], color="tab:orange", lw=1, label=f"largest training pair ({pairs['max_cm']:.0f} cm)")
    ax.set_xlabel("start: end-point error of the oracle's i-th neighbour (cm)")
    ax.set_ylabel(f"after N = {n}: end-point error (cm)")
    ax.set_title(f"{split} images: how far refinement corrects", fontsize=9)
    ax.legend(fontsize=6, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
