"""The batched tool tracker against mink's (``factory.robots.ik_batch``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from factory.robots.ik import IKConfig, IKSolver
from factory.robots.ik_batch import BatchTracker, rotation_error
from factory.robots.panda import HOME_QPOS

pytest.importorskip("mink")

CFG = IKConfig(max_iters=20, pos_tol=5e-4, rot_tol_deg=0.5)  # the policy's tracker


def _path(n: int, frames: int, seed: int = 1) -> tuple[np.ndarray, list, list]:
    """Start joints (n, 7) near home and, per frame, tool targets drifting 4 mm and 0.5 deg a
    frame with 1 mm of noise (a policy's predicted tool path)."""
    rng = np.random.default_rng(seed)
    q0 = np.asarray(HOME_QPOS, float) + rng.normal(0, 0.2, (n, 7))
    pos0, rot0, _ = BatchTracker(CFG).kinematics(q0)
    dirs = rng.normal(0, 1, (n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    axes = rng.normal(0, 1, (n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    pos = [pos0 + dirs * 0.004 * (f + 1) + rng.normal(0, 0.001, (n, 3)) for f in range(frames)]
    rot = [
        Rotation.from_rotvec(axes * np.radians(0.5) * (f + 1)).as_matrix() @ rot0
        for f in range(frames)
    ]
    return q0, pos, rot


def test_batch_tracker_follows_mink_on_a_tool_path() -> None:
    """Frame by frame from the previous command, both trackers reach every target within the
    tolerances and stay within 1e-3 rad of each other."""
    n = 8
    q0, pos, rot = _path(n, 40)
    mink_ik, batch = IKSolver(CFG), BatchTracker(CFG)
    qm, qb = q0.copy(), q0.copy()
    for p, r in zip(pos, rot, strict=True):
        for i in range(n):
            target = np.eye(4)
            target[:3, :3], target[:3, 3] = r[i], p[i]
            qm[i] = mink_ik.track(target, qm[i])
        qb = batch.track(p, r, qb)
        got_p, got_r, _ = batch.kinematics(qb)
        assert np.linalg.norm(got_p - p, axis=1).max() < CFG.pos_tol
        assert np.degrees(np.linalg.norm(rotation_error(r, got_r), axis=1)).max() < CFG.rot_tol_deg
        assert np.abs(qm - qb).max() < 1e-3


def test_batch_tracker_keeps_joint_limits_out_of_reach() -> None:
    """Targets a metre out of reach: the closest configuration found, inside the joint limits,
    and arms already at their target do not move."""
    batch = BatchTracker(CFG)
    q0 = np.tile(np.asarray(HOME_QPOS, float), (3, 1))
    pos, rot, _ = batch.kinematics(q0)
    far = pos.copy()
    far[:2] += np.array([1.0, 0.0, 0.0])
    q = batch.track(far, rot, q0)
    assert ((q >= batch.lo - 1e-9) & (q <= batch.hi + 1e-9)).all()
    got, _, _ = batch.kinematics(q)
    assert (
        np.linalg.norm(got[:2] - far[:2], axis=1) < np.linalg.norm(pos[:2] - far[:2], axis=1)
    ).all()
    np.testing.assert_allclose(q[2], np.clip(q0[2], batch._start_lo, batch._start_hi), atol=1e-12)


def test_rotation_error_is_the_rotation_vector() -> None:
    rng = np.random.default_rng(0)
    a = Rotation.random(6, random_state=1).as_matrix()
    vec = rng.normal(0, 0.8, (6, 3))
    vec[0] = [np.pi - 1e-5, 0, 0]  # near pi
    b = Rotation.from_rotvec(vec).as_matrix() @ a
    got = rotation_error(b, a)
    np.testing.assert_allclose(got[1:], vec[1:], atol=1e-8)
    assert abs(np.linalg.norm(got[0]) - (np.pi - 1e-5)) < 1e-4
