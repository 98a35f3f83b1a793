"""Compare trained motion autoencoders on held-out demos: reconstruction error in the world frame
and the fraction of decoded motions whose poses IK reaches within 5 mm / 0.05 rad (joint limits
enforced). The recorded demos go through the same IK check as a reference row.

With --execute, each round trip Dec(Enc(M)) is also executed in MJX in its episode's stored scene,
through the evaluation path (scene guard, IK, controller, the task's predicate), and the table gains
its task success; the reference row is then the ground-truth replay (it must read 100 %). That rate
bounds any plan that is the decoder's output, as READ-L's is: on close_box, READ's autoencoder keeps
51 of 100 test motions, READ-L solves 50, and the two agree on 91 of the 100 episodes (BENCHMARKS.md 18l).

examples:
  python -m experiments.ae_report --runs runs/reach_target/read runs/reach_target/read_kin \\
      --data data/ --split test --out docs/autoencoders.json
  python -m experiments.ae_report --runs runs/close_box/read_l_conv --execute \\
      --out results/close_box/read_l_conv/autoencoder_test.json
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
    p.add_argument("--execute", action="store_true",
                   help="also execute every round trip in its episode's scene (task success; ~1 s per episode on a CPU)")
    p.add_argument("--batch-size", type=_cli.positive_int, default=32, help="episodes executed together (--execute)")
    p.add_argument("--out", default=None, help="JSON output (a markdown table goes beside it)")
    return p


def table(rows: list[dict]) -> str:
    head = ("| autoencoder | demos | pos err mm (mean / p95) | end pos err mm (median / p95) | rot err rad (mean) | uv err px | "
            "poses reachable | motions reachable | IK pos err mm (median / max) |")
    executed = any("task_success" in r for r in rows)
    if executed:
        head += " task success |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        rec, rc = r.get("reconstruction"), r["reachability"]
        rec_cols = (f"{rec['pos_err_mm_mean']:.1f} / {rec['pos_err_mm_p95']:.1f} | "
                    f"{rec['end_pos_err_mm_median']:.1f} / {rec['end_pos_err_mm_p95']:.1f} | {rec['rot_err_rad_mean']:.3f} | "
                    f"{rec['uv_err_px_mean']:.2f}") if rec else "- | - | - | -"
        lines.append(f"| {r['name']} | {r['episodes']} | {rec_cols} | {100 * rc['poses_reachable']:.1f}% | "
                     f"{100 * rc['motions_reachable']:.1f}% | {rc['ik_pos_err_mm_median']:.2f} / "
                     f"{rc['ik_pos_err_mm_max']:.1f} |")
        if executed:
            ts = r.get("task_success")
            lines[-1] += f" {ts['successes']} / {r['episodes']} |" if ts else " - |"
    return "\n".join(lines)


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    from readjax import provenance, tasks
    from readjax.lab import ae_eval
    from readjax.data.store import load_dataset
    from readjax.methods import base

    runs = [Path(r) for r in args.runs]
    specs = [base.read_run(r) for r in runs]
    task_names = {s["task"] for s in specs}
    if len(task_names) != 1:
        raise ValueError(f"the runs are of different tasks: {sorted(task_names)}")
    task = task_names.pop()
    ds = load_dataset(Path(args.data) / task / args.split, limit=args.episodes)
    env = tasks.make(task)
    reference = {"name": "recorded demos (IK check only)", "episodes": len(ds),
                 "reachability": ae_eval.reachability(env.chain, ds.camera, ds.motion)}
    execute = None
    if args.execute:
        from readjax.evaluation import replay_ground_truth
        from readjax.sim.execute import execute_motions

        replay = replay_ground_truth(env, ds, batch_size=args.batch_size)  # the scene guard, then the ground truth
        if replay["successes"] < len(ds):
            raise ValueError(f"the ground truth replays at {replay['successes']} / {len(ds)} on {task}'s {args.split} split "
                             f"(failed seeds {replay['failed_seeds'][:10]}): executed round trips would not measure "
                             f"the autoencoder here (see experiments.verify)")
        reference.update(name="recorded demos (ground-truth replay)", task_success=ae_eval.task_success(replay["success"]))
        print(f"ground truth replayed: {replay['successes']} / {len(ds)}", flush=True)
        execute = lambda m: execute_motions(env, ds.camera, ds.scenes, m, batch_size=args.batch_size)["success"]
    rows = [reference]
    for run in runs:
        res = ae_eval.evaluate_autoencoder(run, ds.motion, execute=execute)
        res["name"] = ("kinematics-aware AE" if res["kinematic"] else "task-space VAE") + f" ({run.name})"
        rows.append(res)
        print(f"{res['name']}: done", flush=True)
    text = table(rows)
    print(text)
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"task": task, "split": args.split, "dataset_fingerprint": ds.fingerprint,
                                   "seeds": ds.seeds.tolist(), "rows": rows,
                                   "versions": provenance.versions()}, indent=1))
        out.with_suffix(".md").write_text(f"# Autoencoders on {task} ({args.split} split)\n\n{text}\n")
        print(f"wrote {out} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
