"""Version bisection: the MJX micro-benchmark (experiments/bench_mjx_step.py) under several
jax / mujoco / mujoco-mjx combinations, each in its own virtual environment, interleaved and
repeated so that a noisy shared machine affects all alike.

Make the environments first, e.g.:
  python3 -m venv /tmp/venvs/m4 && /tmp/venvs/m4/bin/pip install jax==0.10.2 jaxlib==0.10.2 \\
      mujoco==4.0.0 mujoco-mjx==3.17.0
then:
  python -m experiments.bench_versions --venv pinned=.venv --venv m4=/tmp/venvs/m4 --rounds 2
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from experiments import _cli

SCRIPT = Path(__file__).resolve().parent / "bench_mjx_step.py"


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.bench_versions", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--venv", action="append", required=True, metavar="NAME=PATH",
                   help="a labelled virtual environment to benchmark (repeat)")
    p.add_argument("--batch", type=_cli.positive_int, default=32)
    p.add_argument("--rounds", type=_cli.positive_int, default=2, help="interleaved repetitions")
    p.add_argument("--out", default="runs/bench/versions.json")
    return p


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    venvs = {}
    for item in args.venv:
        name, _, path = item.partition("=")
        py = Path(path) / "bin" / "python"
        if not py.exists():
            raise FileNotFoundError(f"no python in virtual environment {path}")
        venvs[name] = py
    runs: dict[str, list[dict]] = {n: [] for n in venvs}
    for r in range(args.rounds):
        for name, py in venvs.items():
            proc = subprocess.run([str(py), str(SCRIPT), str(args.batch)], capture_output=True, text=True,
                                  timeout=1800)
            line = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
            if proc.returncode or not line:
                runs[name].append({"error": (proc.stderr or proc.stdout)[-400:]})
                print(f"round {r + 1} {name}: failed", flush=True)
                continue
            runs[name].append(json.loads(line[-1]))
            print(f"round {r + 1} {name}: {line[-1]}", flush=True)
    summary = {}
    for name, rs in runs.items():
        ok = [x for x in rs if "error" not in x]
        if ok:
            summary[name] = {"jax": ok[0]["jax"], "mujoco": ok[0]["mujoco"],
                             "steps_per_s": statistics.median(x["steps_per_s"] for x in ok),
                             "compile_s": statistics.median(x["compile_s"] for x in ok)}
        else:
            summary[name] = {"error": rs[-1]["error"]}
    base = summary.get(next(iter(venvs)), {}).get("steps_per_s")
    print(f"{'env':<10} {'jax':>8} {'mujoco':>8} {'steps/s':>9} {'ratio':>6} {'compile s':>9}")
    for name, s in summary.items():
        if "error" in s:
            print(f"{name:<10} failed: {s['error'][-120:]!r}")
        else:
            ratio = s["steps_per_s"] / base if base else float("nan")
            print(f"{name:<10} {s['jax']:>8} {s['mujoco']:>8} {s['steps_per_s']:>9.0f} {ratio:>6.2f} "
                  f"{s['compile_s']:>9.1f}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"batch": args.batch, "runs": runs, "summary": summary}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(_cli.run(main))
