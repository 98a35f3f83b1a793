"""A training stage's folder, ``RUN/<stage>/``, and how to read it without JAX: ``stage.json`` (the
stage's identity: config, dataset fingerprint, versions), ``metrics.jsonl`` (a line per logged step,
its ``time_s`` counted from the start of the run that logged it), ``stop.json`` (when and why a
finished stage stopped: converged under the rule, or the step cap), ``loss.png`` (the curve, the stop
marked) and ``checkpoints/``. :class:`readjax.training.Stage` writes it; evaluation records, the
grid's progress lines and ETA, the sweep and the report read it through here."""

from __future__ import annotations

import json
from pathlib import Path

STAGE_FILE = "stage.json"
METRICS_FILE = "metrics.jsonl"
STOP_FILE = "stop.json"
LOSS_CURVE = "loss.png"
PACE_ROWS = 10  # the last logged steps of a stage's current run that give its pace


def read_metrics(stage_dir: str | Path) -> list[dict]:
    """Every logged step of the stage, oldest first ([] before the first)."""
    f = Path(stage_dir) / METRICS_FILE
    return [json.loads(ln) for ln in f.read_text().splitlines() if ln.strip()] if f.exists() else []


def read_stop(stage_dir: str | Path) -> dict | None:
    """Why and when the stage finished (``stop.json``), or None while it has not."""
    f = Path(stage_dir) / STOP_FILE
    return json.loads(f.read_text()) if f.exists() else None


def is_finished(stage_dir: str | Path) -> bool:
    return (Path(stage_dir) / STOP_FILE).exists()


def step_cap(stage_dir: str | Path) -> int | None:
    """The stage's step cap from its recorded config (``train.vae_steps`` for the autoencoder stage,
    ``train.steps`` for the others); None where ``stage.json`` is missing or unreadable."""
    stage_dir = Path(stage_dir)
    try:
        train = json.loads((stage_dir / STAGE_FILE).read_text())["config"]["train"]
        return int(train["vae_steps" if stage_dir.name == "vae" else "steps"])
    except (OSError, KeyError, ValueError, TypeError):
        return None


def stage_records(run_dir: str | Path) -> dict[str, dict]:
    """Per stage of a run folder (each ``<stage>/stage.json``): the last logged step and, once the
    stage finished, why (``stop.json``: converged or the step cap; None before it finished or for a
    stage trained before the record existed). Evaluations carry it, so a result says how long its
    model trained and whether it had converged."""
    out = {}
    for f in sorted(Path(run_dir).glob(f"*/{STAGE_FILE}")):
        rows = read_metrics(f.parent)
        out[f.parent.name] = {"steps": rows[-1]["step"] if rows else 0, "stop": read_stop(f.parent)}
    return out


def progress(run_dir: str | Path) -> str:
    """A training's progress from its run folder, e.g. ``vae done, read 2250/5000``: each stage
    finished, or its last logged step against its step cap (a stage under the convergence rule may
    stop before the cap); "" before any stage has logged a step."""
    parts = []
    records = stage_records(run_dir)
    for stage, rec in sorted(records.items(), key=lambda kv: (kv[1]["stop"] is None, kv[0])):  # finished first
        if rec["stop"] is not None:
            parts.append(f"{stage} done")
            continue
        cap = step_cap(Path(run_dir) / stage)
        parts.append(f"{stage} {rec['steps']}/{cap}" if cap else f"{stage} {rec['steps']}")
    return ", ".join(parts)


def seconds_left(run_dir: str | Path, stages: tuple[str, ...]) -> float | None:
    """A training under way priced by its own pace: per unfinished stage of ``stages``, the steps left
    to its cap times its seconds per step over the last ``PACE_ROWS`` logged steps of its current run
    (the clock restarts with each run, so the window stays within one; validation included,
    compilation not). None when a stage has no pace yet (not started, or one row into a run): the
    caller prices the step whole. A stage under the convergence rule may stop before its cap, so this
    is an upper bound."""
    left = 0.0
    for stage in stages:
        d = Path(run_dir) / stage
        if is_finished(d):
            continue
        try:
            rows = read_metrics(d)
        except (OSError, ValueError):  # a line half-written
            return None
        cap = step_cap(d)
        if cap is None or not rows:
            return None
        window = [rows[-1]]
        for r in reversed(rows[:-1]):
            if len(window) == PACE_ROWS or r["time_s"] >= window[-1]["time_s"]:  # the window's start, or an earlier run
                break
            window.append(r)
        if len(window) < 2:
            return None
        pace = (window[0]["time_s"] - window[-1]["time_s"]) / (window[0]["step"] - window[-1]["step"])
        left += max(cap - rows[-1]["step"], 0) * pace
    return left


def plot_losses(stage_dir: str | Path, title: str) -> Path | None:
    """The stage's loss curve (``loss.png``): every logged loss term, the held-out validation loss
    and the stop; None before the first logged step."""
    stage_dir = Path(stage_dir)
    rows = read_metrics(stage_dir)
    if not rows:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [k for k in rows[0] if k not in ("step", "time_s", "grad_norm", "val_loss")]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    steps = [r["step"] for r in rows]
    for k in keys:
        ax.plot(steps, [r[k] for r in rows], label=k, lw=1.2 if k == "loss" else 0.8)
    val = [(r["step"], r["val_loss"]) for r in rows if "val_loss" in r]
    if val:
        ax.plot(*zip(*val), "k.-", label="val_loss (held out)", lw=1.2, ms=3)
    stop = read_stop(stage_dir)
    if stop is not None:
        ax.axvline(stop["stopped_at"], color="r", ls="--", lw=1, label=f"stop at {stop['stopped_at']}: {stop['reason']}")
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_title(title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    out = stage_dir / LOSS_CURVE
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
