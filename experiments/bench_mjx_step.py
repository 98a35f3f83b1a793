"""Version-independent MJX micro-benchmark (run by experiments.bench_versions in other venvs).

Steps the pick_up_cup scene (Panda + two cups, boxes colliding) batched: jit(vmap(scan of 20
mjx.step)) at a batch size; prints one JSON line with compile time and physics steps/s. Uses only
the public MJX API so that older mujoco-mjx/jax releases can run it; the XLA flag and the pure-jnp
Cholesky are set up as readjax does.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _set_xla_flags() -> None:
    """readjax's XLA flag, where this jaxlib knows it (loaded without importing the package, which
    would import jax first)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_readjax_runtime", ROOT / "readjax" / "_runtime.py")
    runtime = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(runtime)
    runtime.configure_xla_flags()


_set_xla_flags()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402

sys.path.insert(0, str(ROOT))
from readjax import linalg  # noqa: E402

linalg.install_cpu_cholesky()
from mujoco import mjx  # noqa: E402


def main(batch: int = 32, steps: int = 20, repeats: int = 5) -> None:
    m = mujoco.MjModel.from_xml_path(str(ROOT / "tasks_mjcf" / "pick_up_cup.xml"))
    d = mujoco.MjData(m)
    d.qpos[:7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    mujoco.mj_forward(m, d)
    mx = mjx.put_model(m)
    dx = mjx.put_data(m, d)
    ctrl = jnp.asarray(d.qpos[:7].tolist() + [0.04, 0.04])

    def run(d0, noise):
        d0 = d0.replace(ctrl=ctrl + noise)
        return jax.lax.scan(lambda dd, _: (mjx.step(mx, dd), None), d0, None, length=steps)[0].qpos

    batched = jax.jit(jax.vmap(run, in_axes=(None, 0)))
    noise = jax.random.normal(jax.random.key(0), (batch, 9)) * 0.05
    t = time.perf_counter()
    batched(dx, noise).block_until_ready()
    first = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        batched(dx, noise).block_until_ready()
        times.append(time.perf_counter() - t)
    best = sorted(times)[len(times) // 2]
    print(json.dumps({"jax": jax.__version__, "mujoco": mujoco.__version__, "batch": batch,
                      "compile_s": round(first - best, 2), "steps_per_s": round(batch * steps / best)}))


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
