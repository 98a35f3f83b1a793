"""A Table-7 sweep's grid and its cells' settings: the keys it varies (N at test time; K, L, T in
training: ``TRAIN_KEYS``), the paper's setting A (``DEFAULTS``), a grid parsed from the command line
(``parse_grid``), the sweep's config (``SweepConfig``), the settings it trains (``cell_settings``) and
the config overrides of each (``cell_overrides``). :mod:`readjax.lab.sweep` runs a sweep.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

from readjax import config

TEST_TIME = ("N",)
TRAIN_KEYS = {"K": "train.K", "L": "sde.lam", "T": "sde.theta1"}
DEFAULTS = {"N": config.DEFAULT_N, "K": 3, "L": 0.5, "T": 2.0}  # the paper's setting A (its paper preset's)
CELL_PREFIX = "sweep_"  # a cell's evaluation is RUN/eval/<CELL_PREFIX>N<n>.json (reports list it by sweep)


def setting_of(configs: dict, n: int = config.DEFAULT_N) -> dict:
    """The Table-7 values a run is trained with (its configs after the preset and the overrides) at N."""
    return {"N": n, "K": configs["train"].K, "L": configs["sde"].lam, "T": configs["sde"].theta1}


def parse_grid(items) -> dict[str, list]:
    """["N=1,10,100", "L=0.1,0.5"] -> {"N": [1, 10, 100], "L": [0.1, 0.5]}."""
    grid = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"grid entry {item!r} is not of the form KEY=v1,v2,...")
        key, values = item.split("=", 1)
        key = key.strip()
        if key not in DEFAULTS:
            raise ValueError(f"cannot sweep {key!r}; sweepable: {', '.join(DEFAULTS)}")
        try:
            vals = [int(v) if key in ("N", "K") else float(v) for v in values.split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"grid {key}: expected numbers, got {values!r}") from None
        if not vals:
            raise ValueError(f"grid {key} has no values")
        if key in ("N", "K") and min(vals) < (0 if key == "N" else 1):
            raise ValueError(f"grid {key} values must be >= {0 if key == 'N' else 1}")
        grid[key] = vals
    if not grid:
        raise ValueError("empty grid: give at least one of N=..., K=..., L=..., T=...")
    return grid


@dataclass(frozen=True)
class SweepConfig:
    task: str
    grid: dict = field(default_factory=dict)
    model: str = "read"
    preset: str = "cpu"
    data: str = "data"
    out: str = "runs"
    name: str = "sweep"
    episodes: int = 100
    sets: tuple = ()
    batch_size: int = 50
    results: str | None = None  # also write sweep.json / table.md / sweep.png to RESULTS/<task>/<name>/
    # a finished run trained exactly as setting A (e.g. the grid's READ run): the cell of that setting
    # evaluates it instead of training it again (checked: its recipe and training set must match)
    reference_run: str | None = None
    # "all": every combination of the grid's values; "one": Table 7's layout, setting A and each key
    # varied alone from it (the other keys at A's values; N varied at A's training only)
    vary: str = "all"
    # the Ray cluster the cells train on (None: RAY_ADDRESS, else an embedded Ray on this machine), and
    # what a training asks of a node there beyond ray_resources.STEP_RESOURCES (``--resources``: train:KEY=VALUE,...)
    ray_address: str | None = None
    resources: tuple = ()
    # also keep committed cells measured on the same seeds but another version of the test split (another
    # CPU's float rounding of the expert's motions: the same scenes and images, fingerprints differ);
    # off, such cells are trained again. The table marks each pair across versions (VERSION_MARK).
    other_split_versions: bool = False


def value_label(v) -> str:
    """How a swept value is written (a folder name, a table cell): 0.5, 2 (a float as ``:g``), 100."""
    return f"{v:g}" if isinstance(v, float) else str(v)


def cell_settings(grid: dict, reference: dict, vary: str = "all") -> list[dict]:
    """The trained settings of a sweep, each {key: value} over the grid's training keys (K, L, T):
    ``vary`` "all" every combination; "one" Table 7's: setting A first, then each key's other values
    with the rest at A."""
    keys = [k for k in TRAIN_KEYS if k in grid]
    if vary == "all":
        return [dict(zip(keys, combo)) for combo in itertools.product(*[grid[k] for k in keys])] or [{}]
    a = {k: reference[k] for k in keys}
    return [a] + [{**a, k: v} for k in keys for v in grid[k] if v != reference[k]]


def cell_overrides(cfg: SweepConfig, values: dict) -> list[str]:
    """The config overrides a cell trains with: the sweep's --set, then the cell's K / L / T."""
    return list(cfg.sets) + [f"{TRAIN_KEYS[k]}={v}" for k, v in values.items()]
