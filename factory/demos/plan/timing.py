"""Jerk-limited time parameterization of joint paths with ruckig.

Community ruckig has no offline intermediate waypoints, so each segment of a piecewise-linear
path is timed on its own, rest to rest, with phase synchronization: every joint's profile has
the same shape, so the motion stays on the straight (collision-checked) segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from factory.robots.panda import PANDA


@dataclass(frozen=True)
class Limits:
    """Per-joint limits used for timing: velocity (rad/s), acceleration, jerk; shape (7,)."""

    v: np.ndarray
    a: np.ndarray
    j: np.ndarray

    @classmethod
    def panda(cls, speed: float = 1.0, accel: float = 1.0, jerk: float = 1.0) -> Limits:
        """The Panda's datasheet limits scaled by the given fractions (each in (0, 1])."""
        for name, f in (("speed", speed), ("accel", accel), ("jerk", jerk)):
            if not 0 < f <= 1:
                raise ValueError(f"{name} scale must be in (0, 1], got {f}")
        return cls(
            np.array(PANDA.v_max) * speed,
            np.array(PANDA.a_max) * accel,
            np.array(PANDA.j_max) * jerk,
        )


@dataclass
class TimedPath:
    """A timed joint trajectory sampled at a fixed rate.

    Attributes:
        dt: sample period (s).
        q, qd, qdd: positions, velocities, accelerations (n, 7).
        segment_times: duration of each segment (s).
    """

    dt: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    segment_times: list[float]

    @property
    def duration(self) -> float:
        return (len(self.q) - 1) * self.dt


def time_segment(q0: np.ndarray, q1: np.ndarray, limits: Limits, dt: float) -> TimedPath:
    """Rest-to-rest, phase-synchronized, jerk-limited motion from ``q0`` to ``q1`` (7,).

    Returns:
        samples at ``dt`` including both ends (the last sample is exactly ``q1``).
    """
    from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

    dof = len(q0)
    otg = Ruckig(dof)
    inp = InputParameter(dof)
    inp.current_position = list(map(float, q0))
    inp.target_position = list(map(float, q1))
    inp.current_velocity = inp.current_acceleration = [0.0] * dof
    inp.target_velocity = inp.target_acceleration = [0.0] * dof
    inp.max_velocity = list(map(float, limits.v))
    inp.max_acceleration = list(map(float, limits.a))
    inp.max_jerk = list(map(float, limits.j))
    inp.synchronization = Synchronization.Phase
    traj = Trajectory(dof)
    result = otg.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise ValueError(f"ruckig could not time the segment: {result}")
    duration = float(traj.duration)
    n = max(1, int(np.ceil(duration / dt)))
    q = np.empty((n + 1, dof))
    qd = np.empty((n + 1, dof))
    qdd = np.empty((n + 1, dof))
    for k in range(n + 1):
        p, v, a = traj.at_time(min(k * dt, duration))
        q[k], qd[k], qdd[k] = p, v, a
    q[-1], qd[-1], qdd[-1] = q1, 0.0, 0.0
    return TimedPath(dt, q, qd, qdd, [duration])


def time_path(path: np.ndarray, limits: Limits, dt: float) -> TimedPath:
    """Times a piecewise-linear joint path (k, 7), segment by segment (rest at waypoints)."""
    path = np.asarray(path, float)
    if len(path) < 2:
        z = np.zeros_like(path[:1])
        return TimedPath(dt, path[:1].copy(), z, z.copy(), [])
    parts = [time_segment(path[i], path[i + 1], limits, dt) for i in range(len(path) - 1)]
    q = np.concatenate([parts[0].q] + [p.q[1:] for p in parts[1:]])
    qd = np.concatenate([parts[0].qd] + [p.qd[1:] for p in parts[1:]])
    qdd = np.concatenate([parts[0].qdd] + [p.qdd[1:] for p in parts[1:]])
    return TimedPath(dt, q, qd, qdd, [t for p in parts for t in p.segment_times])
