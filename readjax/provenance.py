"""Software versions and machine facts recorded beside every dataset, checkpoint and result."""

from __future__ import annotations

import platform

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
