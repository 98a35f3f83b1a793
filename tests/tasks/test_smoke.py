"""One smoke test over every registered task: reset, render, expert rollout shapes, finiteness."""

from __future__ import annotations

import numpy as np
import pytest

from readjax import tasks
from readjax.sim.render import SceneRenderer
from tests.tasks.helpers import EXPERT_SEEDS, expert_run

pytestmark = pytest.mark.timeout(600)


@pytest.mark.parametrize("task", tasks.names())
def test_task_smoke(task):
    env = tasks.make(task)
    assert env.code in tasks.AVG16 and tasks.canonical_name(env.code) == task
    scenes, ok, q0, trace = expert_run(task)
    t = env.episode_steps
    assert trace.tcp_pos.shape == (EXPERT_SEEDS, t, 3)
    assert trace.q.shape == (EXPERT_SEEDS, t, 7)
    assert ok.shape == (EXPERT_SEEDS,)
    for leaf in (trace.tcp_pos, trace.q, trace.grip, scenes.qpos):
        assert np.all(np.isfinite(leaf))
    # different seeds give different scenes
    assert not np.allclose(scenes.qpos[0], scenes.qpos[1]) or not np.allclose(scenes.mocap_pos[0],
                                                                                scenes.mocap_pos[1])
    # the first frame shows something besides the table: the image is not flat
    with SceneRenderer(env.mj_model, 64, 64) as r:
        r.set_state(scenes.qpos[0], scenes.mocap_pos[0], scenes.mocap_quat[0], env.recolour_ids, scenes.rgba[0])
        rgb, depth = r.render()
    assert rgb.shape == (64, 64, 3) and rgb.std() > 10
    assert np.all(np.isfinite(depth)) and depth.min() > 0.3
