"""Planning one open or close demonstration: handle grasp, IK along the joint's arc or line,
ruckig timing -> per-physics-step control targets.

Per scene, :func:`setup_scene` chooses the part (:func:`~factory.tasks.articulated.parts.
choose_parts`) and a base spot for the fixed Panda in front of it from which the whole motion
is reachable, and composes the scene with the robot there (the articulated object is static,
its links move on their joints; light floor objects in the part's way are taken out). Per
episode, :meth:`ArticulatedPlanner.plan_episode`:

1. draws the episode's start and goal joint positions: ``open`` starts closed (0) and aims at
   :data:`OPEN_GOAL` of the span; ``close`` starts open (:data:`CLOSE_START` of the span, a
   hinge :data:`HINGE_CLOSE_START`) and aims at 0;
2. grasps the handle from its geometry (:func:`grasps_in_link`, two ways round): the tool's
   approach axis (+z) along the handle's ``-normal``, its closing axis (+x) across the
   handle's thickness (perpendicular to ``along`` and ``normal``), the finger pads centred on
   the grip; the pre-grasp pose backs off along the normal;
3. moves the tool with the handle (:func:`follow`): waypoints every
   :attr:`ArticulatedMotion.step_deg` (hinge) or :attr:`ArticulatedMotion.step_m` (slide) of
   the joint, the tool pose rigidly attached to the link (the link posed by MuJoCo's
   kinematics at the waypoint's joint value), IK by mink seeded by the previous waypoint,
   within the Panda's joint limits, continuous (no joint jumps more than :data:`MAX_JUMP`
   between waypoints) and collision-free against the scene posed at the waypoint (contacts
   with the moving link allowed); the arm's branch at the grasp is the one of a few IK seeds
   (:data:`GRASP_SEEDS`) that follows furthest; an ``open`` motion that stops beyond the
   success threshold ends there;
4. releases and retreats along the handle's normal; RRTConnect (OMPL) plans the free-space
   reach from the start posture (:data:`READY_QPOS`) to the pre-grasp.

Free motions are timed segment by segment with ruckig (as the pick-and-place task); the
constrained motion is one jerk-limited ruckig profile of the path parameter (no stops at the
waypoints, :func:`time_along`), the joints interpolated linearly between waypoints, its limits
chosen so that no joint exceeds its share of the Panda's velocity, acceleration and jerk
limits.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from factory.demos.plan.planner import CollisionChecker, PlannerConfig, plan
from factory.demos.plan.timing import Limits, time_path
from factory.errors import TaskError
from factory.robots.ik import IKSolver
from factory.robots.panda import (
    GRIP_CLOSED,
    GRIP_OPEN,
    CameraRig,
    RobotIndex,
    RobotPlacement,
    pose_matrix,
)
from factory.schema import Scene
from factory.tasks.articulated.parts import Part, choose_parts
from factory.tasks.pick_place.plan import PlanFailure

__all__ = [
    "CLOSED_AT",
    "CLOSE_START",
    "HINGE_CLOSE_START",
    "OPEN_AT",
    "OPEN_GOAL",
    "ArticulatedMotion",
    "ArticulatedPlan",
    "ArticulatedPlanner",
    "ArticulatedSetup",
    "PlanFailure",
    "setup_scene",
]

log = logging.getLogger(__name__)

OPEN_AT = 0.90
"""``open`` succeeds when the joint ends at this share of its span
(:attr:`ArticulatedSetup.span`: a slide's range, a hinge's up to :data:`HINGE_SPAN`) or
more."""
CLOSED_AT = 0.05
"""``close`` succeeds when the joint ends at this share of its full range or less."""
HINGE_SPAN = math.radians(90.0)
"""The span of a hinged part (rad): its range, but at most 90 deg. Holding the handle of a
door or flap rigidly, the Panda follows it to about 80-95 deg before its joint limits end the
arc (measured on the generated kitchens' fridge and cabinet doors, whose range is 110 deg), so
``open`` counts a hinged part open from 0.9 x 90 deg = 81 deg."""
OPEN_GOAL = (0.93, 0.98)
"""Share of the span ``open`` pulls the part to (drawn per episode)."""
CLOSE_START = (0.6, 1.0)
"""Share of the span a ``close`` episode of a slide starts at (drawn per episode)."""
HINGE_CLOSE_START = (0.6, 0.8)
"""Share of the span (54-72 deg) a ``close`` episode of a hinge starts at: the handle of a door
standing open 90 deg faces sideways, and the arm reaches it from almost no free spot in the
generated kitchens (measured on their fridge doors: 1 of 11 spots at 90 deg, 36 grasps that
plan at 54 deg)."""
MAX_JUMP = 0.5
"""Largest joint change (rad) between two waypoints of the constrained motion."""
MAX_CLEARED = 3
"""Light movable objects (chairs, stools) :func:`setup_scene` takes out of a part's way, at
most, before it gives up on the part."""
MAX_PARTS = 6
"""Parts :func:`setup_scene` tries before it gives up on a scene."""
READY_QPOS = np.array([0.0, -1.2, 0.0, -2.9, 0.0, 1.75, 0.785])
"""The arm's start (and the reach's start) of every episode (rad): the Panda's home posture
tucked in (the tool 0.23 m ahead of the base and 0.36 m above it, pointing down) so that a
part standing open in front of the robot does not touch the hand."""
GRASP_SEEDS = (
    np.array([0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785]),
    np.array([0.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785]),
    np.array([0.0, 0.0, 0.0, -2.0, 1.5, 1.5, 0.0]),
    np.array([0.0, 0.0, 0.0, -2.0, -1.5, 1.5, 0.0]),
)
"""IK seeds (rad) tried after :data:`READY_QPOS` for the arm at the grasp: the arm's branch
there decides whether it can follow the handle along the joint (home, reaching out, wrist
turned either way)."""
RETREAT_SHARES = (1.0, 0.7, 0.5)
"""Shares of :attr:`ArticulatedMotion.retreat` tried, in order, for the retreat after the
release (a door opened far leaves the arm near its limits)."""
PAD_DEPTH = 0.004
"""The finger pads' centre lies this far (m) behind the tool site along the approach: the site
goes this far past the handle's centre so that the pads close on it."""


@dataclass(frozen=True)
class ArticulatedMotion:
    """Timing and geometry of the demonstration.

    Attributes:
        speed, accel, jerk: shares of the Panda's limits for the free reach.
        slow: share for the approach and retreat.
        pull: share for the constrained motion along the joint.
        pregrasp: approach distance along the handle's normal (m); retreat: after release (m).
        step_deg: waypoint spacing of a hinge (deg); step_m: of a slide (m).
        settle, close, release, hold: pauses (s).
    """

    speed: float = 0.5
    accel: float = 0.3
    jerk: float = 0.2
    slow: float = 0.5
    pull: float = 0.25
    pregrasp: float = 0.10
    retreat: float = 0.10
    step_deg: float = 4.0
    step_m: float = 0.02
    settle: float = 0.2
    close: float = 0.6
    release: float = 0.4
    hold: float = 0.6


@dataclass
class ArticulatedSetup:
    """A scene ready for planning: the part, the robot's base spot, the composed model.

    Attributes:
        scene: the scene (as loaded; its articulated assets present).
        part: the part the episodes act on.
        direction: ``open`` or ``close``.
        placement: the robot's base pose (world frame).
        model: the composed scene + robot.
        robot: its robot index.
        rig: the recording cameras.
        joint: the part's joint id in ``model``; qadr: its qpos address; body: its link body id.
        lo, hi: the joint's range in ``model`` (rad or m; 0 closed).
        cleared: objects taken out of the scene (none: kept for the demos' summary).
        frozen: movable objects compiled static (the articulated object itself among them).
    """

    scene: Scene
    part: Part
    direction: str
    placement: RobotPlacement
    model: mujoco.MjModel
    robot: RobotIndex
    rig: CameraRig
    joint: int
    qadr: int
    body: int
    lo: float
    hi: float
    cleared: tuple[str, ...] = ()
    frozen: tuple[str, ...] = ()

    @property
    def span(self) -> float:
        """How far the task opens the part (rad or m): a slide's whole range ``hi``; a hinge's
        range up to :data:`HINGE_SPAN` (the arm cannot follow a handle further round)."""
        if self.model.jnt_type[self.joint] == mujoco.mjtJoint.mjJNT_HINGE:
            return min(self.hi, HINGE_SPAN)
        return self.hi

    @property
    def close_start(self) -> tuple[float, float]:
        """The shares of :attr:`span` a ``close`` episode starts between:
        :data:`HINGE_CLOSE_START` for a hinge, :data:`CLOSE_START` for a slide."""
        if self.model.jnt_type[self.joint] == mujoco.mjtJoint.mjJNT_HINGE:
            return HINGE_CLOSE_START
        return CLOSE_START

    def opened(self, q: float) -> float:
        """Share of :attr:`span` at joint position ``q`` (what the success rule reads)."""
        return float(q) / self.span

    def fraction(self, q: float) -> float:
        """Share of the range at joint position ``q`` (0 closed, 1 fully open)."""
        return float(q) / self.hi

    def link_bodies(self) -> np.ndarray:
        """The moving link's body and the bodies below it (ids)."""
        m = self.model
        out = [self.body]
        for b in range(m.nbody):
            p = b
            while p > 0:
                p = int(m.body_parentid[p])
                if p == self.body:
                    out.append(b)
                    break
        return np.array(sorted(set(out)))


@dataclass(frozen=True)
class SetupHint:
    """What :func:`setup_scene`'s search chose for a scene, to set the same scene up again
    without searching (:func:`setup_scene`'s ``hint``; another process of the same run:
    :mod:`factory.tasks.articulated.setup_record`).

    Attributes:
        part: the part's key (``<object id>:<joint name>``).
        cleared: objects taken out of its way.
        spot: the robot's base spot.
        rig: the recording cameras as aimed there.
    """

    part: str
    cleared: tuple[str, ...]
    spot: RobotPlacement
    rig: CameraRig

    @staticmethod
    def of(setup: ArticulatedSetup) -> SetupHint:
        """The choices of a set-up."""
        return SetupHint(setup.part.key, setup.cleared, setup.placement, setup.rig)

    def to_json(self) -> dict[str, Any]:
        """A plain dict (JSON)."""
        return {
            "part": self.part,
            "cleared": list(self.cleared),
            "spot": asdict(self.spot),
            "rig": asdict(self.rig),
        }

    @staticmethod
    def from_json(d: dict[str, Any]) -> SetupHint:
        """The inverse of :meth:`to_json`."""
        rig: dict[str, Any] = {
            k: tuple(v) if isinstance(v, list) else v for k, v in d["rig"].items()
        }
        return SetupHint(
            str(d["part"]),
            tuple(d["cleared"]),
            RobotPlacement(**d["spot"]),
            CameraRig(**rig),
        )


@dataclass
class ArticulatedPlan:
    """What execution needs for one episode (as
    :class:`~factory.tasks.pick_place.plan.EpisodePlan`).

    Attributes:
        qpos0: initial state (nq,); the part's joint at ``q_start``.
        ctrl: actuator controls per physics step (T, nu).
        targets: desired arm joints (rad) and gripper command (m) per physics step (T, 8).
        phases: phase name -> first physics step.
        grasp_width: the handle's grip thickness (m).
        plan_seconds: planning time per planned segment (s).
        seconds: total planning time (s).
        attempts: grasp variants tried.
        q_start, q_goal: the part's joint position at the start and the motion's end (rad or m).
        pose_tool_in_link: the grasp (4, 4), the link body's frame.
    """

    qpos0: np.ndarray
    ctrl: np.ndarray
    targets: np.ndarray
    phases: dict[str, int]
    grasp_width: float
    plan_seconds: dict[str, float]
    seconds: float
    attempts: int
    q_start: float = 0.0
    q_goal: float = 0.0
    pose_tool_in_link: np.ndarray = field(default_factory=lambda: np.eye(4))


def initial_state(setup: ArticulatedSetup, q_joint: float) -> np.ndarray:
    """The scene's initial qpos (nq,): robot at home, hand open, the part at ``q_joint``."""
    from factory.tasks.pick_place.objects import initial_state as robot_home

    q = robot_home(setup.model, setup.robot)
    q[setup.robot.qpos] = READY_QPOS
    q[setup.qadr] = q_joint
    return q


def grasps_in_link(part: Part) -> list[np.ndarray]:
    """The handle grasps (4, 4) in the link body's frame: approach (+z) along ``-normal``,
    closing axis (+x) across the handle (either way round), the pads on the grip."""
    center, along, normal = part.handle_in_link()
    z = -normal
    x = np.cross(along, normal)
    x /= np.linalg.norm(x)
    out = []
    for sign in (1.0, -1.0):
        xs = sign * x
        y = np.cross(z, xs)
        out.append(pose_matrix(center + PAD_DEPTH * z, np.stack([xs, y, z], axis=1)))
    return out


class _Kinematics:
    """The link's pose at a joint value, from MuJoCo's kinematics of the composed model."""

    def __init__(self, setup: ArticulatedSetup) -> None:
        self.setup = setup
        self.data = mujoco.MjData(setup.model)

    def link(self, qpos: np.ndarray, q_joint: float) -> np.ndarray:
        d, s = self.data, self.setup
        d.qpos[:] = qpos
        d.qpos[s.qadr] = q_joint
        mujoco.mj_kinematics(s.model, d)
        return pose_matrix(d.xpos[s.body], d.xmat[s.body])


def joint_values(
    setup: ArticulatedSetup, q_a: float, q_b: float, motion: ArticulatedMotion
) -> np.ndarray:
    """Waypoints of the joint from ``q_a`` to ``q_b`` (both included)."""
    step = (
        math.radians(motion.step_deg)
        if setup.model.jnt_type[setup.joint] == mujoco.mjtJoint.mjJNT_HINGE
        else motion.step_m
    )
    n = max(2, math.ceil(abs(q_b - q_a) / step) + 1)
    return np.linspace(q_a, q_b, n)


def follow(
    setup: ArticulatedSetup,
    kin: _Kinematics,
    ik: IKSolver,
    checker: CollisionChecker,
    qpos: np.ndarray,
    grasp: np.ndarray,
    values: np.ndarray,
    q_seed: np.ndarray,
) -> tuple[np.ndarray, int]:
    """Arm configurations (k, 7) holding the grasp ``grasp`` (link frame) while the joint goes
    through ``values``: the first ``k`` waypoints that IK reaches continuously and without
    collision (``k`` = len(values) when all). Seeded by ``q_seed`` at the first waypoint."""
    base_inv = np.linalg.inv(setup.placement.matrix())
    out: list[np.ndarray] = []
    prev = q_seed
    state = qpos.copy()
    checker.ignore_bodies(setup.link_bodies())
    try:
        for v in values:
            tool = kin.link(qpos, float(v)) @ grasp
            state[setup.qadr] = v
            checker.set_scene(state)
            q = ik.solve(base_inv @ tool, [prev], accept=checker.valid)
            if q is None or (out and float(np.max(np.abs(q - prev))) > MAX_JUMP):
                break
            out.append(q)
            prev = q
    finally:
        checker.ignore_bodies([])
        checker.set_scene(qpos)
    return np.array(out).reshape(-1, 7), len(out)


def time_along(path: np.ndarray, limits: Limits, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One jerk-limited ruckig profile along a joint path (k, 7) without stops at its
    waypoints: the path parameter ``s`` (s at full speed: the largest joint step over its
    velocity limit, summed) goes from 0 to its end rest to rest with velocity 1, acceleration
    ``min(a/v)`` and jerk ``min(j/v)``; the joints are interpolated linearly in ``s``.

    Returns:
        positions and velocities (T, 7) sampled every ``dt`` s (the last sample is the path's
        end).
    """
    from ruckig import InputParameter, Result, Ruckig, Trajectory

    ds = np.max(np.abs(np.diff(path, axis=0)) / limits.v, axis=1)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    if s[-1] <= 1e-9:
        return path[:1].copy(), np.zeros((1, 7))
    otg = Ruckig(1)
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.target_position = [float(s[-1])]
    inp.current_velocity = inp.current_acceleration = [0.0]
    inp.target_velocity = inp.target_acceleration = [0.0]
    inp.max_velocity = [1.0]
    inp.max_acceleration = [float(np.min(limits.a / limits.v))]
    inp.max_jerk = [float(np.min(limits.j / limits.v))]
    traj = Trajectory(1)
    if otg.calculate(inp, traj) not in (Result.Working, Result.Finished):
        raise TaskError("ruckig could not time the constrained motion")
    duration = float(traj.duration)
    n = max(1, math.ceil(duration / dt))
    sp = np.empty(n + 1)
    sv = np.empty(n + 1)
    for k in range(n + 1):
        p, v, _ = traj.at_time(min(k * dt, duration))
        sp[k], sv[k] = p[0], v[0]
    sp[-1], sv[-1] = s[-1], 0.0
    q = np.stack([np.interp(sp, s, path[:, j]) for j in range(7)], axis=1)
    seg = np.clip(np.searchsorted(s, sp, side="right") - 1, 0, len(ds) - 1)
    slope = np.diff(path, axis=0) / np.maximum(ds, 1e-12)[:, None]
    return q, slope[seg] * sv[:, None]


BASE_BELOW = 0.1
"""The robot's base (its pedestal's top) stands this far (m) below the closed handle: the
Panda reaches a handle ahead with its tool level only up to about 0.1 m above its base."""
REACH = (0.3, 0.78)
"""Horizontal distances (m) from the base at which the handle may be along its whole path."""


def _candidates(
    handle_path: np.ndarray, normal: np.ndarray, z: float, limit: int = 40
) -> list[RobotPlacement]:
    """Base spots in front of the part, facing the middle of the handle's path (its positions
    ``handle_path`` (k, 3), world frame): a 5 cm grid of points at least 0.2 m in front of the
    closed handle (along its ``normal``, world frame) from which the whole path lies within
    :data:`REACH` horizontally, the nearest to the farthest point of the path first (at most
    ``limit``)."""
    c = handle_path.mean(axis=0)
    n2 = np.array([normal[0], normal[1]])
    n2 /= max(float(np.linalg.norm(n2)), 1e-9)
    start = handle_path[0, :2]
    out: list[tuple[float, RobotPlacement]] = []
    for dx in np.arange(-1.0, 1.0001, 0.05):
        for dy in np.arange(-1.0, 1.0001, 0.05):
            xy = c[:2] + np.array([dx, dy])
            if float(np.dot(xy - start, n2)) < 0.2:
                continue
            d = np.linalg.norm(handle_path[:, :2] - xy, axis=1)
            if d.min() < REACH[0] or d.max() > REACH[1]:
                continue
            yaw = math.atan2(c[1] - xy[1], c[0] - xy[0])
            out.append((float(d.max()), RobotPlacement(float(xy[0]), float(xy[1]), z, yaw)))
    out.sort(key=lambda t: t[0])
    return [p for _, p in out[:limit]]


@dataclass
class HandleMotion:
    """The arm's part of an episode between the pre-grasp and the retreat.

    Attributes:
        grasp: the grasp (4, 4), link frame.
        q_pre, q_grasp: arm joints (7,) at the pre-grasp and the grasp (rad).
        path: arm joints (k, 7) holding the handle at each of ``values``.
        values: the joint's waypoints (k,) (rad or m).
        q_back: arm joints (7,) after the retreat.
    """

    grasp: np.ndarray
    q_pre: np.ndarray
    q_grasp: np.ndarray
    path: np.ndarray
    values: np.ndarray
    q_back: np.ndarray


def grasp_and_follow(
    setup: ArticulatedSetup,
    kin: _Kinematics,
    ik: IKSolver,
    checker: CollisionChecker,
    q_start: float,
    q_goal: float,
    grasp: np.ndarray,
    pregrasp: float,
    motion: ArticulatedMotion,
) -> HandleMotion | str:
    """Pre-grasp, grasp, the constrained motion from ``q_start`` to ``q_goal`` and the retreat
    for one grasp (link frame), with the scene's part at ``q_start``.

    Returns:
        the motion, or the failure reason: ``no_grasp`` (no collision-free IK at the pre-grasp
        or the grasp, or the approach collides), ``ik_failed`` (the constrained motion or the
        retreat has no continuous IK; an ``open`` motion that gets beyond :data:`OPEN_AT` +
        0.02 of the range is kept up to there).
    """
    base_inv = np.linalg.inv(setup.placement.matrix())
    qpos = initial_state(setup, q_start)
    checker.attach(None)
    checker.ignore_bodies([])
    checker.set_scene(qpos)

    def solve(pose: np.ndarray, seeds: list[np.ndarray]) -> np.ndarray | None:
        return ik.solve(base_inv @ pose, seeds, accept=checker.valid)

    tool = kin.link(qpos, q_start) @ grasp
    pre = tool.copy()
    pre[:3, 3] -= tool[:3, 2] * pregrasp
    values = joint_values(setup, q_start, q_goal, motion)
    # the arm's branch at the grasp decides whether it can follow the handle: try a few
    seeds = [READY_QPOS, *GRASP_SEEDS]
    best: tuple[np.ndarray, np.ndarray, int] | None = None
    tried: list[np.ndarray] = []
    for seed in seeds:
        q_grasp = solve(tool, [seed])
        if q_grasp is None or any(float(np.max(np.abs(q_grasp - t))) < 0.05 for t in tried):
            continue
        tried.append(q_grasp)
        path, k = follow(setup, kin, ik, checker, qpos, grasp, values, q_grasp)
        if best is None or k > best[2]:
            best = (q_grasp, path, k)
        if k == len(values):
            break
    if best is None:
        return "no_grasp"
    q_grasp, path, k = best
    if k < len(values):
        reached = setup.opened(values[k - 1]) if k else setup.opened(q_start)
        if not (setup.direction == "open" and reached >= OPEN_AT + 0.02):
            return "ik_failed"
        values = values[:k]
    q_pre = solve(pre, [q_grasp])
    if q_pre is None or not checker.segment_valid(q_pre, q_grasp):
        return "no_grasp"
    q_end = float(values[-1])
    end_state = qpos.copy()
    end_state[setup.qadr] = q_end
    tool_end = kin.link(qpos, q_end) @ grasp
    checker.set_scene(end_state)
    checker.ignore_bodies(setup.link_bodies())
    q_back = None
    try:
        for share in RETREAT_SHARES:
            back = tool_end.copy()
            back[:3, 3] -= tool_end[:3, 2] * motion.retreat * share
            q = solve(back, [path[-1]])
            if q is not None and float(np.max(np.abs(q - path[-1]))) <= 1.0:
                q_back = q
                break
    finally:
        checker.ignore_bodies([])
        checker.set_scene(qpos)
    if q_back is None:
        return "ik_failed"
    return HandleMotion(grasp, q_pre, q_grasp, path, values, q_back)


BASE_BODIES = ("panda/robot0_base", "panda/robot0_link0", "panda/robot0_link1")
"""The robot's bodies that do not move out of a swinging part's way (base, pedestal, shoulder)."""


def _sweeps_base(
    setup: ArticulatedSetup,
    checker: CollisionChecker,
    qpos: np.ndarray,
    values: np.ndarray,
    link_names: set[str],
) -> bool:
    """Whether the moving link hits the robot's base or shoulder (:data:`BASE_BODIES`, the arm
    at home) at any of the joint's waypoints ``values``."""
    state = qpos.copy()
    try:
        for v in values:
            state[setup.qadr] = v
            checker.set_scene(state)
            for a, b, _ in checker.collisions(READY_QPOS):
                if (a in link_names and b in BASE_BODIES) or (b in link_names and a in BASE_BODIES):
                    return True
    finally:
        checker.set_scene(qpos)
    return False


ROOM_MARGIN = 0.15
"""A base spot keeps this far (m) inside a room's walls (the pedestal's radius and more)."""
BLOCK_DEPTH = 0.005
"""The moving link touching something else deeper than this (m) at a waypoint blocks it."""


def _in_a_room(scene: Scene, spot: RobotPlacement) -> bool:
    """Whether the base spot lies inside one of the scene's rooms, :data:`ROOM_MARGIN` from its
    walls (a scene without rooms: anywhere)."""
    if not scene.rooms:
        return True
    for r in scene.rooms:
        x0, y0 = r.position.x + ROOM_MARGIN, r.position.y + ROOM_MARGIN
        x1 = r.position.x + r.dimensions.width - ROOM_MARGIN
        y1 = r.position.y + r.dimensions.length - ROOM_MARGIN
        if x0 <= spot.x <= x1 and y0 <= spot.y <= y1:
            return True
    return False


def _part_blocked(setup: ArticulatedSetup, qpos: np.ndarray, values: np.ndarray) -> str:
    """What the moving link runs into (a body's name, ``""``: nothing) at the joint's
    waypoints ``values``: a wall, the furniture next to it, something standing in front (the
    articulated object's own bodies and the robot do not count)."""
    m = setup.model
    d = mujoco.MjData(m)
    own = np.zeros(m.nbody, bool)
    root = m.body(setup.part.obj.id).id
    for b in range(m.nbody):
        p = b
        while p > 0 and p != root:
            p = int(m.body_parentid[p])
        own[b] = p == root
    robot = np.zeros(m.nbody, bool)
    robot[setup.robot.bodies] = True
    link = np.zeros(m.nbody, bool)
    link[setup.link_bodies()] = True
    for v in values:
        d.qpos[:] = qpos
        d.qpos[setup.qadr] = v
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            b1, b2 = (int(m.geom_bodyid[g]) for g in c.geom)
            if c.dist > -BLOCK_DEPTH or not (link[b1] or link[b2]):
                continue
            other = b2 if link[b1] else b1
            if not own[other] and not robot[other]:
                return str(m.body(other).name) or "the world"
    return ""


def _home_free(setup: ArticulatedSetup, checker: CollisionChecker, starts: list[float]) -> bool:
    """Whether the robot at home collides with nothing with the part at each of the episodes'
    possible start positions ``starts`` (rad or m)."""
    try:
        for v in starts:
            checker.set_scene(initial_state(setup, float(v)))
            if not checker.valid(READY_QPOS):
                return False
    finally:
        checker.set_scene(initial_state(setup, float(starts[-1])))
    return True


def _clearable(scene: Scene, name: str, part: Part) -> set[str]:
    """The objects to take out of the scene so that ``part`` can move: the body ``name`` it
    runs into, when it is a light movable floor object (a chair, a stool, a bin: not static,
    at most 25 kg and 1 m across), with what stands on it; empty when it is anything else."""
    ids = {o.id for o in scene.objects}
    if name not in ids or name == part.obj.id:
        return set()
    obj = scene.object(name)
    light = obj.physics.mass <= 25.0 and max(obj.dimensions.width, obj.dimensions.length) <= 1.0
    if obj.is_static or obj.placement.kind != "floor" or not light:
        return set()
    gone = scene.with_dependents({name})
    return set() if part.obj.id in gone else gone


def _setup_part(
    scene: Scene,
    assets_root: str | Path | None,
    part: Part,
    direction: str,
    rig: CameraRig,
    freeze_beyond: float,
    ik: IKSolver,
    motion: ArticulatedMotion,
    why: Counter[str],
    open_to: float = OPEN_GOAL[1],
    round_trip: bool = False,
    spot_check: SpotCheck | None = None,
    chosen: SetupHint | None = None,
) -> ArticulatedSetup | str:
    """:func:`setup_scene` for one part: the set-up, ``"blocked:<body>"`` when the moving link
    runs into that body, or ``""`` when no base spot works (reasons counted into ``why``,
    those of the way back as ``back_<reason>``). With ``chosen`` (an earlier search's choices
    for this part), its spot and cameras are taken without the checks."""
    from factory.tasks.pick_place.objects import move_robot
    from factory.tasks.pick_place.plan import aim_cameras, compose

    frozen = {part.obj.id} if not part.obj.is_static else set()
    if chosen is not None:
        return _set_up_at(
            scene, assets_root, part, direction, chosen.spot, chosen.rig, frozen, freeze_beyond
        )
    model = compose(scene, assets_root, RobotPlacement(0.0, 0.0, 0.0, 0.0), rig, frozen)
    jid = model.joint(part.joint_name).id
    lo, hi = (float(v) for v in model.jnt_range[jid])
    setup = ArticulatedSetup(
        scene,
        part,
        direction,
        RobotPlacement(0.0, 0.0, 0.0, 0.0),
        model,
        RobotIndex.of(model),
        rig,
        jid,
        int(model.jnt_qposadr[jid]),
        model.body(part.body_name).id,
        lo,
        hi,
    )
    kin = _Kinematics(setup)
    span = setup.span
    close_start = setup.close_start
    start = (0.0 if direction == "open" else close_start[1]) * span
    goal = (open_to if direction == "open" else 0.0) * span
    values = joint_values(setup, start, goal, motion)
    center, _, normal = part.handle_in_link()
    q0 = initial_state(setup, start)
    handle = np.array([(kin.link(q0, float(v)) @ np.append(center, 1.0))[:3] for v in values])
    closed = kin.link(q0, 0.0)
    z = max(0.0, float((closed @ np.append(center, 1.0))[2]) - BASE_BELOW)
    spots = _candidates(handle, closed[:3, :3] @ normal, z)
    # the pedestal's height is the spot's: compose once at that height, then move the base
    model = compose(scene, assets_root, spots[0], rig, frozen)
    setup.model, setup.robot = model, RobotIndex.of(model)
    kin = _Kinematics(setup)
    base_body = model.body("panda/robot0_base").id
    blocked = _part_blocked(setup, q0, values)
    if blocked:
        log.info(
            "scene %s: %s (%s) cannot move: it runs into %s",
            scene.id,
            part.key,
            part.label,
            blocked,
        )
        return f"blocked:{blocked}"
    link_names = {model.body(b).name for b in setup.link_bodies()}
    starts = [0.0] if direction == "open" else list(np.linspace(*close_start, 9) * span)
    found = None
    for spot in spots:
        if not _in_a_room(scene, spot):
            why["outside_rooms"] += 1
            continue
        move_robot(model, spot, base_body)
        setup.placement = spot
        checker = CollisionChecker(model, setup.robot, q0)
        if not _home_free(setup, checker, starts):
            why["robot_in_the_way"] += 1
            continue
        if _sweeps_base(setup, checker, q0, values, link_names):
            why["part_hits_base"] += 1
            continue
        results = [
            grasp_and_follow(setup, kin, ik, checker, start, goal, g, motion.pregrasp, motion)
            for g in grasps_in_link(part)[:1]
        ]
        if not isinstance(results[0], HandleMotion):
            results += [
                grasp_and_follow(setup, kin, ik, checker, start, goal, g, motion.pregrasp, motion)
                for g in grasps_in_link(part)[1:]
            ]
        ok = [r for r in results if isinstance(r, HandleMotion)]
        if not ok:
            why.update(r for r in results if isinstance(r, str))
            continue
        if round_trip and direction == "open":
            back = _way_back(setup, kin, ik, checker, float(ok[0].values[-1]), motion)
            if back:
                why[f"back_{back}"] += 1
                continue
        if spot_check is not None:
            refused = spot_check(setup, checker)
            if refused:
                why[refused] += 1
                continue
        found = spot
        break
    if found is None:
        log.info(
            "scene %s: %s (%s) is out of reach from %d base spots",
            scene.id,
            part.key,
            part.label,
            len(spots),
        )
        return ""
    # the third-person cameras look at the middle of the handle's path, not the default
    # workspace centre (0.5 m ahead): that is where the hand works
    ahead = float(np.dot(found.to_base(handle.mean(axis=0))[:2], [1.0, 0.0]))
    cams = aim_cameras(
        scene, assets_root, found, replace(rig, workspace=float(np.clip(ahead, 0.3, 0.8)))
    )
    return _set_up_at(scene, assets_root, part, direction, found, cams, frozen, freeze_beyond)


def _set_up_at(
    scene: Scene,
    assets_root: str | Path | None,
    part: Part,
    direction: str,
    found: RobotPlacement,
    cams: CameraRig,
    frozen: set[str],
    freeze_beyond: float,
) -> ArticulatedSetup:
    """The set-up with the robot at ``found`` and the cameras ``cams`` (the search's end)."""
    from factory.tasks.pick_place.plan import compose, far_objects

    far = far_objects(scene, found, set(), freeze_beyond) | frozen
    model = compose(scene, assets_root, found, cams, far)
    jid = model.joint(part.joint_name).id
    log.info(
        "scene %s: %s %s (%s) from base (%.2f, %.2f, %.2f) yaw %.0f deg",
        scene.id,
        direction,
        part.key,
        part.label,
        found.x,
        found.y,
        found.z,
        math.degrees(found.yaw),
    )
    return ArticulatedSetup(
        scene,
        part,
        direction,
        found,
        model,
        RobotIndex.of(model),
        cams,
        jid,
        int(model.jnt_qposadr[jid]),
        model.body(part.body_name).id,
        float(model.jnt_range[jid][0]),
        float(model.jnt_range[jid][1]),
        (),
        tuple(sorted(far)),
    )


SpotCheck = Callable[[ArticulatedSetup, CollisionChecker], str]
"""A task's own test of a base spot (:func:`setup_scene`'s ``spot_check``): given the set-up
with the robot at the spot and a collision checker of it, ``""`` to take the spot, else the
reason counted against it."""


def _way_back(
    setup: ArticulatedSetup,
    kin: _Kinematics,
    ik: IKSolver,
    checker: CollisionChecker,
    q_open: float,
    motion: ArticulatedMotion,
) -> str:
    """Whether the part opened to ``q_open`` can be pushed back to 0 from the spot in
    ``setup.placement`` (for one of the handle's grasps): ``""`` when it can, else the last
    reason of :func:`grasp_and_follow`."""
    closing = replace(setup, direction="close")
    reason = "no_grasp"
    for g in grasps_in_link(setup.part):
        res = grasp_and_follow(closing, kin, ik, checker, q_open, 0.0, g, motion.pregrasp, motion)
        if isinstance(res, HandleMotion):
            return ""
        reason = res
    return reason


def setup_scene(
    scene: Scene,
    assets_root: str | Path | None,
    direction: str,
    rig: CameraRig | None = None,
    freeze_beyond: float = 1.0,
    max_parts: int = MAX_PARTS,
    open_to: float = OPEN_GOAL[1],
    round_trip: bool = False,
    spot_check: SpotCheck | None = None,
    hint: SetupHint | None = None,
) -> ArticulatedSetup:
    """Chooses the part and the robot's base spot and composes the scene with the robot there.

    For each part of :func:`~factory.tasks.articulated.parts.choose_parts` (at most
    ``max_parts``), base spots in front of its handle (:func:`_candidates`; the base's height
    is the closed handle's height - :data:`BASE_BELOW`, at least 0) are tried in order; a spot
    is taken when the robot at :data:`READY_QPOS` collides with nothing at the episodes'
    possible starts, the moving link never hits its base (:func:`_sweeps_base`), and the whole
    motion from the hardest start (``close``: fully open) to the goal (pre-grasp, grasp, constrained
    motion, retreat: :func:`grasp_and_follow`) plans for one of the handle's grasps. The
    articulated object is compiled static (its links move on their joints); movable objects
    farther than ``freeze_beyond`` (m) are static too.

    Args:
        open_to: for ``open``, the share of the span the checked motion goes to
            (:data:`OPEN_GOAL`'s upper end by default; ``place_inside`` opens a door less, so
            that the arm can push it back).
        round_trip: for ``open``, the spot must also let the arm push the part back from
            there to 0 (:func:`grasp_and_follow` of the closing motion: a task that opens,
            works inside and closes again).
        spot_check: a task's own test of a spot that passed the others (:data:`SpotCheck`:
            ``place_inside`` asks that the hand reach the interior behind a door).
        hint: the choices of an earlier search with the same arguments
            (:meth:`SetupHint.of`): the same set-up, composed without searching.

    Raises:
        TaskError: no part, a named part missing, or no part reachable (with the reasons);
            a ``hint`` whose part the scene lacks.
    """
    rig = rig or CameraRig()
    parts = choose_parts(scene, assets_root)
    ik = IKSolver()
    motion = ArticulatedMotion()
    why: Counter[str] = Counter()

    def set_up(sc: Scene, part: Part, chosen: SetupHint | None = None) -> ArticulatedSetup | str:
        """:func:`_setup_part` of ``part`` in ``sc`` with this call's settings."""
        return _setup_part(
            sc,
            assets_root,
            part,
            direction,
            rig,
            freeze_beyond,
            ik,
            motion,
            why,
            open_to,
            round_trip,
            spot_check,
            chosen=chosen,
        )

    if hint is not None:
        match = [p for p in parts if p.key == hint.part]
        if not match:
            raise TaskError(
                f"scene {scene.id!r}: its set-up record names part {hint.part!r}, which the "
                f"scene lacks (its parts: {', '.join(p.key for p in parts) or 'none'}); "
                "delete the run's cache/setups folder and re-run"
            )
        sc = replace(scene, objects=[o for o in scene.objects if o.id not in hint.cleared])
        res = set_up(sc, match[0], chosen=hint)
        assert isinstance(res, ArticulatedSetup)
        res.cleared = hint.cleared
        return res
    for part in parts[:max_parts]:
        sc, cleared = scene, set[str]()
        for _ in range(MAX_CLEARED + 1):
            res = set_up(sc, part)
            if isinstance(res, ArticulatedSetup):
                res.cleared = tuple(sorted(cleared))
                return res
            if res.startswith("blocked:"):
                name = res.partition(":")[2]
                gone = _clearable(sc, name, part)
                if gone:
                    log.info(
                        "scene %s: took %s out of the way of %s (%s)",
                        scene.id,
                        sorted(gone),
                        part.key,
                        part.label,
                    )
                    sc = replace(sc, objects=[o for o in sc.objects if o.id not in gone])
                    cleared |= gone
                    continue
                why["part_blocked"] += 1
            break
    tried = ", ".join(f"{p.key} ({p.label})" for p in parts[:max_parts])
    raise TaskError(
        f"scene {scene.id!r}: the robot can {direction} none of {tried} from a free base spot "
        f"in front of it ({dict(why)})"
    )


class ArticulatedPlanner:
    """Plans the episodes of one scene (deterministic per seed).

    Args:
        setup: the scene with the robot placed.
        motion: timing and geometry.
        planner_cfg: the free reach's RRTConnect settings.
        open_goal: the shares of the span an ``open`` episode's goal is drawn between
            (:data:`OPEN_GOAL` by default).
    """

    def __init__(
        self,
        setup: ArticulatedSetup,
        motion: ArticulatedMotion | None = None,
        planner_cfg: PlannerConfig | None = None,
        open_goal: tuple[float, float] = OPEN_GOAL,
    ) -> None:
        from factory.tasks.pick_place.objects import initial_state as robot_home

        self.setup = setup
        self.open_goal = open_goal
        self.motion = motion or ArticulatedMotion()
        self.planner_cfg = planner_cfg or PlannerConfig()
        self.ik = IKSolver()
        m = setup.model
        self.model = m
        self.robot = setup.robot
        self.checker = CollisionChecker(m, self.robot, robot_home(m, self.robot))
        self.kin = _Kinematics(setup)
        self.base_inv = np.linalg.inv(setup.placement.matrix())
        self.dt = float(m.opt.timestep)
        mo = self.motion
        self.fast = Limits.panda(mo.speed, mo.accel, mo.jerk)
        self.slow = Limits.panda(mo.speed * mo.slow, mo.accel * mo.slow, mo.jerk * mo.slow)
        self.pull = Limits.panda(mo.pull, mo.pull, mo.pull)

    def start_and_goal(self, rng: np.random.Generator) -> tuple[float, float]:
        """The episode's start and goal joint positions (rad or m), drawn with ``rng``."""
        hi = self.setup.span
        if self.setup.direction == "open":
            return 0.0, float(rng.uniform(*self.open_goal)) * hi
        return float(rng.uniform(*self.setup.close_start)) * hi, 0.0

    def plan_episode(self, seed: int) -> ArticulatedPlan | PlanFailure:
        """Plans one episode (deterministic in ``seed``): its start and goal
        (:meth:`start_and_goal`), a pre-grasp distance of 0.8-1.2 x ``pregrasp``, the two
        grasps in a random order (:func:`grasp_and_follow`), the reach by RRTConnect."""
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed)
        setup, mo, ck = self.setup, self.motion, self.checker
        q_start, q_goal = self.start_and_goal(rng)
        qpos = initial_state(setup, q_start)
        ck.set_scene(qpos)
        ck.attach(None)
        ck.ignore_bodies([])
        if not ck.valid(READY_QPOS):
            return PlanFailure("collision", "robot at home collides", time.perf_counter() - t0)
        counts: Counter[str] = Counter()
        pregrasp = float(rng.uniform(0.8, 1.2)) * mo.pregrasp
        grasps = grasps_in_link(setup.part)
        for attempt, gi in enumerate(rng.permutation(len(grasps))):
            res = grasp_and_follow(
                setup, self.kin, self.ik, ck, q_start, q_goal, grasps[gi], pregrasp, mo
            )
            if isinstance(res, str):
                counts[res] += 1
                continue
            seconds: dict[str, float] = {}
            reach = plan(ck, READY_QPOS, res.q_pre, self.planner_cfg, int(rng.integers(2**31 - 1)))
            seconds["reach"] = reach.seconds
            if reach.path is None:
                counts["plan_failed"] += 1
                continue
            out = self._timeline(qpos, reach.path, res, seconds)
            out.q_start, out.q_goal = q_start, float(res.values[-1])
            out.pose_tool_in_link = res.grasp
            out.attempts = attempt + 1
            out.seconds = time.perf_counter() - t0
            return out
        tried = f"{setup.part.key} ({setup.part.label}): {len(grasps)} grasps tried"
        return PlanFailure.of_counts(counts, "no_grasp", tried, t0)

    def _timeline(
        self,
        qpos: np.ndarray,
        reach: np.ndarray,
        res: HandleMotion,
        seconds: dict[str, float],
    ) -> ArticulatedPlan:
        from factory.tasks.pick_place.plan import targets_to_ctrl

        mo, dt = self.motion, self.dt
        arm: list[np.ndarray] = []
        vel: list[np.ndarray] = []
        grip: list[float] = []
        phases: dict[str, int] = {}

        def hold(name: str, q: np.ndarray, secs: float, opening: float) -> None:
            phases[name] = len(arm)
            n = max(1, round(secs / dt))
            arm.extend([q] * n)
            vel.extend([np.zeros(7)] * n)
            grip.extend([opening] * n)

        def move(name: str, p: np.ndarray, limits: Limits, opening: float) -> None:
            phases[name] = len(arm)
            timed = time_path(p, limits, dt)
            arm.extend(list(timed.q[1:]))
            vel.extend(list(timed.qd[1:]))
            grip.extend([opening] * (len(timed.q) - 1))

        q_pre, q_grasp, path, q_back = res.q_pre, res.q_grasp, res.path, res.q_back
        hold("settle", READY_QPOS, mo.settle, GRIP_OPEN)
        move("reach", reach, self.fast, GRIP_OPEN)
        move("approach", np.stack([q_pre, q_grasp]), self.slow, GRIP_OPEN)
        hold("grasp", q_grasp, mo.close, GRIP_CLOSED)
        phases["pull"] = len(arm)
        q, qd = time_along(np.vstack([q_grasp[None], path]), self.pull, dt)
        arm.extend(list(q[1:]))
        vel.extend(list(qd[1:]))
        grip.extend([GRIP_CLOSED] * (len(q) - 1))
        hold("release", path[-1], mo.release, GRIP_OPEN)
        move("retreat", np.stack([path[-1], q_back]), self.slow, GRIP_OPEN)
        hold("hold", q_back, mo.hold, GRIP_OPEN)
        phases["end"] = len(arm)
        ctrl = targets_to_ctrl(self.model, self.robot, np.asarray(arm), np.asarray(vel), grip)
        targets = np.concatenate([np.asarray(arm), np.asarray(grip)[:, None]], axis=1)
        return ArticulatedPlan(
            qpos, ctrl, targets, phases, float(self.setup.part.handle.thickness), seconds, 0.0, 0
        )


def camera_calibration(
    setup: ArticulatedSetup, cameras: Sequence[str]
) -> tuple[dict[str, list[float]], dict[str, float]]:
    """The calibration of those of ``cameras`` fixed in the scene: each one's pose in the
    robot's base frame (12: position m, rotation rows) and vertical field of view (deg)
    (:func:`factory.demos.record.calibration.camera_calibration`)."""
    from factory.demos.record.calibration import camera_calibration as calibrate
    from factory.robots.panda import CAMERAS, SCENE_CAMERAS, rot_z

    cams = {c: CAMERAS[c] for c in cameras if c in SCENE_CAMERAS}
    p = setup.placement
    return calibrate(setup.model, cams, p.pos(), rot_z(p.yaw), None)
