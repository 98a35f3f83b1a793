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
    # METHOD.md section 10: variants and baselines
    "read_o": ("readjax.methods.read_o", "ReadOModel", ("read_o",)),
    "read_l": ("readjax.methods.read_l", "ReadLModel", ("vae", "read_l")),
    "deterministic": ("readjax.methods.deterministic", "DeterministicModel", ("deterministic",)),
    "vpsde": ("readjax.methods.vpsde", "VPSDEModel", ("vpsde",)),
    "vpsde_cg": ("readjax.methods.vpsde_cg", "VPSDECGModel", ("vpsde_cg",)),
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
