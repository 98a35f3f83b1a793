"""Software versions and machine facts recorded beside every dataset, checkpoint and result."""

from __future__ import annotations

import functools
import platform
import subprocess
from pathlib import Path

import jax

from readjax._runtime import installed_version

PACKAGES = ("readjax", "jax", "jaxlib", "flax", "optax", "orbax-checkpoint", "mujoco", "mujoco-mjx",
            "numpy", "scipy", "h5py")


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for p in PACKAGES:
        out[p] = installed_version(p) or "not installed"
    return out


def machine() -> dict[str, str]:
    devs = jax.devices()
    return {"platform": platform.platform(), "backend": jax.default_backend(),
            "devices": f"{len(devs)} x {devs[0].device_kind}"}


@functools.cache
def commit() -> str:
    """The git commit of the readjax checkout running this ("<sha>" plus "-dirty" when tracked files
    differ from it), or "unknown" outside a git checkout (an installed wheel)."""
    root = Path(__file__).resolve().parent.parent

    def git(*args):
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10)

    try:
        head = git("rev-parse", "--short=12", "HEAD")
        if head.returncode != 0:
            return "unknown"
        dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head.stdout.strip() + ("-dirty" if dirty else "")
