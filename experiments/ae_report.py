"""Compare trained motion autoencoders on held-out demos: reconstruction error in the world frame
and the fraction of decoded motions whose poses IK reaches within 5 mm / 0.05 rad (joint limits
enforced). The recorded demos go through the same IK check as a reference row.

examples:
  python -m experiments.ae_report --runs runs/reach_target/read runs/reach_target/read_kin \\
      --data data/ --split test --out docs/autoencoders.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.ae_report", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--runs", nargs="+", required=True, help="run folders whose vae/ stage is trained")
    p.add_argument("--data", default="data", help="dataset root (DATA/<task>/<split>)")
    p.add_argument("--split", default="test", help="which split to reconstruct")
    p.add_argument("--episodes", type=_cli.positive_int, default=None, help="use the first N demos (default: all)")
    p.add_argument("--out", default=None, help="JSON output (a markdown table goes beside it)")
    return p


def table(rows: list[dict]) -> str:
    head = ("| autoencoder | demos | pos err mm (mean / p95) | end pos err mm (median / p95) | rot err rad (mean) | uv err px | "
            "poses reachable | motions reachable | IK pos err mm (median / max) |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        rec, rc = r.get("reconstruction"), r["reachability"]
        rec_cols = (f"{rec['pos_err_mm_mean']:.1f} / {rec['pos_err_mm_p95']:.1f} | "
                    f"{rec['end_pos_err_mm_median']:.1f} / {rec['end_pos_err_mm_p95']:.1f} | {rec['rot_err_rad_mean']:.3f} | "
                    f"{rec['uv_err_px_mean']:.2f}") if rec else "- | - | - | -"
        lines.append(f"| {r['name']} | {r['episodes']} | {rec_cols} | {100 * rc['poses_reachable']:.1f}% | "
                     f"{100 * rc['motions_reachable']:.1f}% | {rc['ik_pos_err_mm_median']:.2f} / "
                     f"{rc['ik_pos_err_mm_max']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax import ae_eval, provenance, tasks
    from readjax.data.store import load_dataset
    from readjax.methods import base

    runs = [Path(r) for r in args.runs]
    specs = [base.read_run(r) for r in runs]
    task_names = {s["task"] for s in specs}
    if len(task_names) != 1:
        raise ValueError(f"the runs are of different tasks: {sorted(task_names)}")
    task = task_names.pop()
    ds = load_dataset(Path(args.data) / task / args.split, limit=args.episodes)
    rows = [{"name": "recorded demos (IK check only)", "episodes": len(ds),
             "reachability": ae_eval.reachability(tasks.make(task).chain, ds.camera, ds.motion)}]
    for run in runs:
        res = ae_eval.evaluate_autoencoder(run, ds.motion)
        res["name"] = ("kinematics-aware AE" if res["kinematic"] else "task-space VAE") + f" ({run.name})"
        rows.append(res)
        print(f"{res['name']}: done", flush=True)
    text = table(rows)
    print(text)
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"task": task, "split": args.split, "rows": rows,
                                   "versions": provenance.versions()}, indent=1))
        out.with_suffix(".md").write_text(f"# Autoencoders on {task} ({args.split} split)\n\n{text}\n")
        print(f"wrote {out} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
