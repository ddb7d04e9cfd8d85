"""Timed base trajectories: headings along the path, limits, end at the goal."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

pytest.importorskip("ruckig")

from factory.nav import BaseLimits, NavError, base_trajectory, time_base_path, yaw_waypoints

PATH = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5], [0.5, 2.5], [0.55, 2.6]])
LIMITS = BaseLimits()


def test_yaw_faces_the_motion_and_turns_at_corners() -> None:
    wps = yaw_waypoints(PATH, start_yaw=math.pi, goal_yaw=-math.pi / 2)
    # start: turn in place from pi to 0 (the short way: 2 pi - ... stays continuous)
    assert np.allclose(wps[0], [0, 0, math.pi])
    assert np.allclose(wps[1][:2], [0, 0]) and math.cos(wps[1][2]) == pytest.approx(1.0)
    for a, b in itertools.pairwise(wps):
        moved = np.linalg.norm(b[:2] - a[:2])
        if moved > 0.25:  # long segments are driven facing the motion, without turning
            heading = math.atan2(b[1] - a[1], b[0] - a[0])
            assert a[2] == pytest.approx(b[2])
            assert math.cos(a[2] - heading) == pytest.approx(1.0)
        elif moved > 0:  # the short last one sideways, at the heading it had
            assert a[2] == pytest.approx(b[2])
        else:  # a turn in place takes the short way round
            assert abs(b[2] - a[2]) <= math.pi + 1e-9
    assert math.sin(wps[-1][2]) == pytest.approx(-1.0) and math.cos(wps[-1][2]) == pytest.approx(
        0.0, abs=1e-9
    )
    assert np.allclose(wps[-1][:2], PATH[-1])
    assert np.abs(np.diff(wps[:, 2])).max() <= math.pi + 1e-9  # unwrapped, continuous


@pytest.mark.parametrize("dt", [0.01, 0.05])
def test_limits_and_goal(dt: float) -> None:
    traj = base_trajectory(PATH, 0.3, 2.0, LIMITS, dt=dt)
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
    # starts and ends at rest, at the start and at the goal
    assert np.allclose(traj.q[0], [0, 0, 0.3])
    assert np.allclose(traj.q[-1][:2], PATH[-1])
    assert math.cos(traj.q[-1][2] - 2.0) == pytest.approx(1.0)
    assert np.allclose(traj.qd[[0, -1]], 0) and np.allclose(traj.qdd[[0, -1]], 0)
    # the base reaches its full speed on the long first segment
    assert speed.max() >= 0.95 * LIMITS.v_max
    # it stays on the polyline: every sample lies on a path segment
    d = np.min([_seg_dist(traj.q[:, :2], a, b) for a, b in itertools.pairwise(PATH)], axis=0)
    assert d.max() < 1e-9


def _seg_dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    s = np.clip(((p - a) @ ab) / (ab @ ab), 0, 1)
    return np.linalg.norm(a + np.outer(s, ab) - p, axis=1)


def test_slower_limits_take_longer() -> None:
    fast = base_trajectory(PATH, 0.0, 0.0, LIMITS)
    slow = base_trajectory(PATH, 0.0, 0.0, BaseLimits(v_max=0.25, a_max=0.25))
    assert slow.duration > fast.duration
    # a 2 m straight at 0.5 m/s and 0.5 m/s^2 takes at least 2 / 0.5 + 0.5 / 0.5 = 5 s
    straight = time_base_path(np.array([[0, 0, 0], [2, 0, 0]], float), LIMITS, 0.01)
    assert 5.0 <= straight.duration <= 5.0 + 0.5


def test_single_point_and_errors() -> None:
    still = base_trajectory(np.array([[1.0, 2.0]]), 0.5, 0.5)
    assert len(still.t) == 1 and np.allclose(still.q, [[1.0, 2.0, 0.5]])
    turn = base_trajectory(np.array([[1.0, 2.0]]), 0.0, math.pi / 2)
    assert np.allclose(turn.q[:, :2], [1.0, 2.0])
    assert turn.q[-1, 2] == pytest.approx(math.pi / 2)
    with pytest.raises(NavError):
        BaseLimits(v_max=0.0)
    with pytest.raises(NavError):
        yaw_waypoints(np.zeros((2, 3)), 0.0, 0.0)
    with pytest.raises(NavError):
        time_base_path(np.zeros((2, 3)), LIMITS, dt=0.0)
