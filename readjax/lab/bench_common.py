"""What the benchmarks (``experiments.bench``) share: a call timed again and again, and a synthetic
training split (random images, straight-line reaches) for a planner's retrieval database or a train
step's batches: latency and step time do not depend on the values.
"""

from __future__ import annotations

import time


def time_calls(fn, repeats: int) -> list[float]:
    """Seconds of each of ``repeats`` calls of ``fn`` (nothing blocked on, nothing warmed up)."""
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def synthetic_motions(camera, n: int, rng):
    """n reachable straight-line reaches (B, 101, 10) in the camera's motion format."""
    import numpy as np

    from readjax import motion as motion_lib

    t = np.linspace(0, 1, motion_lib.FRAMES)[None, :, None]
    pos = rng.uniform([0.3, -0.3, 0.1], [0.7, 0.3, 0.5], (n, 1, 3)) * t + (1 - t) * np.array([0.31, 0, 0.49])
    rot = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (n, motion_lib.FRAMES, 3, 3))
    return np.asarray(motion_lib.encode(camera, pos.astype(np.float32), rot.astype(np.float32),
                                        np.ones((n, motion_lib.FRAMES), np.float32)))


def synthetic_dataset(camera, n: int, size: int, seed: int = 0):
    """A training split of n synthetic demos (random images, straight-line motions) at ``size`` px."""
    import numpy as np

    from readjax import motion as motion_lib
    from readjax.data.store import Dataset

    rng = np.random.default_rng(seed)
    return Dataset("reach_target", "train", camera, rng.uniform(size=(n, size, size, 4)).astype(np.float32),
                   synthetic_motions(camera, n, rng), np.zeros((n, motion_lib.FRAMES, motion_lib.JOINTS), np.float32),
                   np.arange(n))
