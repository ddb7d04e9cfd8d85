"""Timed base trajectories (x, y, yaw) through base poses, with ruckig.

A pose path (k, 3) (x, y and unwrapped yaw; from :func:`factory.nav.se2.plan_se2_path`) is
driven piece by piece, each piece a straight motion in SE(2) from one pose to the next: the
base moves along the segment and turns at once (it is holonomic). Yaw is unwrapped: each piece
takes the yaw difference as given, and the values stay continuous, as the base's hinge joint
and position actuator expect.

Timing: each piece is timed rest to rest with ruckig on two coordinates, the distance along the
segment and the yaw, with phase synchronization, so the base stays on the checked straight
motion. The planar speed is limited along the segment, hence ``|v| <= v_max`` in any
direction.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from factory.nav.errors import NavError


@dataclass(frozen=True)
class BaseLimits:
    """Speed limits of a mobile base, used to time its trajectories.

    The Omron LD-60 (robosuite's ``OmronMobileBase``) reaches 1.35 m/s (1.8 m/s for its LD-90
    sibling) per Omron's datasheet; the defaults here are deliberately conservative for driving
    with an arm among furniture: 0.5 m/s, 0.5 m/s^2, 1.0 rad/s, 1.0 rad/s^2. The jerk limits
    are our own smoothness choice (the datasheet gives none).

    Attributes:
        v_max: planar speed (m/s).
        a_max: planar acceleration (m/s^2).
        j_max: planar jerk (m/s^3).
        yaw_v_max: yaw rate (rad/s).
        yaw_a_max: yaw acceleration (rad/s^2).
        yaw_j_max: yaw jerk (rad/s^3).
    """

    v_max: float = 0.5
    a_max: float = 0.5
    j_max: float = 2.0
    yaw_v_max: float = 1.0
    yaw_a_max: float = 1.0
    yaw_j_max: float = 4.0

    def __post_init__(self) -> None:
        for name in ("v_max", "a_max", "j_max", "yaw_v_max", "yaw_a_max", "yaw_j_max"):
            if not getattr(self, name) > 0:
                raise NavError(f"BaseLimits.{name} must be positive, got {getattr(self, name)}")


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class BaseTrajectory:
    """A timed base trajectory sampled at a fixed rate.

    Attributes:
        dt: sample period (s).
        t: sample times (n,) (s), from 0.
        q: base poses (n, 3): x, y (m, world) and unwrapped yaw (rad about +z).
        qd: velocities (n, 3) (m/s, m/s, rad/s).
        qdd: accelerations (n, 3) (m/s^2, m/s^2, rad/s^2).
        waypoints: the poses (m, 3) the trajectory rests at, in order.
    """

    dt: float
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    waypoints: np.ndarray

    @property
    def duration(self) -> float:
        """Length in time (s)."""
        return float(self.t[-1])


def _time_piece(
    a: np.ndarray, b: np.ndarray, limits: BaseLimits, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest-to-rest motion from pose ``a`` to ``b`` (3,): samples at ``dt`` with both ends."""
    from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

    d = b[:2] - a[:2]
    length = math.hypot(d[0], d[1])
    u = d / length if length > 0 else np.zeros(2)
    otg = Ruckig(2)
    inp = InputParameter(2)
    inp.current_position = [0.0, float(a[2])]
    inp.target_position = [length, float(b[2])]
    inp.current_velocity = inp.current_acceleration = [0.0, 0.0]
    inp.target_velocity = inp.target_acceleration = [0.0, 0.0]
    inp.max_velocity = [limits.v_max, limits.yaw_v_max]
    inp.max_acceleration = [limits.a_max, limits.yaw_a_max]
    inp.max_jerk = [limits.j_max, limits.yaw_j_max]
    inp.synchronization = Synchronization.Phase
    traj = Trajectory(2)
    result = otg.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise NavError(f"ruckig could not time the base motion {a} -> {b}: {result}")
    duration = float(traj.duration)
    n = max(1, math.ceil(duration / dt - 1e-9))
    q = np.empty((n + 1, 3))
    qd = np.empty((n + 1, 3))
    qdd = np.empty((n + 1, 3))
    for k in range(n + 1):
        (s, yaw), (sd, yd), (sdd, ydd) = traj.at_time(min(k * dt, duration))
        q[k] = (a[0] + u[0] * s, a[1] + u[1] * s, yaw)
        qd[k] = (u[0] * sd, u[1] * sd, yd)
        qdd[k] = (u[0] * sdd, u[1] * sdd, ydd)
    q[-1], qd[-1], qdd[-1] = b, 0.0, 0.0
    return q, qd, qdd


def time_base_path(
    waypoints: np.ndarray, limits: BaseLimits | None = None, dt: float = 0.02
) -> BaseTrajectory:
    """Times rest poses (m, 3) one piece after the other (see the module docstring).

    Args:
        waypoints: base poses (x, y, unwrapped yaw), e.g. a path of
            :func:`factory.nav.se2.plan_se2_path`.
        limits: speed limits; default :class:`BaseLimits`.
        dt: sample period (s).

    Returns:
        samples at ``dt``; the last is exactly the last waypoint, at rest.
    """
    limits = limits or BaseLimits()
    wps = np.asarray(waypoints, float)
    if wps.ndim != 2 or len(wps) < 1 or wps.shape[1] != 3:
        raise NavError(f"base waypoints must be (m >= 1, 3), got shape {wps.shape}")
    if not dt > 0:
        raise NavError(f"dt must be positive, got {dt}")
    qs, qds, qdds = [wps[:1]], [np.zeros((1, 3))], [np.zeros((1, 3))]
    for a, b in itertools.pairwise(wps):
        if np.abs(b - a).max() < 1e-9:
            continue
        q, qd, qdd = _time_piece(a, b, limits, dt)
        qs.append(q[1:])
        qds.append(qd[1:])
        qdds.append(qdd[1:])
    q = np.concatenate(qs)
    return BaseTrajectory(
        dt=dt,
        t=np.arange(len(q)) * dt,
        q=q,
        qd=np.concatenate(qds),
        qdd=np.concatenate(qdds),
        waypoints=wps,
    )
