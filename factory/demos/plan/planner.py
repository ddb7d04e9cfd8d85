"""Joint-space motion planning: OMPL RRTConnect with MuJoCo collision checking.

The checker works on a copy of the composed model whose collision bitmasks only let the robot
(and an attached object) collide: scene objects never collide with one another there, so each
check costs one ``mj_kinematics`` plus a narrow phase over the robot's neighbourhood. A state is
valid when nothing touching the robot or the attached object penetrates (the grasped object may
touch the fingers).
"""

from __future__ import annotations

import copy
import logging
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from factory.nav.rrt import seed_ompl
from factory.robots.panda import PANDA, RobotIndex

log = logging.getLogger(__name__)

_SCENE_TYPE, _SCENE_AFF = 2, 1
_ROBOT_TYPE, _ROBOT_AFF = 3, 3


@dataclass(frozen=True)
class PlannerConfig:
    """Planning parameters.

    Attributes:
        timeout: seconds per RRTConnect query.
        range: RRTConnect's extension step (rad); 0 lets OMPL choose.
        resolution: state-validity resolution along edges, as a share of the space's extent.
        simplify: seconds of path simplification.
        check_step: joint step of the final fine re-check of every path (rad).
        tolerance: penetration tolerated by the checker (m).
        attempts: planning queries before giving up.
    """

    timeout: float = 5.0
    range: float = 0.0
    resolution: float = 0.002
    simplify: float = 0.5
    check_step: float = 0.01
    tolerance: float = 0.0
    attempts: int = 2


@dataclass
class Attachment:
    """An object carried by the tool: its body, free-joint address and pose in the tool frame."""

    body: int
    qpos_adr: int
    pose_obj_in_tool: np.ndarray  # (4, 4)
    geoms: np.ndarray = field(default_factory=lambda: np.zeros(0, int))


class CollisionChecker:
    """Collision checks of robot configurations against a scene state.

    Args:
        model: the composed scene + robot model.
        robot: its robot index.
        qpos: the scene state (nq,) whose objects are the obstacles.
        tolerance: penetration tolerated (m).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        robot: RobotIndex,
        qpos: np.ndarray,
        tolerance: float = 0.0,
    ) -> None:
        self.model = copy.copy(model)
        m = self.model
        collides = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        m.geom_contype[collides] = _SCENE_TYPE
        m.geom_conaffinity[collides] = _SCENE_AFF
        m.geom_contype[robot.geoms] = _ROBOT_TYPE
        m.geom_conaffinity[robot.geoms] = _ROBOT_AFF
        m.geom_margin[:] = 0.0
        m.geom_gap[:] = 0.0
        # Island sleeping keeps static bodies' poses from the last full update, so a robot base
        # moved in the model (``move_robot``) would be checked where it was: the checker only
        # poses and collides, and gains nothing from sleeping.
        m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        self.robot = robot
        self.data = mujoco.MjData(m)
        self.base = np.array(qpos, dtype=float)
        self.tolerance = tolerance
        self.attached: Attachment | None = None
        self._finger = np.zeros(m.ngeom, bool)
        self._finger[robot.finger_geoms] = True
        self._robot = np.zeros(m.ngeom, bool)
        self._robot[robot.geoms] = True
        self._ignore = np.zeros(m.ngeom, bool)
        self._q_min, self._q_max = np.array(PANDA.q_min), np.array(PANDA.q_max)
        self.checks = 0

    def set_scene(self, qpos: np.ndarray) -> None:
        """Replaces the scene state (nq,)."""
        self.base = np.array(qpos, dtype=float)

    def attach(self, attachment: Attachment | None) -> None:
        """Carries an object with the tool (None: release)."""
        m = self.model
        if self.attached is not None:
            g = self.attached.geoms
            m.geom_contype[g] = _SCENE_TYPE
            m.geom_conaffinity[g] = _SCENE_AFF
        self.attached = attachment
        if attachment is not None:
            g = np.flatnonzero(
                (m.geom_bodyid == attachment.body)
                & ((m.geom_contype != 0) | (m.geom_conaffinity != 0))
            )
            attachment.geoms = g
            m.geom_contype[g] = _ROBOT_TYPE
            m.geom_conaffinity[g] = _ROBOT_AFF

    def ignore_bodies(self, bodies: np.ndarray | list[int]) -> None:
        """Contacts with these bodies' geoms are allowed (e.g. the object being grasped)."""
        self._ignore[:] = np.isin(self.model.geom_bodyid, np.asarray(bodies, int))

    def _pose(self, q: np.ndarray) -> None:
        d, m = self.data, self.model
        d.qpos[:] = self.base
        d.qpos[self.robot.qpos] = q
        mujoco.mj_kinematics(m, d)
        att = self.attached
        if att is not None:
            tool = np.eye(4)
            tool[:3, :3] = d.site_xmat[self.robot.site].reshape(3, 3)
            tool[:3, 3] = d.site_xpos[self.robot.site]
            pose = tool @ att.pose_obj_in_tool
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, pose[:3, :3].reshape(-1))
            d.qpos[att.qpos_adr : att.qpos_adr + 3] = pose[:3, 3]
            d.qpos[att.qpos_adr + 3 : att.qpos_adr + 7] = quat
            mujoco.mj_kinematics(m, d)

    def _offending(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Geoms and distances of the offending contacts at arm joints ``q`` (7,): deeper
        than the tolerance, not with an ignored body, not the grasped object between the
        fingers; ``(g1, g2, dist)``, each (k,)."""
        self.checks += 1
        self._pose(q)
        d, m = self.data, self.model
        mujoco.mj_collision(m, d)
        if d.ncon == 0:
            empty = np.zeros(0, int)
            return empty, empty, np.zeros(0)
        con, ncon = d.contact, d.ncon
        dist = np.asarray(con.dist)[:ncon]
        bad = np.flatnonzero(dist < -self.tolerance)
        geom = np.asarray(con.geom)[:ncon][bad]
        g1, g2, dist = geom[:, 0], geom[:, 1], dist[bad]
        keep = ~(self._ignore[g1] | self._ignore[g2])
        if self.attached is not None:
            att = self.attached.body
            body = m.geom_bodyid
            held = ((body[g1] == att) | (body[g2] == att)) & (self._finger[g1] | self._finger[g2])
            keep &= ~held
        return g1[keep], g2[keep], dist[keep]

    def collisions(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """The offending contacts at arm joints ``q`` (7,): (body, body, distance m)."""
        m = self.model
        g1, g2, dist = self._offending(q)
        return [
            (m.body(int(m.geom_bodyid[a])).name, m.body(int(m.geom_bodyid[b])).name, float(x))
            for a, b, x in zip(g1, g2, dist, strict=True)
        ]

    def valid(self, q: np.ndarray) -> bool:
        """Whether arm joints ``q`` (7,) are within limits and collision-free."""
        q = np.asarray(q)
        if (q < self._q_min).any() or (q > self._q_max).any():
            return False
        return len(self._offending(q)[0]) == 0

    def segment_valid(self, q0: np.ndarray, q1: np.ndarray, step: float = 0.01) -> bool:
        """Whether the straight joint-space segment is valid at joint steps <= ``step`` rad."""
        n = max(1, int(np.ceil(np.abs(np.asarray(q1) - q0).max() / step)))
        return all(self.valid(q0 + (q1 - q0) * (k / n)) for k in range(n + 1))

    def path_valid(self, path: np.ndarray, step: float = 0.01) -> bool:
        """Whether a piecewise-linear joint path (k, 7) is valid at joint steps <= ``step``."""
        return all(self.segment_valid(path[i], path[i + 1], step) for i in range(len(path) - 1))


@dataclass
class PlanResult:
    """A planned path: waypoints (k, 7) or None, seconds spent and a reason on failure."""

    path: np.ndarray | None
    seconds: float
    reason: str = ""


def plan(
    checker: CollisionChecker,
    q_start: np.ndarray,
    q_goal: np.ndarray,
    cfg: PlannerConfig,
    seed: int = 0,
) -> PlanResult:
    """RRTConnect in the arm's joint space from ``q_start`` to ``q_goal`` (7,) each.

    A direct segment that is valid is returned as is. Paths are simplified by OMPL, then
    re-checked at ``cfg.check_step``; a path that fails the fine check is planned again.
    """
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    t0 = time.perf_counter()
    q_start, q_goal = np.asarray(q_start, float), np.asarray(q_goal, float)
    for name, q in (("start", q_start), ("goal", q_goal)):
        if not checker.valid(q):
            hits = checker.collisions(q)
            return PlanResult(None, time.perf_counter() - t0, f"{name} in collision: {hits[:2]}")
    if checker.segment_valid(q_start, q_goal, cfg.check_step):
        return PlanResult(np.stack([q_start, q_goal]), time.perf_counter() - t0)
    ou.setLogLevel(ou.LOG_WARN)
    seed_ompl(seed)
    space = ob.RealVectorStateSpace(7)
    bounds = ob.RealVectorBounds(7)
    for i in range(7):
        bounds.setLow(i, PANDA.q_min[i])
        bounds.setHigh(i, PANDA.q_max[i])
    space.setBounds(bounds)
    reason = "no path found"
    for _attempt in range(cfg.attempts):
        setup = og.SimpleSetup(space)
        setup.setStateValidityChecker(lambda s: checker.valid(np.array([s[i] for i in range(7)])))
        start, goal = space.allocState(), space.allocState()
        for i in range(7):
            start[i], goal[i] = float(q_start[i]), float(q_goal[i])
        setup.setStartAndGoalStates(start, goal)
        info = setup.getSpaceInformation()
        info.setStateValidityCheckingResolution(cfg.resolution)
        planner = og.RRTConnect(info)
        if cfg.range > 0:
            planner.setRange(cfg.range)
        setup.setPlanner(planner)
        solved = setup.solve(cfg.timeout)
        if not solved or str(solved) != "Exact solution":
            reason = f"RRTConnect found no path in {cfg.timeout:.1f} s"
            continue
        setup.simplifySolution(cfg.simplify)
        sol = setup.getSolutionPath()
        path = np.array(
            [[sol.getState(k)[i] for i in range(7)] for k in range(sol.getStateCount())]
        )
        path[0], path[-1] = q_start, q_goal
        if checker.path_valid(path, cfg.check_step):
            return PlanResult(path, time.perf_counter() - t0)
        reason = "simplified path failed the fine collision re-check"
    return PlanResult(None, time.perf_counter() - t0, reason)
