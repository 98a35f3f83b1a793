"""What each step of a grid or a sweep asks of the Ray node that runs it (CPUs, a share of a GPU,
memory), by kind of step: the defaults, ``--resources`` overrides, and the check that some node of the
cluster can run every kind asked for (:mod:`readjax.lab.ray_grid` runs the steps)."""

from __future__ import annotations

from readjax.lab.steps import PipelineError

GIB = 1024 ** 3
# What a step asks of the node that runs it, by kind (Ray's task options; memory in bytes): one CPU
# each, so a machine runs as many steps at once as it has cores, and memory: the tiny grid's steps
# peak at 0.9-1.3 GB (RSS, measured: docs/cluster.md), the cpu preset's full-size ones were not
# measured, hence the room. ``--resources KIND:KEY=VALUE,...`` changes them.
STEP_RESOURCES = {
    "generate": {"num_cpus": 1, "memory": 2 * GIB},
    "verify": {"num_cpus": 1, "memory": 2 * GIB},
    "train": {"num_cpus": 1, "memory": 3 * GIB},
    "evaluate": {"num_cpus": 1, "memory": 2 * GIB},
    "media": {"num_cpus": 1, "memory": 2 * GIB},
    "choose": {"num_cpus": 1, "memory": 1 * GIB},  # reads the val evaluations' JSONs, writes the choice
}
# where the cluster has GPUs a training asks for this share of one (a GPU holds a dozen of the cpu
# preset's trainings; JAX's preallocation is turned off for them), and only the trainings: the GPU
# nodes take them, the CPU nodes the rest
TRAININGS_PER_GPU = 12


def parse_resources(items) -> dict[str, dict]:
    """``["train:num_gpus=0.5,memory=8", "evaluate:num_cpus=2"]`` -> {kind: {option: value}}, memory
    given in GiB."""
    out: dict[str, dict] = {}
    for item in items:
        kind, _, pairs = item.partition(":")
        if kind not in STEP_RESOURCES or not pairs:
            raise ValueError(f"--resources {item!r}: expected KIND:KEY=VALUE[,KEY=VALUE], KIND one of "
                             f"{', '.join(STEP_RESOURCES)}")
        for pair in pairs.split(","):
            key, _, value = pair.partition("=")
            if key not in ("num_cpus", "num_gpus", "memory"):
                raise ValueError(f"--resources {item!r}: KEY is num_cpus, num_gpus or memory (GiB), got {key!r}")
            try:
                v = float(value)
            except ValueError:
                raise ValueError(f"--resources {item!r}: {key} must be a number, got {value!r}") from None
            if v < 0:
                raise ValueError(f"--resources {item!r}: {key} must be >= 0")
            out.setdefault(kind, {})[key] = int(v * GIB) if key == "memory" else v
    return out


def step_resources(overrides: dict | None = None, gpus: float = 0.0) -> dict[str, dict]:
    """Each kind's Ray options: :data:`STEP_RESOURCES`, a training's share of a GPU where the cluster
    has ``gpus``, then ``overrides`` (:func:`parse_resources`)."""
    out = {kind: dict(options) for kind, options in STEP_RESOURCES.items()}
    if gpus > 0:
        out["train"]["num_gpus"] = 1 / TRAININGS_PER_GPU
    for kind, options in (overrides or {}).items():
        out[kind].update(options)
    return out


_RAY_NAMES = {"num_cpus": "CPU", "num_gpus": "GPU", "memory": "memory"}


def check_fits(demands: dict[str, dict], kinds, nodes: list[dict]) -> None:
    """Refuse a grid with a kind of step that no node of the cluster could ever run (Ray would wait
    for it forever): naming the kind, what it asks and how to ask for less."""
    totals = [n["Resources"] for n in nodes if n.get("Alive")]
    for kind in sorted(set(kinds)):
        ask = {name: demands[kind][k] for k, name in _RAY_NAMES.items() if demands[kind].get(k)}
        if not any(all(node.get(k, 0) >= v for k, v in ask.items()) for node in totals):
            shown = ", ".join(f"{k} {v / GIB:.1f} GiB" if k == "memory" else f"{k} {v:g}" for k, v in ask.items())
            raise PipelineError(f"no node of the Ray cluster has what a {kind} step asks ({shown}); ask for less "
                                f"with --resources {kind}:KEY=VALUE (docs/cluster.md)")
