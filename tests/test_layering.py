"""The models, the diffusion code and the motion format import downward only: no MuJoCo."""

import subprocess
import sys


def test_models_and_diffusion_do_not_import_mujoco():
    code = ("import sys; import readjax.models, readjax.diffusion, readjax.motion; "
            "print(sorted(m for m in sys.modules if m.startswith(('mujoco', 'readjax.sim'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_the_library_never_imports_the_lab():
    """readjax.lab (grids, sweeps, reports, diagnostics) imports the library; nothing outside readjax/lab
    imports readjax.lab, in code or at run time."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "readjax"
    offenders = []
    for f in root.rglob("*.py"):
        if "lab" in f.relative_to(root).parts:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            if any(n == "readjax.lab" or n.startswith("readjax.lab.") for n in names):
                offenders.append(str(f.relative_to(root)))
    assert offenders == []
    code = ("import sys; import readjax, readjax.planner, readjax.evaluation, readjax.training, readjax.methods, "
            "readjax.data.generate, readjax.tasks; print(sorted(m for m in sys.modules if m.startswith('readjax.lab')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout
