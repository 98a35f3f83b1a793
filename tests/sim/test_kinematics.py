"""Panda forward kinematics and Jacobian against two oracles: pytorch-kinematics and C MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from readjax import tasks
from readjax.sim import kinematics as kin
from readjax.sim.scene import mjcf_dir


@pytest.fixture(scope="module")
def env():
    return tasks.make("reach_target")


def _random_q(chain, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(chain.lower, chain.upper, size=(n, 7)).astype(np.float32)


def test_fk_matches_pytorch_kinematics(env):
    torch = pytest.importorskip("torch")
    pk = pytest.importorskip("pytorch_kinematics")
    import pytorch_kinematics.mjcf as pkm

    # pytorch-kinematics 0.10 keys JOINT_TYPE_MAP by enums that no longer hash like ints (mujoco>=3.12)
    pkm.JOINT_TYPE_MAP = {int(k): v for k, v in pkm.JOINT_TYPE_MAP.items()}
    xml = (mjcf_dir() / "robot" / "panda.xml").read_text()
    chain = pk.build_serial_chain_from_mjcf(xml, "hand").to(dtype=torch.float64)
    q = _random_q(env.chain, 128)
    tf = chain.forward_kinematics(torch.as_tensor(q, dtype=torch.float64)).get_matrix().numpy()
    # readjax's end effector is the tcp site: hand frame + 0.1034 m along its z
    tcp_pos = tf[:, :3, 3] + tf[:, :3, 2] * 0.1034
    pos, rot = kin.fk(env.chain, q)
    assert np.abs(np.asarray(pos) - tcp_pos).max() < 1e-4
    ang = np.arccos(np.clip((np.trace(np.asarray(rot).transpose(0, 2, 1) @ tf[:, :3, :3], axis1=1, axis2=2) - 1) / 2,
                            -1, 1))
    assert ang.max() < 1e-3


def test_fk_and_jacobian_match_mujoco(env):
    m = env.mj_model
    d = mujoco.MjData(m)
    site = m.site("tcp").id
    for q in _random_q(env.chain, 20, seed=1):
        d.qpos[env.chain.qpos_adr] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jp, jr, site)
        pos, rot, jac = kin.fk_jacobian(env.chain, q)
        np.testing.assert_allclose(np.asarray(pos), d.site_xpos[site], atol=1e-5)
        np.testing.assert_allclose(np.asarray(rot), d.site_xmat[site].reshape(3, 3), atol=1e-5)
        np.testing.assert_allclose(np.asarray(jac[:3]), jp[:, env.chain.qvel_adr], atol=1e-5)
        np.testing.assert_allclose(np.asarray(jac[3:]), jr[:, env.chain.qvel_adr], atol=1e-5)


def test_home_pose_points_down(env):
    pos, rot = kin.fk(env.chain, kin.HOME_Q)
    assert np.asarray(rot)[2, 2] < -0.999  # tcp z axis points at the table
    assert 0.25 < float(pos[0]) < 0.35 and float(pos[2]) > 0.4


def test_chain_limits_are_the_models(env):
    np.testing.assert_allclose(env.chain.lower[3], -3.0718, atol=1e-4)
    assert np.all(env.chain.lower < env.chain.upper)
