"""Shared command-line plumbing: readable errors instead of tracebacks for user mistakes."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import readjax  # noqa: F401  (XLA flags before jax is imported)
from readjax import _runtime
from readjax.data.store import DatasetError
from readjax.tasks import UnknownTaskError
from readjax.training import CheckpointError

USER_ERRORS = (ValueError, FileNotFoundError, DatasetError, UnknownTaskError, CheckpointError)


def run(main, argv=None) -> int:
    """Call ``main(argv)``; user errors print one line on stderr and exit with status 2; otherwise
    the exit status is what ``main`` returns (None: 0). A command run from the shell (``argv`` None)
    first restarts itself once with glibc's malloc tuned (``readjax._runtime.MALLOC_TUNABLES``: its
    steps 1.5-2x faster on the CPU; ``READJAX_MALLOC=system`` opts out), except for ``--help``."""
    if argv is None and not {"-h", "--help"} & set(sys.argv[1:]):
        _runtime.reexec_with_malloc_tunables()
    try:
        rc = main(argv)
    except USER_ERRORS as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; re-run the same command to resume", file=sys.stderr)
        return 130
    return int(rc or 0)


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Each option's default after its help, except where there is none to show (None: the help says
    what happens then) or the help already names it in its own words ("(default: ...")."""

    def _get_help_string(self, action):
        if action.default is None or "(default:" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def add_split_arguments(p: argparse.ArgumentParser) -> None:
    """--task, --data, --split, --episodes and --batch-size: which stored episodes a ground-truth
    replay executes (experiments.verify, experiments.tolerance), and how many at once."""
    p.add_argument("--task", required=True, help="task name or paper code")
    p.add_argument("--data", default="data", help="dataset root (holds <task>/<split>/)")
    p.add_argument("--split", default="test", choices=["train", "test", "val"])
    p.add_argument("--episodes", type=positive_int, default=None, help="the first N episodes (default: all)")
    p.add_argument("--batch-size", type=positive_int, default=32, help="episodes executed together")


def read_json_record(path, key: str, what: str) -> dict:
    """A JSON object that must hold ``key`` (``what`` names the kind, for the message): a missing file,
    broken JSON or another kind of record is a one-line error, raised before any work starts."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no {what} at {path}")
    try:
        record = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not JSON ({e})") from None
    if not isinstance(record, dict) or key not in record:
        raise ValueError(f"{path} is not a {what} (no {key!r})")
    return record


def add_ray_arguments(p: argparse.ArgumentParser, what: str) -> None:
    """--ray-address and --resources: where experiments.pipeline and experiments.sweep run their steps
    (:mod:`readjax.lab.ray_grid`), and what a ``what`` of each kind asks of a node."""
    from readjax.lab import ray_resources

    shown = "; ".join(f"{kind} " + ", ".join(f"{k}={v / ray_resources.GIB:g} GiB" if k == "memory" else f"{k}={v:g}"
                                               for k, v in opts.items())
                      for kind, opts in ray_resources.STEP_RESOURCES.items())
    p.add_argument("--ray-address", default=None, metavar="HOST:PORT",
                   help="the Ray cluster to run on (its head's address, as `ray start --head` prints it); default: "
                        "the RAY_ADDRESS variable, else an embedded Ray on this machine, as many steps at once as "
                        "it has cores")
    p.add_argument("--resources", nargs="+", default=[], metavar="KIND:KEY=VALUE,...",
                   help=f"what a {what} asks of the node that runs it, by KIND, beyond the defaults ({shown}; a "
                        f"training also num_gpus=1/{ray_resources.TRAININGS_PER_GPU} where the cluster has GPUs); KEY "
                        f"num_cpus, num_gpus or memory (GiB), e.g. train:num_gpus=0.5,memory=8")
