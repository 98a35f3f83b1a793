#!/usr/bin/env bash
# One-time set-up of a fresh machine (idempotent; `make` calls it):
#   1. system libraries for offscreen rendering (EGL/OSMesa via Mesa) with apt, when missing
#   2. a virtual environment in .venv with readjax and its pinned dependencies (+ dev extra)
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES="libegl1 libegl-mesa0 libgl1-mesa-dri libglx-mesa0 libosmesa6"
missing=""
for p in $APT_PACKAGES; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "setup: installing system packages:$missing"
  if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null; then SUDO="sudo"; else
    echo "setup: cannot install$missing (not root, no sudo); rendering needs them" >&2; exit 1; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
fi

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
  echo "setup: readjax pins need Python 3.11 (found $("$PY" --version)); set PYTHON=python3.11" >&2
  exit 1
fi
STAMP=.venv/.readjax-installed
if [ ! -f "$STAMP" ] || [ pyproject.toml -nt "$STAMP" ]; then
  [ -x .venv/bin/python ] || "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
  # torch==2.13.0 (dev extra) resolves to the local CPU wheel; never let pip pick a CUDA build
  .venv/bin/python -m pip install -q -e ".[dev]"
  touch "$STAMP"
fi
echo "setup: ok ($(.venv/bin/python -c 'import jax, mujoco; print("jax", jax.__version__, "mujoco", mujoco.__version__)' 2>/dev/null | tail -1))"
