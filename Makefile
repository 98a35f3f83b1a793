# The two commands of the README: `make demo` (the main job) and `make test`.
# Both set up a fresh machine first (apt GL libraries if missing, .venv, pinned packages).
PY := .venv/bin/python
export MUJOCO_GL ?= egl

.PHONY: setup demo test test-slow bench gallery

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m experiments.demo

# Two pytest workers (pytest-xdist): XLA compiles one program at a time, so a single process leaves
# a core idle through much of a cold run; tests sharing an expensive fixture or a task's expert
# rollout go to one worker (tests/conftest.py, xdist_group_of). TEST_WORKERS=0: one process.
TEST_WORKERS ?= 2
test: setup
	$(PY) -m pytest -q -n $(TEST_WORKERS)

test-slow: setup
	$(PY) -m pytest -q -m slow

bench: setup
	$(PY) -m experiments.bench sim --tasks all --batch-sizes 8 32 128

gallery: setup
	$(PY) -m experiments.gallery --out docs/
