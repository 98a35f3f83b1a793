"""Process-wide JAX set-up that must happen before the first trace.

Why this exists (measured, see BENCHMARKS.md and ../shared/STACK.md):
* XLA's CPU fusion emitters make MJX 250-1000x slower, so they are switched off through
  ``XLA_FLAGS`` *before* jax is imported.
* jaxlib's batched LAPACK Cholesky deadlocks at batch ~128 on the CPU; MJX calls
  ``jax.scipy.linalg.cho_factor``/``cho_solve`` for the mass matrix, the implicitfast integrator
  and the Newton solver. On the CPU backend we route both through :mod:`readjax.linalg`, a
  pure-jnp Cholesky, so the lowered programs hold no LAPACK call.
* Compiles take 15-70 s each, so a persistent compilation cache is on by default.
* The default PRNG is "rbg": with the fusion emitters off, every threefry op costs ~2 s of
  compile time on the CPU (a UNet init compiled in 50 s with threefry, 6 s with rbg). Keys are
  still explicit and every result is a pure function of its seed on one machine.
"""

from __future__ import annotations

import ctypes.util
import os
import sys
import warnings
from importlib import metadata

_CPU_FLAG = "--xla_cpu_use_fusion_emitters=false"


def fusion_flag_known(jaxlib_version: str | None) -> bool:
    """Whether this jaxlib's XLA still has the fusion-emitter flag.

    jaxlib 0.11 dropped it, and XLA aborts the process on an unknown flag in XLA_FLAGS (seen with
    jaxlib 0.11.2, the version on the lent GPU machines), so the flag is only set for older ones.
    """
    if jaxlib_version is None:
        return True
    try:
        major, minor = (int(p) for p in jaxlib_version.split(".")[:2])
    except ValueError:
        return True
    return (major, minor) < (0, 11)


def installed_version(package: str) -> str | None:
    """An installed distribution's version, None if absent (no import of the package itself)."""
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def configure_xla_flags() -> None:
    """Append the CPU fusion-emitter flag to XLA_FLAGS (idempotent) where jaxlib knows it."""
    flags = os.environ.get("XLA_FLAGS", "")
    if not fusion_flag_known(installed_version("jaxlib")):
        return
    if "xla_cpu_use_fusion_emitters" not in flags:
        os.environ["XLA_FLAGS"] = (flags + " " + _CPU_FLAG).strip()
    if "jax" in sys.modules and "xla_cpu_use_fusion_emitters" not in flags:
        warnings.warn(
            "jax was imported before readjax; XLA_FLAGS=--xla_cpu_use_fusion_emitters=false may not "
            "take effect and MJX can be 100x slower on the CPU. Import readjax first or export the flag.",
            stacklevel=3,
        )


def choose_gl(find_library) -> str:
    """The MUJOCO_GL backend for headless rendering: EGL where libEGL exists, else OSMesa, else
    glfw. Asking for EGL where libEGL is missing makes ``import mujoco`` itself fail (PyOpenGL
    raises AttributeError, seen on the lent GPU machines), while glfw imports everywhere and only
    a renderer created without a display fails, so simulation-only work still runs."""
    if find_library("EGL"):
        return "egl"
    if find_library("OSMesa"):
        return "osmesa"
    return "glfw"


def configure_gl() -> None:
    """Headless OpenGL for mujoco.Renderer (must be chosen before mujoco is imported)."""
    if "MUJOCO_GL" not in os.environ:
        os.environ["MUJOCO_GL"] = choose_gl(ctypes.util.find_library)
    if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])


def default_cache_dir() -> str:
    return os.environ.get(
        "READJAX_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "readjax", "jax")
    )


def configure_jax() -> None:
    """Persistent compilation cache and the CPU Cholesky replacement."""
    import jax

    cache = default_cache_dir()
    if cache and cache.lower() != "off":
        os.makedirs(cache, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    if os.environ.get("READJAX_PRNG", "rbg") != "threefry":
        jax.config.update("jax_default_prng_impl", "rbg")
    from readjax import linalg

    linalg.install_cpu_cholesky()
