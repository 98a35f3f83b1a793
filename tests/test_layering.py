"""The models, the diffusion code and the motion format import downward only: no MuJoCo."""

import subprocess
import sys


def test_models_and_diffusion_do_not_import_mujoco():
    code = ("import sys; import readjax.models, readjax.diffusion, readjax.motion; "
            "print(sorted(m for m in sys.modules if m.startswith(('mujoco', 'readjax.sim'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
