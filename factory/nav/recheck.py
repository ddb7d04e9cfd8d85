"""Re-checks a timed base trajectory against the scene in MuJoCo, with the robot's real shape.

The grid plans with a disc; this check poses the whole robot (base box, torso, the arm as the
caller left it in ``qpos``, usually stowed) at every sample of the trajectory and reads the
contacts between robot geoms and everything else. It works on a copy of the model whose
collision bitmasks only let robot geoms meet scene geoms (scene-scene and robot-robot pairs are
never generated), with margins and gaps zeroed, and calls ``mj_kinematics`` + ``mj_collision``
per sample (the collision part of ``mj_forward``).
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass

import mujoco
import numpy as np

log = logging.getLogger(__name__)

BASE_COLLISION = "base_collision"
"""The failure reason of a base trajectory that drives the robot into the scene."""

_ROBOT_TYPE, _ROBOT_AFF = 1, 2
_SCENE_TYPE, _SCENE_AFF = 2, 1


@dataclass(frozen=True)
class RecheckResult:
    """The outcome of a trajectory re-check.

    Attributes:
        ok: whether no penetration exceeds the tolerance.
        reason: ``""`` or ``base_collision``.
        max_penetration: deepest penetration of a robot geom into the scene (m, >= 0).
        worst_sample: index of the sample with that penetration (-1 with no contact).
        contact: (robot body, scene body) names at the worst sample, or ``("", "")``.
        samples: number of samples checked.
    """

    ok: bool
    reason: str
    max_penetration: float
    worst_sample: int
    contact: tuple[str, str]
    samples: int


def recheck_base_trajectory(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    base_q: np.ndarray,
    base_qpos_adr: np.ndarray,
    robot_geoms: np.ndarray,
    tolerance: float = 0.02,
    stride: int = 1,
) -> RecheckResult:
    """Drives the robot's base joints along ``base_q`` and measures its penetration.

    Args:
        model: the compiled scene with the mobile robot.
        qpos: the state (nq,) to check in: the scene's objects and the arm (stowed).
        base_q: base joint values (n, 3): x, y (m), yaw (rad), e.g. ``BaseTrajectory.q``.
        base_qpos_adr: qpos addresses (3,) of the base joints x, y, yaw.
        robot_geoms: ids of the robot's colliding geoms.
        tolerance: penetration allowed (m); deeper fails with ``base_collision``.
        stride: check every ``stride``-th sample (the last one always).

    Returns:
        the deepest penetration and where.
    """
    m = copy.copy(model)
    collides = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
    robot = np.zeros(m.ngeom, bool)
    robot[np.asarray(robot_geoms, int)] = True
    m.geom_contype[collides] = _SCENE_TYPE
    m.geom_conaffinity[collides] = _SCENE_AFF
    m.geom_contype[robot & collides] = _ROBOT_TYPE
    m.geom_conaffinity[robot & collides] = _ROBOT_AFF
    m.geom_margin[:] = 0.0
    m.geom_gap[:] = 0.0
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    d = mujoco.MjData(m)
    base_q = np.atleast_2d(np.asarray(base_q, float))
    adr = np.asarray(base_qpos_adr, int)
    idx = list(range(0, len(base_q), max(1, stride)))
    if idx[-1] != len(base_q) - 1:
        idx.append(len(base_q) - 1)
    worst, worst_k, pair = 0.0, -1, ("", "")
    for k in idx:
        d.qpos[:] = qpos
        d.qpos[adr] = base_q[k]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        for c in d.contact[: d.ncon]:
            depth = -float(c.dist)
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            if robot[g1] == robot[g2] or depth <= worst:
                continue
            rg, sg = (g1, g2) if robot[g1] else (g2, g1)
            worst, worst_k = depth, k
            pair = (m.body(int(m.geom_bodyid[rg])).name, m.body(int(m.geom_bodyid[sg])).name)
    ok = worst <= tolerance
    if not ok:
        log.debug("base trajectory collides at sample %d: %s %.3f m", worst_k, pair, worst)
    return RecheckResult(
        ok=ok,
        reason="" if ok else BASE_COLLISION,
        max_penetration=worst,
        worst_sample=worst_k,
        contact=pair,
        samples=len(idx),
    )
