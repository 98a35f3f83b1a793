"""Process set-up: XLA flags only where the installed jaxlib knows them (XLA aborts otherwise), and a
headless GL backend that exists on the machine (else `import mujoco` fails), and compiled code
released before the process reaches the kernel's cap on memory mappings."""

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
