"""Replicates: results of one recipe from trainings with different ``train.seed``. On a task where
trainings disagree, the spread across them is the yardstick a paired test between two methods'
single trainings needs (BENCHMARKS.md 8g)."""

from __future__ import annotations

import json

import numpy as np

from readjax import tasks
from readjax.lab.result_record import eval_config_of, with_defaults
from readjax.tables import natural_key, row_label


def training_group(r: dict) -> str | None:
    """What a result measures apart from which training produced it: the task, the method, every
    config except ``train.seed``, the training set (its fingerprint, where recorded: the same
    recipe on another machine's data is another experiment) and the evaluation (name and protocol
    settings). Results with the same group and different training seeds are replicates of one
    recipe; None when the result does not record its configs."""
    configs = r.get("configs")
    if not configs:
        return None
    configs = with_defaults(configs)
    configs["train"] = {k: v for k, v in configs.get("train", {}).items() if k != "seed"}
    # an evaluation recorded before an EvalConfig field existed ran with its default
    eval_config = eval_config_of(r)
    return json.dumps([r["task"], r.get("method"), configs, r.get("train_fingerprint"), r.get("name"),
                       eval_config], sort_keys=True)


def across_trainings(results: list[dict]) -> list[dict]:
    """Groups of results (:func:`training_group`) produced by at least two trainings with different
    ``train.seed``: per group its row labels, success rates, mean and range. On a task where
    trainings disagree, one training's paired test against another method's says little about the
    methods (BENCHMARKS.md 8g); the spread across trainings is the yardstick."""
    groups: dict[str, list[dict]] = {}
    for r in results:
        g = training_group(r)
        if g is not None:
            groups.setdefault(g, []).append(r)
    out = []
    for members in groups.values():
        seeds = {m["configs"].get("train", {}).get("seed") for m in members}
        if len(seeds) < 2:
            continue
        members = sorted(members, key=lambda m: natural_key(row_label(m)))
        rates = [100 * m["success_rate"] for m in members]
        out.append({"task": members[0]["task"], "eval": members[0].get("name"),
                    "rows": [row_label(m) for m in members],
                    "seeds": [m["configs"].get("train", {}).get("seed") for m in members],
                    "rates": rates, "mean": float(np.mean(rates)), "min": min(rates), "max": max(rates)})
    return sorted(out, key=lambda g: (g["task"], natural_key(g["rows"][0])))


def across_lines(results: list[dict]) -> list[str]:
    groups = across_trainings(results)
    if not groups:
        return []
    lines = ["## Across trainings (same recipe, different `train.seed`)", "",
             "Rows whose configs and evaluation are identical except the training seed: each training's "
             "success %, their mean and range.", "",
             "| task | rows (seed) | success % | mean | range |", "|---|---|---|---|---|"]
    for g in groups:
        rows = "<br>".join(f"{r} ({s})" for r, s in zip(g["rows"], g["seeds"]))
        rates = " / ".join(f"{x:.0f}" for x in g["rates"])
        lines.append(f"| {tasks.code_of(g['task'])} | {rows} | {rates} | {g['mean']:.1f} | {g['min']:.0f}-{g['max']:.0f} |")
    return lines + [""]
