"""readjax: READ (Retrieval-Enhanced Asymmetric Diffusion, CVPR 2024) in JAX and MuJoCo MJX.

Importing the package configures JAX for MJX on the CPU (see :mod:`readjax._runtime`); import
``readjax`` before ``jax`` in scripts.
"""

from readjax import _runtime

_runtime.configure_xla_flags()
_runtime.configure_gl()
_runtime.configure_jax()

__version__ = "0.1.0"


def __getattr__(name: str):
    """``readjax.Planner`` without importing the models on ``import readjax``."""
    if name == "Planner":
        from readjax.planner import Planner

        return Planner
    raise AttributeError(f"module 'readjax' has no attribute {name!r}")
