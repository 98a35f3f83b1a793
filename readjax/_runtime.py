"""Process-wide JAX set-up that must happen before the first trace.

Why this exists (measured, see BENCHMARKS.md and ../shared/STACK.md):
* XLA's CPU fusion emitters make MJX 250-1000x slower, so they are switched off through
  ``XLA_FLAGS`` *before* jax is imported.
* jaxlib's batched LAPACK Cholesky deadlocks at batch ~128 on the CPU; MJX calls
  ``jax.scipy.linalg.cho_factor``/``cho_solve`` for the mass matrix, the implicitfast integrator
  and the Newton solver. On the CPU backend we route both through :mod:`readjax.linalg`, a
  pure-jnp Cholesky, so the lowered programs hold no LAPACK call.
* Compiles take 15-70 s each, so a persistent compilation cache is on by default.
* glibc's malloc hands every buffer above its mmap threshold (32 MiB at most) back to the kernel
  when it is freed, and XLA:CPU allocates a step's temporaries afresh on every call: a cpu-preset
  READ training step took ~74 000 page faults (~300 MB zeroed by the kernel), 40 % of its CPU time
  in the kernel. :data:`MALLOC_TUNABLES` keeps freed memory in the process (the steps 1.5-2x
  faster, the same bits); glibc reads them only at a process's start, so the CLIs restart
  themselves once with them (:func:`reexec_with_malloc_tunables`) and the pipeline passes them to
  its steps.
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


# glibc malloc: no mmap'd chunks (so nothing is unmapped on free), one arena (XLA's worker threads
# would otherwise allocate from per-thread arenas, whose oversized requests fall back to mmap), and
# no trimming of the heap's top below 4 GiB of free memory. A process's resident memory then stays
# at its peak instead of shrinking after it.
MALLOC_TUNABLES = (("glibc.malloc.mmap_max", "0"), ("glibc.malloc.trim_threshold", "4294967296"),
                   ("glibc.malloc.arena_max", "1"))
MALLOC_OPT_OUT = "READJAX_MALLOC"  # =system: leave glibc's malloc as it is
_REEXECED = "_READJAX_MALLOC_REEXEC"  # set in the restarted process: never restart twice


def malloc_opted_out(env) -> bool:
    """Whether ``env`` asks for glibc's malloc as it is (``READJAX_MALLOC=system``)."""
    return env.get(MALLOC_OPT_OUT) == "system"


def with_malloc_tunables(env) -> dict:
    """A copy of ``env`` whose GLIBC_TUNABLES holds :data:`MALLOC_TUNABLES`; a tunable the caller
    already set keeps the caller's value. Unchanged where ``READJAX_MALLOC=system``."""
    env = dict(env)
    if malloc_opted_out(env):
        return env
    given = [t for t in env.get("GLIBC_TUNABLES", "").split(":") if t]
    names = {t.split("=", 1)[0] for t in given}
    env["GLIBC_TUNABLES"] = ":".join(given + [f"{k}={v}" for k, v in MALLOC_TUNABLES if k not in names])
    return env


def malloc_tuned(env) -> bool:
    """Whether ``env`` already asks for every tunable (or opts out)."""
    return with_malloc_tunables(env).get("GLIBC_TUNABLES") == env.get("GLIBC_TUNABLES")


def reexec_with_malloc_tunables(argv=None, env=None, execve=os.execve, system: str = sys.platform,
                                libc: str | None = None) -> bool:
    """Restart this process (``argv``, default ``sys.orig_argv``) with :data:`MALLOC_TUNABLES` where
    glibc is the C library and they are not set yet; returns False where it does not (``execve``
    does not return). Call it first thing in a command's entry point, never in a library."""
    import platform

    env = os.environ if env is None else env
    libc = platform.libc_ver()[0] if libc is None else libc
    if system != "linux" or libc != "glibc" or malloc_tuned(env) or env.get(_REEXECED):
        return False
    argv = list(sys.orig_argv if argv is None else argv)
    sys.stdout.flush()
    sys.stderr.flush()
    execve(sys.executable, [sys.executable] + argv[1:], {**with_malloc_tunables(env), _REEXECED: "1"})
    return True


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


# --- compiled-code mappings ---------------------------------------------------------------------
# XLA's CPU backend gives every compiled kernel its own memory mappings (code, read-only data,
# data): ~150 for a small jitted function, thousands for an MJX rollout. Linux caps mappings per
# process (vm.max_map_count, 65530 by default), and a compile past the cap segfaults inside LLVM.
# A process that compiles hundreds of programs (the test suite, a training-and-evaluation sweep)
# reached it (BENCHMARKS 8i). Dropping JAX's in-memory executable caches unmaps them; a later call
# recompiles, from the persistent cache when it is on.


def map_count(maps_path: str = "/proc/self/maps") -> int | None:
    """Memory mappings this process holds (None where /proc is absent: not Linux)."""
    try:
        with open(maps_path, "rb") as f:
            return sum(1 for _ in f)
    except OSError:
        return None


def map_limit(limit_path: str = "/proc/sys/vm/max_map_count") -> int | None:
    """The kernel's cap on one process's mappings (None where unreadable)."""
    try:
        with open(limit_path) as f:
            return int(f.read().strip())
    except (OSError, ValueError):
        return None


def release_compiled_if_crowded(fraction: float = 0.5, count: int | None = None,
                                limit: int | None = None) -> bool:
    """Free JAX's compiled executables (``jax.clear_caches`` and a garbage collection) when this
    process holds more than ``fraction`` of the kernel's mapping cap; True if it did. Call it
    between independent units of work (a test, a sweep cell): cheap (one read of /proc) and a
    no-op until the process gets near the cap. ``count`` / ``limit`` default to the live values."""
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction}")
    count = map_count() if count is None else count
    limit = map_limit() if limit is None else limit
    if count is None or limit is None or count <= fraction * limit:
        return False
    import gc

    import jax

    jax.clear_caches()
    gc.collect()
    return True
