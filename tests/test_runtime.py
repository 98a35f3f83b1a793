"""Process set-up: XLA flags only where the installed jaxlib knows them (XLA aborts otherwise), and a
headless GL backend that exists on the machine (else `import mujoco` fails)."""

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
