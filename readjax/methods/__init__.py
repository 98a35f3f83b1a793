"""The methods: READ, its ablations and the paper's baselines, behind one interface.

Each method module offers ``train(task, data_root, run_dir, configs, preset, stages, progress,
stop_at) -> run spec`` and a model class loaded from a run folder (``load_model``) with
``encode``, ``generate`` and, for retrieval-based methods, ``database_tokens``/``spe_distances``.
"""

from __future__ import annotations

import importlib

from readjax.methods import base

# method name -> (module, model class, training stages)
METHODS = {
    "read": ("readjax.methods.read", "ReadModel", ("vae", "read")),
}


def names() -> tuple[str, ...]:
    return tuple(METHODS)


def module(name: str):
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; known: {', '.join(METHODS)}")
    return importlib.import_module(METHODS[name][0])


def stages(name: str) -> tuple[str, ...]:
    module(name)
    return METHODS[name][2]


def load_model(run_dir):
    """The trained model of a run folder (its method is read from run.json)."""
    spec = base.read_run(run_dir)
    name = spec.get("method", "read")
    return getattr(module(name), METHODS[name][1])(run_dir)
