"""Choose a READ run's refinement setting on the validation split, never on the test episodes.

Reads the run's validation evaluations, one per candidate --setting (experiments.evaluate --split val,
their JSONs in RESULTS/<task>/<run>/val/, each on a val split whose ground-truth replay is on record:
experiments.verify --split val --results RESULTS), keeps the setting with the highest val success (ties:
the one closest to the paper's recipe, rounds 1, renoise, candidates 1) and writes
RESULTS/<task>/<run>/choice.json: the chosen setting and its evaluate flags, every candidate's val
success and episodes, the val split's fingerprint, the rule and the commit. The run's test evaluations
then take it with experiments.evaluate --choice FILE. experiments.pipeline runs this per READ run.

examples:
  python -m experiments.choose --task RT --run-name read --N 100 --episodes 100 \\
      --setting rounds=1,refine=renoise --setting rounds=2,refine=cold_anchor --results results/
"""

from __future__ import annotations

import argparse
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.choose", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    p.add_argument("--task", required=True, help="task name or paper code")
    p.add_argument("--run-name", required=True, help="the run's folder name (RESULTS/<task>/<run>/)")
    p.add_argument("--N", type=_cli.positive_int, required=True, help="the refinement steps the candidates ran at")
    p.add_argument("--episodes", type=_cli.positive_int, required=True, help="val episodes each candidate ran on")
    p.add_argument("--setting", action="append", required=True, metavar="rounds=R,refine=U[,candidates=C]",
                   help="a candidate setting (repeat for each); its val evaluation must be in RESULTS")
    p.add_argument("--results", default="results", help="the results root (holds <task>/<run>/val/ and <task>/verify/)")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from readjax import tasks
    from readjax.lab import choice as choice_lib
    from readjax.lab.refine_setting import RefineSetting

    task = tasks.canonical_name(args.task)
    settings = list(dict.fromkeys(RefineSetting.parse(s) for s in args.setting))
    made = choice_lib.make_choice(args.results, task, args.run_name, settings, args.N, args.episodes)
    path = choice_lib.write_choice(args.results, made)
    for c in made["candidates"]:
        s = RefineSetting(**c["setting"])
        mark = "  <- chosen" if c["setting"] == made["chosen"] else ""
        print(f"{s.text():45s} val {100 * c['success_rate']:5.1f} % ({c['successes']}/{c['episodes']}){mark}")
    print(f"{task}/{args.run_name}: chose {' '.join(made['flags'])} on val split {made['val_fingerprint']}; "
          f"written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
