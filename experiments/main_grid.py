"""Run the current suite's main table (issue 52's grid) end to end, resumably: phase A (seed 0 of READ and
Deterministic on all 16 tasks), then phase B (seeds 1 and 2 and the paper's recipe on eight tasks, and the
paper's Tables 5 and 8). Each phase is one `experiments.pipeline` command built from the plan that the
pages report against (readjax/lab/grid_plan.py), so what runs and what the tables call pending agree.

Stopped at any point (Ctrl-C, kill, a machine given back), the same command resumes: each phase skips
what results/ already holds and, on a fresh machine, regenerates and verifies only the data that an
unfinished step needs. A phase that ends with a failed step stops the grid (its error names it).
Arguments after `--` go to every phase's pipeline command (--ray-address, --data, --runs, --resources...).

examples:
  python -m experiments.main_grid --print                 # the two pipeline commands, run nothing
  python -m experiments.main_grid --dry-run               # each phase's steps: done / skip / todo, with ETAs
  nohup python -m experiments.main_grid >> grid.log 2>&1 &
  python -m experiments.main_grid --phases B -- --ray-address 10.0.0.1:6379
  python -m experiments.main_grid -- --deadline +170m   # a 3-hour job: start nothing that would not land
"""

from __future__ import annotations

import argparse
import shlex
import signal
import subprocess
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.main_grid", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--phases", nargs="+", default=["A", "B"], choices=["A", "B"], help="phases to run, in order")
    p.add_argument("--print", action="store_true", help="print each phase's pipeline command and run nothing")
    p.add_argument("--dry-run", action="store_true", help="each phase's pipeline --dry-run (starts no Ray)")
    p.add_argument("extra", nargs=argparse.REMAINDER, metavar="-- ARG",
                   help="arguments appended to every phase's pipeline command")
    return p


def commands(phases, extra=(), dry_run: bool = False) -> list[list[str]]:
    """The pipeline command lines of ``phases``, in order."""
    from readjax.lab.grid_plan import pipeline_argvs

    argvs = pipeline_argvs()
    extra = list(extra)[1:] if list(extra)[:1] == ["--"] else list(extra)  # the separator, not a later "--"
    return [[sys.executable, "-m", "experiments.pipeline", *argvs[ph], *extra, *(["--dry-run"] if dry_run else [])]
            for ph in phases]


def _run(cmd: list[str]) -> int:
    """Run one phase; a SIGTERM to this process goes on to it (the pipeline stops its steps and records them)."""
    child = subprocess.Popen(cmd)
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: child.send_signal(signum))
    try:
        return child.wait()
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    cmds = commands(args.phases, args.extra, args.dry_run)
    for phase, cmd in zip(args.phases, cmds):
        print(f"# phase {phase}: " + shlex.join(cmd[1:]), flush=True)
        if args.print:
            continue
        rc = _run(cmd)
        if rc:
            print(f"phase {phase} ended with status {rc}; re-run this command to resume", file=sys.stderr)
            return rc
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
