"""Timed base trajectories through poses: limits, straight SE(2) pieces, end at the goal."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

pytest.importorskip("ruckig")

from factory.nav import BaseLimits, NavError, time_base_path

POSES = np.array(
    [
        [0.0, 0.0, 0.3],
        [2.0, 0.0, 0.3],  # straight ahead
        [2.0, 1.5, 1.8],  # sideways while turning
        [0.5, 2.5, 1.8],
        [0.5, 2.5, 2.0 + 2 * math.pi],  # a turn in place past pi (unwrapped yaw is kept)
    ]
)
LIMITS = BaseLimits()


@pytest.mark.parametrize("dt", [0.01, 0.05])
def test_limits_and_goal(dt: float) -> None:
    traj = time_base_path(POSES, LIMITS, dt=dt)
    n = len(traj.t)
    assert traj.q.shape == traj.qd.shape == traj.qdd.shape == (n, 3)
    assert np.allclose(np.diff(traj.t), dt)
    tol = 1.01
    speed = np.linalg.norm(traj.qd[:, :2], axis=1)
    accel = np.linalg.norm(traj.qdd[:, :2], axis=1)
    assert speed.max() <= LIMITS.v_max * tol
    assert accel.max() <= LIMITS.a_max * tol
    assert np.abs(traj.qd[:, 2]).max() <= LIMITS.yaw_v_max * tol
    assert np.abs(traj.qdd[:, 2]).max() <= LIMITS.yaw_a_max * tol
    # the samples agree with the velocities (finite differences, within a step of acceleration)
    fd = np.diff(traj.q, axis=0) / dt
    assert np.linalg.norm(fd[:, :2], axis=1).max() <= LIMITS.v_max * tol + LIMITS.a_max * dt
    assert np.abs(fd[:, 2]).max() <= LIMITS.yaw_v_max * tol + LIMITS.yaw_a_max * dt
    # starts and ends at rest, at the start and exactly at the goal (yaw as given)
    assert np.allclose(traj.q[0], POSES[0]) and np.array_equal(traj.q[-1], POSES[-1])
    assert np.allclose(traj.qd[[0, -1]], 0) and np.allclose(traj.qdd[[0, -1]], 0)
    # the base reaches its full speed on the long first piece
    assert speed.max() >= 0.95 * LIMITS.v_max
    # each piece is straight in SE(2): every sample lies on a segment between poses, its yaw
    # the same share of the way as its position (phase synchronization)
    d = np.min([_seg_dist(traj.q, a, b) for a, b in itertools.pairwise(POSES)], axis=0)
    assert d.max() < 1e-6


def _seg_dist(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of poses (n, 3) from the straight SE(2) motion a -> b (yaw in m at 1 m/rad)."""
    ab = b - a
    s = np.clip(((q - a) @ ab) / (ab @ ab), 0, 1)
    return np.linalg.norm(a + np.outer(s, ab) - q, axis=1)


def test_slower_limits_take_longer() -> None:
    fast = time_base_path(POSES, LIMITS)
    slow = time_base_path(POSES, BaseLimits(v_max=0.25, a_max=0.25))
    assert slow.duration > fast.duration
    # a 2 m straight at 0.5 m/s and 0.5 m/s^2 takes at least 2 / 0.5 + 0.5 / 0.5 = 5 s
    straight = time_base_path(np.array([[0, 0, 0], [2, 0, 0]], float), LIMITS, 0.01)
    assert 5.0 <= straight.duration <= 5.0 + 0.5


def test_single_pose_repeats_and_errors() -> None:
    still = time_base_path(np.array([[1.0, 2.0, 0.5]]))
    assert len(still.t) == 1 and np.allclose(still.q, [[1.0, 2.0, 0.5]])
    twice = time_base_path(np.array([[1.0, 2.0, 0.5], [1.0, 2.0, 0.5], [1.0, 2.0, 1.0]]))
    assert twice.q[-1, 2] == pytest.approx(1.0)
    with pytest.raises(NavError):
        BaseLimits(v_max=0.0)
    with pytest.raises(NavError):
        time_base_path(np.zeros((2, 2)), LIMITS)
    with pytest.raises(NavError):
        time_base_path(np.zeros((2, 3)), LIMITS, dt=0.0)
