"""Process set-up: XLA flags only where the installed jaxlib knows them (XLA aborts otherwise), and a
headless GL backend that exists on the machine (else `import mujoco` fails), compiled code
released before the process reaches the kernel's cap on memory mappings, and glibc's malloc tuned
in every command's process (XLA:CPU's steps page-fault their temporaries in afresh otherwise)."""

import os
import platform
import subprocess
import sys

import pytest

from readjax import _runtime
from readjax._runtime import fusion_flag_known


def test_fusion_flag_only_for_jaxlib_before_0_11():
    assert fusion_flag_known("0.10.2")
    assert fusion_flag_known("0.4.38")
    assert not fusion_flag_known("0.11.2")
    assert not fusion_flag_known("1.0.0")


def test_unknown_versions_keep_the_flag():
    assert fusion_flag_known(None)
    assert fusion_flag_known("dev")


def test_gl_backend_falls_back_when_egl_is_missing():
    from readjax._runtime import choose_gl

    assert choose_gl(lambda name: "lib" + name if name in ("EGL", "OSMesa") else None) == "egl"
    assert choose_gl(lambda name: "libOSMesa.so" if name == "OSMesa" else None) == "osmesa"
    assert choose_gl(lambda name: None) == "glfw"


def test_map_count_reads_a_maps_file(tmp_path):
    maps = tmp_path / "maps"
    maps.write_text("a\nb\nc\n")
    assert _runtime.map_count(str(maps)) == 3
    assert _runtime.map_count(str(tmp_path / "absent")) is None
    limit = tmp_path / "max_map_count"
    limit.write_text("65530\n")
    assert _runtime.map_limit(str(limit)) == 65530
    limit.write_text("not a number")
    assert _runtime.map_limit(str(limit)) is None


def test_release_frees_compiled_code_only_when_crowded():
    """Compiled executables hold memory mappings until JAX's caches drop them; the release is a
    no-op below the threshold and unmaps them above it, while the jitted function still works."""
    import jax
    import jax.numpy as jnp

    if _runtime.map_count() is None:
        pytest.skip("no /proc/self/maps on this platform")

    def f(x):
        for j in range(20):
            x = jnp.tanh(x @ x.T + j) + jnp.sin(x).sum(0)
        return x

    jax.clear_caches()
    before = _runtime.map_count()
    fn = jax.jit(f)
    expected = fn(jnp.ones((16, 16)))
    held = _runtime.map_count() - before
    assert held > 20, f"a 40-kernel program should hold many mappings, held {held}"
    assert not _runtime.release_compiled_if_crowded(0.5, count=10, limit=100)
    assert _runtime.map_count() - before >= held
    assert _runtime.release_compiled_if_crowded(0.5, count=60, limit=100)
    assert _runtime.map_count() - before < held / 2
    assert jnp.array_equal(fn(jnp.ones((16, 16))), expected)  # recompiles on demand
    with pytest.raises(ValueError, match="fraction"):
        _runtime.release_compiled_if_crowded(1.5)


# --- glibc malloc tuning -------------------------------------------------------------------------


def test_malloc_tunables_join_the_callers_own_and_keep_their_values():
    env = _runtime.with_malloc_tunables({"GLIBC_TUNABLES": "glibc.malloc.arena_max=4:glibc.rtld.nns=8", "X": "1"})
    tunables = env["GLIBC_TUNABLES"].split(":")
    assert tunables[:2] == ["glibc.malloc.arena_max=4", "glibc.rtld.nns=8"]
    assert "glibc.malloc.mmap_max=0" in tunables and "glibc.malloc.arena_max=1" not in tunables
    assert env["X"] == "1" and _runtime.malloc_tuned(env) and not _runtime.malloc_tuned({"X": "1"})
    fresh = _runtime.with_malloc_tunables({})["GLIBC_TUNABLES"]
    assert fresh == ":".join(f"{k}={v}" for k, v in _runtime.MALLOC_TUNABLES)
    assert _runtime.with_malloc_tunables({"READJAX_MALLOC": "system"}) == {"READJAX_MALLOC": "system"}


def test_a_command_restarts_once_with_the_tunables_and_only_under_glibc():
    calls = []

    def execve(path, argv, env):
        calls.append((argv, env))

    argv = ["/some/python", "-m", "experiments.train", "--task", "RT"]
    assert _runtime.reexec_with_malloc_tunables(argv, {"A": "1"}, execve, "linux", "glibc")
    (new_argv, env), = calls
    assert new_argv[1:] == argv[1:] and env["A"] == "1" and _runtime.malloc_tuned(env)
    # the restarted process (or one started tuned, or opted out, or not on glibc) runs on
    assert not _runtime.reexec_with_malloc_tunables(argv, env, execve, "linux", "glibc")
    assert not _runtime.reexec_with_malloc_tunables(argv, {"READJAX_MALLOC": "system"}, execve, "linux", "glibc")
    assert not _runtime.reexec_with_malloc_tunables(argv, {}, execve, "darwin", "")
    assert not _runtime.reexec_with_malloc_tunables(argv, {}, execve, "linux", "musl")
    assert len(calls) == 1


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc", reason="glibc only")
def test_a_command_from_the_shell_runs_with_the_tunables(tmp_path):
    """End to end: a command run from the shell (``_cli.run`` with no argv) restarts itself tuned,
    and a pipeline step's process is started tuned (no restart)."""
    from readjax.lab import steps

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {k: v for k, v in os.environ.items() if k not in ("GLIBC_TUNABLES", "READJAX_MALLOC")}
    probe = tmp_path / "probe.py"
    probe.write_text("import os, sys\nfrom experiments import _cli\n"
                     "def main(argv):\n    print(os.environ.get('GLIBC_TUNABLES', ''))\n"
                     "sys.exit(_cli.run(main))\n")
    out = subprocess.run([sys.executable, str(probe)], env={**env, "PYTHONPATH": root}, capture_output=True,
                         text=True, check=True)
    assert _runtime.malloc_tuned({"GLIBC_TUNABLES": out.stdout.strip()})
    log = tmp_path / "step.log"
    assert steps.launch([sys.executable, "-c", "import os; print(os.environ.get('GLIBC_TUNABLES', ''), "
                         "os.environ.get('_READJAX_MALLOC_REEXEC'))"], log) == 0
    tunables, restarted = log.read_text().split()
    assert _runtime.malloc_tuned({"GLIBC_TUNABLES": tunables}) and restarted == "None"
