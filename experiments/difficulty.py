"""How hard each task is without any trained model: the paper's oracle rows (Table 5, "Cheat").

For every test episode, the i-th nearest training demonstration to its ground-truth motion
(i = 1, 3, 10) is executed in the episode's stored scene through the evaluation path, without
refinement, and the success rate is set beside the paper's own Cheat row. A task on which the
nearest of 1000 demonstrations already succeeds far more often than in the paper is an easier
benchmark than the paper's.

What it does for each task, resuming whatever exists: generate the training split (--train-episodes)
and the test split (--episodes) if they are missing or short, replay the test split's ground truth
(it must succeed 100 %; the record goes to RESULTS/<task>/verify/), execute the oracle's neighbours,
and write RESULTS/<task>/difficulty/<test fingerprint>.json. Then it prints the table of the tasks
asked for (with --tasks all: the 16-task table and Avg12 / Avg16), read from RESULTS.

examples:
  python -m experiments.difficulty --task PB                       # one task, end to end
  python -m experiments.difficulty --tasks all --table-only        # the committed 16-task table
  python -m experiments.difficulty --tasks PU SR --train-episodes 200 --episodes 50 --results /tmp/r
"""

from __future__ import annotations

import argparse
import sys

from experiments import _cli


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.difficulty", description=__doc__,
                                formatter_class=_cli.HelpFormatter)
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--task", help="one task (name or paper code)")
    g.add_argument("--tasks", nargs="+", help="several tasks, or 'all'")
    p.add_argument("--data", default="data", help="dataset root (holds <task>/train and <task>/test)")
    p.add_argument("--results", default="results", help="results root (records are committed there)")
    p.add_argument("--train-episodes", type=_cli.positive_int, default=1000,
                   help="training demonstrations the oracle chooses from")
    p.add_argument("--episodes", type=_cli.positive_int, default=100, help="test episodes")
    p.add_argument("--ranks", type=_cli.positive_int, nargs="+", default=[1, 3, 10],
                   help="which neighbours: 1 = the nearest")
    p.add_argument("--image-size", type=_cli.positive_int, default=None,
                   help="image size of generated splits (default: that of the task's existing splits, so the "
                        "pipeline's data is measured as it is; 128 where there are none). The oracle reads "
                        "motions, not images")
    p.add_argument("--batch-size", type=_cli.positive_int, default=32, help="episodes simulated together")
    p.add_argument("--table-only", action="store_true", help="measure nothing: print the table from RESULTS")
    p.add_argument("--force", action="store_true", help="measure again even where a record exists")
    p.add_argument("--unverified", action="store_true",
                   help="measure even where the test split's ground truth replays below 100 %% (the row is "
                        "marked ‡ in every table: the evaluation path does not reproduce every demonstration)")
    p.add_argument("--out", default=None, help="also write the table (markdown) to this file")
    return p


def _tasks(args) -> list[str]:
    from readjax import tasks

    names = [args.task] if args.task else args.tasks
    if len(names) == 1 and names[0].lower() == "all":
        return list(tasks.names())
    return [tasks.canonical_name(n) for n in names]


def _prepare(task: str, args) -> None:
    """Generate what is missing and replay the test split's ground truth if no record exists."""
    from readjax.lab import verification
    from readjax.data import store
    from readjax.data.generate import GenerateConfig, generate
    from readjax import tasks
    from readjax.evaluation import replay_ground_truth
    from readjax.sim.execute import execution_record

    size = args.image_size or store.existing_image_size(args.data, task) or GenerateConfig.image_size
    for split, n in (("train", args.train_episodes), ("test", args.episodes)):
        generate(GenerateConfig(task=task, split=split, episodes=n, out=args.data, batch_size=args.batch_size,
                                image_size=size))
    test = store.load_dataset(store.split_dir(args.data, task, "test"))
    if not verification.is_verified(args.results, task, test.fingerprint, args.episodes):
        on_record = verification.find(args.results, task, test.fingerprint) or {}
        if args.unverified and on_record.get("execution") == execution_record():
            return  # replayed below 100 % on record by this execution path: measured anyway, marked
        record = replay_ground_truth(tasks.make(task), test, batch_size=args.batch_size)
        verification.write(args.results, dict(record, data=str(store.split_dir(args.data, task, "test"))))
        if record["success_rate"] < 1.0 and not args.unverified:
            raise ValueError(f"{task}: the test split's ground truth replays at {100 * record['success_rate']:.1f} %, "
                             f"not 100 % (failed seeds {record['failed_seeds'][:10]}): the evaluation path does not "
                             f"measure what it says on this task; nothing measured")


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from readjax.data import store
    from readjax.lab import difficulty

    names = _tasks(args)
    if not args.table_only:
        for task in names:
            have = difficulty.load_records(args.results).get(task)
            if have and not args.force:
                try:
                    test = store.load_dataset(store.split_dir(args.data, task, "test"))
                    if have["test_fingerprint"] == test.fingerprint and have["episodes"] >= args.episodes:
                        print(f"{task}: record exists for test split {test.fingerprint}; --force to measure again")
                        continue
                except store.DatasetError:
                    pass  # no local split: generate it and measure
            _prepare(task, args)
            r = difficulty.measure(task, args.data, args.results, ranks=tuple(args.ranks), episodes=args.episodes,
                                   train_episodes=args.train_episodes, batch_size=args.batch_size,
                                   require_replay=not args.unverified)
            rates = " / ".join(f"{100 * r['ranks'][str(i)]['success_rate']:.0f}" for i in args.ranks)
            print(f"{task} ({r['code']}): oracle i = {'/'.join(map(str, args.ranks))}: {rates} %  "
                  f"(paper's Cheat: {' / '.join(str(v) for v in r['paper_cheat'].values())})")
    records = {t: r for t, r in difficulty.load_records(args.results).items() if t in names}
    text = difficulty.table(records, ranks=tuple(args.ranks))
    print(text)
    if args.out:
        from pathlib import Path

        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(_cli.run(main))
