"""Locating and compiling the task MJCF files."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco

_ENV_VAR = "READJAX_MJCF_DIR"


def mjcf_dir() -> Path:
    """Folder holding robot/, common/ and one MJCF per task.

    Looked up in order: $READJAX_MJCF_DIR, the package's installed copy (readjax/_mjcf, for
    wheels), the repository's tasks_mjcf/ next to the package.
    """
    if os.environ.get(_ENV_VAR):
        return Path(os.environ[_ENV_VAR])
    here = Path(__file__).resolve().parent.parent
    for cand in (here / "_mjcf", here.parent / "tasks_mjcf"):
        if (cand / "robot" / "panda.xml").exists():
            return cand
    raise FileNotFoundError(
        "cannot find the task MJCF folder (tasks_mjcf/); set READJAX_MJCF_DIR to its path"
    )


def load_model(xml_file: str) -> mujoco.MjModel:
    """Compile ``tasks_mjcf/<xml_file>`` (includes resolve relative to that folder)."""
    path = mjcf_dir() / xml_file
    if not path.exists():
        raise FileNotFoundError(f"no MJCF scene {path}")
    return mujoco.MjModel.from_xml_path(str(path))
