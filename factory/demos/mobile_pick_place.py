"""Mobile pick-and-place: drive to a support, pick an object, drive to another support, place it.

The robot is the Panda on the Omron base (:mod:`factory.demos.mobile_robot`). Per scene,
:func:`mobile_setup` composes the scene with the robot (and two fisheye cameras on its mounts)
and rasterizes the occupancy grid, inflated by the base's footprint radius. Per episode,
:meth:`MobilePlanner.plan_episode` (deterministic in its seed):

1. spawns the base at a free pose of the inflated grid (:func:`factory.nav.random_free_pose`),
   arm stowed, hand closed;
2. ``navigate_to_pick``: a base pose beside the pick support (:func:`factory.nav.base_pose_beside`),
   an OMPL path on the grid, a ruckig-timed (x, y, yaw) trajectory under
   :data:`~factory.demos.mobile_robot.BASE_LIMITS`, re-checked with the robot's real shape;
3. ``pick``: the fixed-base machinery with the arm's base frame at the mobile arm mount:
   antipodal grasps (:mod:`factory.demos.grasps`), mink IK (:class:`factory.demos.ik.IKSolver`,
   which works on the fixed robot alone in its link0 frame, here mapped through the mount
   pose), OMPL RRTConnect arm motions checked in the scene (:mod:`factory.demos.planner`),
   ruckig timing (:mod:`factory.demos.timing`); then the arm folds into a carry pose;
4. ``navigate_to_place``: as 2, to a base pose beside the place support, carrying the object
   (the re-check moves the object with the hand);
5. ``place``: the object upright on the place support's top, released, the hand retreats.

Everything is timed into per-physics-step control targets: 7 arm joints, the gripper and the
base (x, y, yaw), with a sub-task label per step and a done flag at each sub-task's last
step. :func:`execute_mobile` simulates the controls in one ``mujoco.MjData``, records frames
(state, base pose, arm, gripper, action, labels, RGB + depth of ``left``, ``right``, ``wrist``
and the fisheye cameras ``fisheye_front``/``fisheye_back``) and checks success
(:func:`check_mobile_success`). Nothing is teleported.

Frames: world frame for poses (m, rad); the base pose is the footprint centre's (x, y) and the
unwrapped yaw (the base joints' values); tool site +z is the approach, +x the closing axis.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

import mujoco
import numpy as np

from factory.demos.grasps import (
    Grasp,
    GraspConfig,
    GripperShape,
    antipodal_candidates,
    collision_pieces,
    facing_order,
    gripper_clear,
)
from factory.demos.ik import IKConfig, IKSolver
from factory.demos.mobile_robot import (
    BASE_LIMITS,
    CAMERAS,
    FISHEYE_CAMERA_QUAT,
    FISHEYE_MOUNTS,
    FOOTPRINT_RADIUS,
    PREFIX,
    STOW_FINGERS,
    STOW_QPOS,
    MobileRobotIndex,
    add_mobile_robot,
)
from factory.demos.pick_place import MotionConfig, targets_to_ctrl
from factory.demos.planner import Attachment, CollisionChecker, PlannerConfig, plan
from factory.demos.robot import GRIP_CLOSED, GRIP_OPEN, HOME_QPOS, pose_matrix, rot_z
from factory.demos.task import Outcome
from factory.demos.timing import Limits, time_path
from factory.errors import TaskError
from factory.nav import (
    BASE_COLLISION,
    NAV_FAILED,
    BaseLimits,
    BasePose,
    BaseTrajectory,
    NavError,
    NavPlannerConfig,
    OccupancyGrid,
    base_pose_beside,
    base_trajectory,
    plan_base_path,
    random_free_pose,
)
from factory.nav.grid import geom_points

if TYPE_CHECKING:
    from factory.demos.robot import RobotIndex
    from factory.schema import Scene, SceneObject

log = logging.getLogger(__name__)

SUBTASKS: tuple[str, str, str, str] = ("navigate_to_pick", "pick", "navigate_to_place", "place")
"""Sub-task labels, in order; a step's label id is its index here."""

NO_SPAWN = "no_spawn"
NO_PLACE_SUPPORT = "no_place_support"
COLLISION = "collision"
REASONS: tuple[str, ...] = (
    NAV_FAILED,
    BASE_COLLISION,
    NO_SPAWN,
    NO_PLACE_SUPPORT,
    "no_grasp",
    "ik_failed",
    "plan_failed",
    "approach_collision",
    "lift_collision",
    "retreat_collision",
)
"""Planning failure reasons (the grasp/IK ones are the fixed-base task's)."""

FISHEYE_CAMERAS: dict[str, str] = {name: f"{PREFIX}{name}" for name in FISHEYE_MOUNTS}
"""Recording fisheye camera name -> camera name in the composed model (added to the mounts)."""
ALL_CAMERAS: tuple[str, ...] = (*CAMERAS, *FISHEYE_CAMERAS)
"""Every recording camera of the mobile robot."""


class MobileTaskError(TaskError):
    """A scene cannot host the mobile task (missing objects, no place support).

    Attributes:
        reason: the failure key (``no_place_support`` or ``""``).
    """

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason


# ---------------------------------------------------------------------------------------------
# Task objects and scene set-up


@dataclass(frozen=True)
class MobileTaskObjects:
    """The objects of a mobile pick-and-place.

    Attributes:
        pick: the object to move; pick_support: what it stands on; place_support: the
            furniture whose top it goes onto.
    """

    pick: SceneObject
    pick_support: SceneObject
    place_support: SceneObject


def mobile_task_objects(
    scene: Scene,
    pick: str | None = None,
    pick_support: str | None = None,
    place_support: str | None = None,
) -> MobileTaskObjects:
    """The pick object, its support and the place support of a scene.

    Without ids, they are read as :func:`factory.demos.task.task_objects` reads them (objects
    with ``task_role`` ``pick`` / ``place_target``, else the task instruction): the pick's
    support is what it stands on; the place support is the target when the target stands on
    the floor (a desk), else what the target stands on (the desk under a tray), or an object
    with ``task_role`` ``place_support``.

    Raises:
        TaskError: no pick object or it stands on nothing.
        MobileTaskError: no place support (reason ``no_place_support``), or it is the pick's
            own support.
    """
    from factory.demos.task import task_objects

    by_id = {o.id: o for o in scene.objects}

    def get(oid: str, what: str) -> SceneObject:
        if oid not in by_id:
            reason = NO_PLACE_SUPPORT if what == "place support" else ""
            raise MobileTaskError(f"scene {scene.id!r} has no {what} {oid!r}", reason)
        return by_id[oid]

    role_support = next((o for o in scene.objects if o.task_role == "place_support"), None)
    target: SceneObject | None = None
    if pick is None or (place_support is None and role_support is None):
        try:
            objs = task_objects(scene)
            target = objs.target
            pick = pick or objs.pick.id
        except TaskError:
            if pick is None:
                pick = next((o.id for o in scene.objects if o.task_role == "pick"), None)
                if pick is None:
                    raise
    p = get(pick, "pick object")
    sid = pick_support or p.placement.support_id
    if not sid:
        raise MobileTaskError(f"scene {scene.id!r}: pick object {p.id!r} stands on no support")
    ps = get(sid, "pick support")
    if place_support is None:
        if role_support is not None:
            place_support = role_support.id
        elif target is not None:
            on = target.placement.support_id
            floor = target.placement.kind == "floor" or not on or on not in by_id
            place_support = target.id if floor else on
    if place_support is None:
        raise MobileTaskError(
            f"scene {scene.id!r}: no place support (give an object task_role 'place_support' "
            "or 'place_target')",
            NO_PLACE_SUPPORT,
        )
    pl = get(place_support, "place support")
    if pl.id == ps.id:
        raise MobileTaskError(
            f"scene {scene.id!r}: the place support {pl.id!r} is the pick's own support",
            NO_PLACE_SUPPORT,
        )
    return MobileTaskObjects(p, ps, pl)


@dataclass
class MobileSetup:
    """A scene composed with the mobile robot, ready for planning.

    Attributes:
        scene: the scene; objects: its task objects.
        model: the composed model (robot, recording cameras, fisheye cameras).
        robot: the robot's addresses in it.
        grid: the occupancy grid of the scene (robot left out), not inflated.
        nav_grid: ``grid`` inflated by ``FOOTPRINT_RADIUS``: where the base centre may be.
        arm_mount: pose (4, 4) of the arm's IK frame (link0) in the base frame.
    """

    scene: Scene
    objects: MobileTaskObjects
    model: mujoco.MjModel
    robot: MobileRobotIndex
    grid: OccupancyGrid
    nav_grid: OccupancyGrid
    arm_mount: np.ndarray


def compose_mobile(
    scene: Scene,
    assets_root: str | Path | None = None,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> mujoco.MjModel:
    """Compiles a scene with the mobile robot at ``pose`` (x, y m, yaw rad; its ``qpos0``) and
    a camera in each fisheye mount (``mobile/fisheye_front``, ``mobile/fisheye_back``)."""
    from factory.sim.compile import compile_scene

    compiled = compile_scene(scene, assets_root)
    spec = compiled.spec
    add_mobile_robot(spec, pose)
    for name, mount in FISHEYE_MOUNTS.items():
        spec.body(mount).add_camera(name=FISHEYE_CAMERAS[name], quat=list(FISHEYE_CAMERA_QUAT))
    return spec.compile()


def _arm_mount(model: mujoco.MjModel, robot: MobileRobotIndex) -> np.ndarray:
    """Pose (4, 4) of the IK model's base frame (the fixed robot's link0 at the origin) in the
    mobile base frame."""
    from factory.demos.robot import robot_model

    data = mujoco.MjData(model)
    data.qpos[robot.base_qpos] = 0.0
    mujoco.mj_kinematics(model, data)
    link0 = model.body(f"{PREFIX}robot0_link0").id
    mobile = pose_matrix(data.xpos[link0], data.xmat[link0])
    fixed_model = robot_model()
    fd = mujoco.MjData(fixed_model)
    mujoco.mj_kinematics(fixed_model, fd)
    fl0 = fixed_model.body("panda/robot0_link0").id
    fixed = pose_matrix(fd.xpos[fl0], fd.xmat[fl0])
    return cast(np.ndarray, mobile @ np.linalg.inv(fixed))


def mobile_setup(
    scene: Scene,
    assets_root: str | Path | None = None,
    objects: MobileTaskObjects | None = None,
    resolution: float = 0.05,
) -> MobileSetup:
    """Composes the scene with the robot and rasterizes its occupancy grid.

    Args:
        scene: the scene.
        assets_root: the run's assets folder (None: objects are boxes).
        objects: the task objects; default :func:`mobile_task_objects`.
        resolution: grid cell side (m).

    Raises:
        TaskError: the task objects are missing.
    """
    objects = objects or mobile_task_objects(scene)
    model = compose_mobile(scene, assets_root)
    robot = MobileRobotIndex.of(model)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    grid = OccupancyGrid.from_model(model, data, resolution=resolution)
    return MobileSetup(
        scene=scene,
        objects=objects,
        model=model,
        robot=robot,
        grid=grid,
        nav_grid=grid.inflate(FOOTPRINT_RADIUS),
        arm_mount=_arm_mount(model, robot),
    )


def base_matrix(pose: np.ndarray) -> np.ndarray:
    """The base frame (4, 4) in the world for a base pose (3,): x, y (m), yaw (rad)."""
    return pose_matrix(np.array([pose[0], pose[1], 0.0]), rot_z(float(pose[2])))


def body_box(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> np.ndarray:
    """World axis-aligned box (6,) of a body's colliding geoms: xmin, ymin, zmin, xmax, ymax,
    zmax (m); ``data`` needs current kinematics."""
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    geoms = np.flatnonzero((model.geom_bodyid == body) & collides)
    if not len(geoms):
        raise TaskError(f"body {model.body(body).name!r} has no collision geometry")
    pts = np.concatenate([geom_points(model, data, int(g)) for g in geoms])
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


def support_top(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> float:
    """World height (m) of a support's top at its centre: the topmost surface on the vertical
    line through the middle of its box (the fixed task's ``_surface_height`` there)."""
    from factory.demos.grasps import _line_intervals

    box = body_box(model, data, body)
    pieces = collision_pieces(model, body)
    pose = pose_matrix(data.xpos[body], data.xmat[body])
    centre = np.array([(box[0] + box[3]) / 2, (box[1] + box[4]) / 2, box[5] + 1.0])
    local = np.linalg.inv(pose) @ np.append(centre, 1.0)
    down = pose[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    t_in, t_out, _ = _line_intervals(pieces, local[None, :3], down[None])
    hit = t_in < t_out
    if not hit.any():
        return float(box[5])
    return float(centre[2] - t_in[hit].min())


# ---------------------------------------------------------------------------------------------
# Plans


@dataclass(frozen=True)
class MobileMotionConfig:
    """Parameters of the mobile task beyond the fixed arm's :class:`MotionConfig`.

    Attributes:
        arm: the arm's timing and approach distances (shared with the fixed task).
        limits: base driving limits.
        nav: base path planner parameters.
        carry_tool: tool position (m) in the base frame while driving with the object: above
            the base, pointing down.
        spawn_clearance: extra clearance of the spawn pose from inflated obstacles (m).
        spawn_tries: spawn poses drawn before ``no_spawn``.
        base_offsets: edge-to-base-centre distances of the poses beside a support (m).
        max_base_poses: poses beside a support tried per episode.
        place_depths: how far in from the support's near edge the object is put (m).
        place_lateral: sideways offsets of the place point from the base's axis (m).
        place_margin: clearance of the placed object from the support's edges (m).
        max_place_tries: place poses (point and turn) tried per episode over all base poses.
        drive_check_stride: physics steps between re-checked samples of a base trajectory.
        drive_tolerance: penetration allowed in the base re-check (m).
        settle: pause before and after each drive (s).
    """

    arm: MotionConfig = field(default_factory=MotionConfig)
    limits: BaseLimits = BASE_LIMITS
    nav: NavPlannerConfig = field(default_factory=NavPlannerConfig)
    carry_tool: tuple[float, float, float] = (0.35, 0.0, 1.05)
    spawn_clearance: float = 0.05
    spawn_tries: int = 20
    base_offsets: tuple[float, ...] = (0.55, 0.65, 0.75)
    max_base_poses: int = 6
    place_depths: tuple[float, ...] = (0.2, 0.3, 0.12, 0.4)
    place_lateral: tuple[float, ...] = (0.0, 0.1, -0.1, 0.2, -0.2)
    place_margin: float = 0.04
    max_place_tries: int = 24
    drive_check_stride: int = 25
    drive_tolerance: float = 0.02
    settle: float = 0.2


@dataclass
class MobileEpisodePlan:
    """What execution needs for one mobile episode (T physics steps).

    Attributes:
        qpos0: initial state (nq,): base at the spawn pose, arm stowed, hand closed.
        ctrl: actuator controls per physics step (T, nu): desired positions plus a velocity
            lead (``kv/kp * qd``) for the arm and the base.
        targets: the action per step (T, 11): arm joints (rad), gripper command (m; 0.08 open,
            negative squeezes), base x, y (m) and unwrapped yaw (rad), world frame.
        subtask: label id per step (T,) int8, an index into :data:`SUBTASKS`.
        subtask_done: (T,) bool, true at each sub-task's last step.
        phases: phase name -> first physics step (``navigate_to_pick``, ``reach``, ...).
        spawn, pick_base, place_base: base poses (3,) (x, y m, yaw rad).
        grasp_width: span of the chosen grasp (m).
        plan_seconds: planning time per planned motion (s).
        seconds: total planning time (s).
    """

    qpos0: np.ndarray
    ctrl: np.ndarray
    targets: np.ndarray
    subtask: np.ndarray
    subtask_done: np.ndarray
    phases: dict[str, int]
    spawn: np.ndarray
    pick_base: np.ndarray
    place_base: np.ndarray
    grasp_width: float
    plan_seconds: dict[str, float]
    seconds: float = 0.0

    @property
    def steps(self) -> int:
        """Physics steps T."""
        return len(self.ctrl)


@dataclass
class MobilePlanFailure:
    """Why an episode could not be planned.

    Attributes:
        reason: one of :data:`REASONS`.
        detail: a sentence for the log.
        seconds: planning time spent (s).
        counts: failures per reason over the candidates tried.
    """

    reason: str
    detail: str
    seconds: float
    counts: dict[str, int] = field(default_factory=dict)


@dataclass
class _Pick:
    """The arm's plan at the pick support (joint configurations (7,), paths (k, 7))."""

    reach: np.ndarray
    q_pre: np.ndarray
    q_grasp: np.ndarray
    q_lift: np.ndarray
    to_carry: np.ndarray
    q_carry: np.ndarray
    obj_in_tool: np.ndarray
    obj_rot: np.ndarray
    width: float


@dataclass
class _Place:
    """The arm's plan at the place support."""

    to_pre: np.ndarray
    q_preplace: np.ndarray
    q_place: np.ndarray
    q_retreat: np.ndarray


class _Fail(Exception):
    """Internal: a stage failed with a reason."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason


class MobilePlanner:
    """Plans the episodes of one scene for the mobile robot.

    Args:
        setup: the composed scene.
        motion: mobile task parameters.
        grasp_cfg, ik_cfg, planner_cfg: the fixed task's grasp, IK and arm planner parameters.
        max_grasps: grasp candidates tried per base pose.
        grasp_facing: preference for grasps on the side facing the arm (see
            :func:`~factory.demos.grasps.facing_order`).
    """

    def __init__(
        self,
        setup: MobileSetup,
        motion: MobileMotionConfig | None = None,
        grasp_cfg: GraspConfig | None = None,
        ik_cfg: IKConfig | None = None,
        planner_cfg: PlannerConfig | None = None,
        max_grasps: int = 8,
        grasp_facing: float = 1.0,
    ) -> None:
        self.setup = setup
        self.motion = motion or MobileMotionConfig()
        self.grasp_cfg = grasp_cfg or GraspConfig()
        self.ik = IKSolver(ik_cfg)
        self.planner_cfg = planner_cfg or PlannerConfig()
        self.max_grasps = max_grasps
        self.grasp_facing = grasp_facing
        m = setup.model
        self.model = m
        self.robot = setup.robot
        # The checkers take the fixed robot's index; the mobile index has the same fields.
        ridx = cast("RobotIndex", setup.robot)
        self._ridx = ridx
        self.checker = CollisionChecker(m, ridx, m.qpos0)
        self.drive_checker = CollisionChecker(
            m, ridx, m.qpos0, tolerance=self.motion.drive_tolerance
        )
        self.shape = GripperShape.of(m, ridx, GRIP_OPEN)
        objs = setup.objects
        self.pick_body = m.body(objs.pick.id).id
        self.pick_support_body = m.body(objs.pick_support.id).id
        self.place_support_body = m.body(objs.place_support.id).id
        jnt = int(m.body_jntadr[self.pick_body])
        if jnt < 0 or m.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
            raise MobileTaskError(f"pick object {objs.pick.id!r} is not a free body")
        self.pick_adr = int(m.jnt_qposadr[jnt])
        self.pieces = collision_pieces(m, self.pick_body)
        self.dt = float(m.opt.timestep)
        mo = self.motion.arm
        self.fast = Limits.panda(mo.speed, mo.accel, mo.jerk)
        self.slow = Limits.panda(mo.speed * mo.slow, mo.accel * mo.slow, mo.jerk * mo.slow)
        self._rng = np.random.default_rng(0)

    # ---- helpers
    def _arm_base(self, base: np.ndarray) -> np.ndarray:
        return cast(np.ndarray, base_matrix(base) @ self.setup.arm_mount)

    def _scene_state(self, qpos: np.ndarray, base: np.ndarray) -> np.ndarray:
        """``qpos`` with the base at ``base`` and the hand open (the checkers' convention)."""
        q = np.array(qpos)
        q[self.robot.base_qpos] = base
        q[self.robot.finger_qpos] = self.robot.finger_pos(GRIP_OPEN)
        return q

    def _ik(
        self, arm_base: np.ndarray, pose_world: np.ndarray, seeds: list[np.ndarray]
    ) -> np.ndarray | None:
        """IK of a world tool pose (4, 4) with the arm's base at ``arm_base`` (4, 4), accepted
        only collision-free in the scene (the checker's current state)."""
        return self.ik.solve(np.linalg.inv(arm_base) @ pose_world, seeds, accept=self.checker.valid)

    def _drive_ok(
        self, qpos: np.ndarray, traj: BaseTrajectory, q_arm: np.ndarray, stride: int
    ) -> tuple[bool, str]:
        """Re-checks a base trajectory with the arm at ``q_arm`` (and whatever the drive
        checker carries) against the scene, every ``stride`` samples and the last."""
        ck = self.drive_checker
        idx = list(range(0, len(traj.q), max(1, stride)))
        if idx[-1] != len(traj.q) - 1:
            idx.append(len(traj.q) - 1)
        for k in idx:
            ck.set_scene(self._scene_state(qpos, traj.q[k]))
            hits = ck.collisions(q_arm)
            if hits:
                return False, f"at t={traj.t[k]:.2f} s: {hits[0]}"
        return True, ""

    def _navigate(
        self,
        qpos: np.ndarray,
        start: np.ndarray,
        goal: BasePose,
        q_arm: np.ndarray,
        seed: int,
    ) -> BaseTrajectory:
        """A timed, re-checked base trajectory from ``start`` (3,) to ``goal``.

        Raises:
            _Fail: ``nav_failed`` or ``base_collision``.
        """
        mo = self.motion
        path = plan_base_path(self.setup.nav_grid, start[:2], goal.xy, mo.nav, seed)
        if not path.ok or path.path is None:
            raise _Fail(NAV_FAILED, path.detail)
        traj = base_trajectory(path.path, float(start[2]), goal.yaw, mo.limits, self.dt)
        stride = max(1, mo.drive_check_stride)
        ok, why = self._drive_ok(qpos, traj, q_arm, stride)
        if not ok:
            raise _Fail(BASE_COLLISION, why)
        return traj

    def _grasps(self, data: mujoco.MjData, arm_xy: np.ndarray) -> list[Grasp]:
        pose = pose_matrix(data.xpos[self.pick_body], data.xmat[self.pick_body])
        cands = antipodal_candidates(
            self.pieces,
            pose[:3, :3],
            self.grasp_cfg,
            self._rng,
            self.model.body_ipos[self.pick_body],
        )
        cands = facing_order(cands, pose, arm_xy, self.grasp_facing)
        back = np.eye(4)
        back[2, 3] = -self.grasp_cfg.pregrasp
        out = []
        for g in cands:
            tool = pose @ g.pose_tool_in_obj
            clear = self.grasp_cfg.clearance
            if gripper_clear(
                self.model, data, self.shape, tool, clear, self.robot.bodies
            ) and gripper_clear(
                self.model, data, self.shape, tool @ back, clear, self.robot.bodies
            ):
                out.append(g)
            if len(out) >= self.grasp_cfg.keep:
                break
        mujoco.mj_kinematics(self.model, data)
        return out

    # ---- stages
    def _plan_pick(
        self, qpos: np.ndarray, base: np.ndarray, counts: Counter[str], seed: int
    ) -> _Pick | None:
        """Grasp, IK and arm motions at the pick support with the base at ``base`` (3,)."""
        m, ck, mo = self.model, self.checker, self.motion.arm
        state = self._scene_state(qpos, base)
        ck.set_scene(state)
        ck.attach(None)
        ck.ignore_bodies([])
        if not ck.valid(STOW_QPOS):
            counts[BASE_COLLISION] += 1
            return None
        data = mujoco.MjData(m)
        data.qpos[:] = state
        mujoco.mj_kinematics(m, data)
        arm_base = self._arm_base(base)
        grasps = self._grasps(data, arm_base[:2, 3])
        if not grasps:
            counts["no_grasp"] += 1
            return None
        obj_pose = pose_matrix(data.xpos[self.pick_body], data.xmat[self.pick_body])
        carry_rot = np.diag([1.0, -1.0, -1.0])
        for g in grasps[: self.max_grasps]:
            ck.attach(None)
            ck.ignore_bodies([])
            grasp = obj_pose @ g.pose_tool_in_obj
            pre = grasp.copy()
            pre[:3, 3] -= grasp[:3, 2] * mo.pregrasp
            lift = grasp.copy()
            lift[2, 3] += mo.lift
            q_pre = self._ik(arm_base, pre, [HOME_QPOS])
            if q_pre is None:
                counts["ik_failed"] += 1
                continue
            q_grasp = self._ik(arm_base, grasp, [q_pre])
            if q_grasp is None or not ck.segment_valid(q_pre, q_grasp):
                counts["ik_failed" if q_grasp is None else "approach_collision"] += 1
                continue
            obj_in_tool = np.linalg.inv(grasp) @ obj_pose
            attach = Attachment(self.pick_body, self.pick_adr, obj_in_tool)
            ck.attach(attach)
            ck.ignore_bodies([self.pick_support_body])
            q_lift = self._ik(arm_base, lift, [q_grasp])
            if q_lift is None or not ck.segment_valid(q_grasp, q_lift):
                counts["ik_failed" if q_lift is None else "lift_collision"] += 1
                continue
            ck.ignore_bodies([])
            # Carry: the tool above the base pointing down, the hand turned as at the grasp.
            x_in_base = (np.linalg.inv(base_matrix(base)) @ grasp)[:3, 0]
            yaw = math.atan2(x_in_base[1], x_in_base[0])
            carry = base_matrix(base) @ pose_matrix(
                np.array(self.motion.carry_tool), rot_z(yaw) @ carry_rot
            )
            q_carry = self._ik(arm_base, carry, [q_lift, STOW_QPOS])
            if q_carry is None:
                counts["ik_failed"] += 1
                continue
            to_carry = plan(ck, q_lift, q_carry, self.planner_cfg, seed + 1)
            ck.attach(None)
            if to_carry.path is None:
                counts["plan_failed"] += 1
                continue
            reach = plan(ck, STOW_QPOS, q_pre, self.planner_cfg, seed)
            if reach.path is None:
                counts["plan_failed"] += 1
                continue
            self._seconds["reach"] = reach.seconds
            self._seconds["to_carry"] = to_carry.seconds
            return _Pick(
                reach.path,
                q_pre,
                q_grasp,
                q_lift,
                to_carry.path,
                q_carry,
                obj_in_tool,
                obj_pose[:3, :3],
                g.width,
            )
        return None

    def _place_points(self, pose: BasePose, box: np.ndarray) -> list[np.ndarray]:
        """Candidate object positions (2,) on the support's top in front of a base pose."""
        mo = self.motion
        r = 0.5 * math.hypot(
            self.setup.objects.pick.dimensions.width, self.setup.objects.pick.dimensions.length
        )
        fwd = np.array([math.cos(pose.yaw), math.sin(pose.yaw)])
        side = np.array([-fwd[1], fwd[0]])
        lo = box[:2] + r + mo.place_margin
        hi = box[3:5] - r - mo.place_margin
        out = []
        for depth in mo.place_depths:
            for lat in mo.place_lateral:
                xy = pose.xy + fwd * (pose.offset + depth) + side * lat
                if (xy >= lo).all() and (xy <= hi).all():
                    out.append(xy)
        return out

    def _plan_place(
        self,
        qpos: np.ndarray,
        pose: BasePose,
        base: np.ndarray,
        pick: _Pick,
        top: float,
        box: np.ndarray,
        counts: Counter[str],
        seed: int,
    ) -> _Place | None:
        """IK and arm motions that put the carried object on the place support's top."""
        ck, mo = self.checker, self.motion.arm
        arm_base = self._arm_base(base)
        ck.set_scene(self._scene_state(qpos, base))
        attach = Attachment(self.pick_body, self.pick_adr, pick.obj_in_tool)
        points = self._place_points(pose, box)
        if not points:
            counts[NO_PLACE_SUPPORT] += 1
            return None
        for xy in points:
            for turn in (0.0, np.pi / 2, -np.pi / 2, np.pi):
                if self._place_tries >= self.motion.max_place_tries:
                    return None
                self._place_tries += 1
                ck.attach(attach)
                ck.ignore_bodies([])
                obj = np.eye(4)
                obj[:3, :3] = rot_z(turn) @ pick.obj_rot
                obj[:2, 3] = xy
                obj[2, 3] = top + mo.place_drop
                place = obj @ np.linalg.inv(pick.obj_in_tool)
                preplace = place.copy()
                preplace[2, 3] += mo.preplace
                q_pre = self._ik(arm_base, preplace, [pick.q_carry])
                if q_pre is None:
                    counts["ik_failed"] += 1
                    continue
                q_place = self._ik(arm_base, place, [q_pre])
                if q_place is None or not ck.segment_valid(q_pre, q_place):
                    counts["ik_failed"] += 1
                    continue
                retreat = place.copy()
                retreat[:3, 3] -= place[:3, 2] * mo.pregrasp
                ck.attach(None)
                ck.ignore_bodies([self.pick_body])
                q_ret = self._ik(arm_base, retreat, [q_place])
                if q_ret is None or not ck.segment_valid(q_place, q_ret):
                    counts["ik_failed" if q_ret is None else "retreat_collision"] += 1
                    continue
                ck.ignore_bodies([])
                ck.attach(attach)
                to_pre = plan(ck, pick.q_carry, q_pre, self.planner_cfg, seed + 2)
                ck.attach(None)
                self._seconds["to_place"] = to_pre.seconds
                if to_pre.path is None:
                    counts["plan_failed"] += 1
                    continue
                return _Place(to_pre.path, q_pre, q_place, q_ret)
        return None

    def plan_episode(self, seed: int) -> MobileEpisodePlan | MobilePlanFailure:
        """Plans one episode (deterministic in ``seed``): see the module docstring."""
        t0 = time.perf_counter()
        self._rng = np.random.default_rng(seed)
        self._seconds: dict[str, float] = {}
        self._place_tries = 0
        counts: Counter[str] = Counter()
        try:
            plan_ = self._plan(seed, counts)
        except _Fail as f:
            counts[f.reason] += 1
            return MobilePlanFailure(f.reason, str(f), time.perf_counter() - t0, dict(counts))
        plan_.seconds = time.perf_counter() - t0
        return plan_

    def _plan(self, seed: int, counts: Counter[str]) -> MobileEpisodePlan:
        m, robot, mo, setup = self.model, self.robot, self.motion, self.setup
        rng = self._rng
        ompl_seed = int(rng.integers(2**31 - 1))
        qpos = np.array(m.qpos0)
        qpos[robot.qpos] = STOW_QPOS
        qpos[robot.finger_qpos] = robot.finger_pos(STOW_FINGERS)
        data = mujoco.MjData(m)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        grid = setup.nav_grid
        pick_box = body_box(m, data, self.pick_support_body)
        place_box = body_box(m, data, self.place_support_body)
        place_top = support_top(m, data, self.place_support_body)
        pick_xy = np.array(data.xpos[self.pick_body][:2])

        # (a) spawn
        spawn: np.ndarray | None = None
        self.drive_checker.attach(None)
        self.drive_checker.ignore_bodies([])
        for _ in range(mo.spawn_tries):
            try:
                p = random_free_pose(grid, rng, min_clearance=mo.spawn_clearance)
            except NavError as e:
                raise _Fail(NO_SPAWN, str(e)) from None
            self.drive_checker.set_scene(self._scene_state(qpos, p.as_array()))
            if not self.drive_checker.collisions(STOW_QPOS):
                spawn = p.as_array()
                break
        if spawn is None:
            raise _Fail(NO_SPAWN, f"no collision-free spawn pose in {mo.spawn_tries} draws")
        qpos[robot.base_qpos] = spawn

        # (b, c) navigate to a pose beside the pick support, pick there
        beside = base_pose_beside(
            grid, _xy_box(pick_box), spawn[:2], pick_xy, offsets=mo.base_offsets
        )
        if not beside:
            raise _Fail(
                NAV_FAILED, f"no reachable base pose beside {setup.objects.pick_support.id!r}"
            )
        nav1 = pick = None
        pick_pose: BasePose | None = None
        for pose in beside[: mo.max_base_poses]:
            try:
                traj = self._navigate(qpos, spawn, pose, STOW_QPOS, ompl_seed)
            except _Fail as f:
                counts[f.reason] += 1
                log.debug("pick pose %s: %s", pose, f)
                continue
            base = traj.q[-1]
            pick = self._plan_pick(qpos, base, counts, ompl_seed)
            if pick is not None:
                nav1, pick_pose = traj, pose
                break
        if nav1 is None or pick is None or pick_pose is None:
            raise _Fail(
                _worst(counts),
                f"no pick from {len(beside[: mo.max_base_poses])} poses: {dict(counts)}",
            )
        pick_base = nav1.q[-1]

        # (d, e) carry to a pose beside the place support, place there
        beside = base_pose_beside(
            grid, _xy_box(place_box), pick_base[:2], None, offsets=mo.base_offsets
        )
        if not beside:
            raise _Fail(
                NAV_FAILED, f"no reachable base pose beside {setup.objects.place_support.id!r}"
            )
        # The drive is checked with the object in the hand (its pose taken in the carry pose).
        self.drive_checker.attach(Attachment(self.pick_body, self.pick_adr, pick.obj_in_tool))
        counts2: Counter[str] = Counter()
        nav2 = place = None
        try:
            for pose in beside[: mo.max_base_poses]:
                try:
                    traj = self._navigate(qpos, pick_base, pose, pick.q_carry, ompl_seed + 3)
                except _Fail as f:
                    counts2[f.reason] += 1
                    continue
                place = self._plan_place(
                    qpos, pose, traj.q[-1], pick, place_top, place_box, counts2, ompl_seed
                )
                if place is not None:
                    nav2 = traj
                    break
        finally:
            self.drive_checker.attach(None)
        if nav2 is None or place is None:
            counts.update(counts2)
            raise _Fail(
                _worst(counts2), f"no place from the poses beside the support: {dict(counts2)}"
            )
        return self._timeline(qpos, spawn, nav1, pick, nav2, place)

    # ---- timing
    def _timeline(
        self,
        qpos: np.ndarray,
        spawn: np.ndarray,
        nav1: BaseTrajectory,
        pick: _Pick,
        nav2: BaseTrajectory,
        place: _Place,
    ) -> MobileEpisodePlan:
        mo, dt = self.motion.arm, self.dt
        arm: list[np.ndarray] = []
        arm_v: list[np.ndarray] = []
        grip: list[float] = []
        base: list[np.ndarray] = []
        base_v: list[np.ndarray] = []
        label: list[int] = []
        phases: dict[str, int] = {}
        cur_base = [np.asarray(spawn, float)]  # the base's rest pose (3,), as the drives end
        cur_sub = [0]  # the current sub-task id

        def hold(name: str, q: np.ndarray, secs: float, opening: float) -> None:
            phases[name] = len(arm)
            n = max(1, round(secs / dt))
            arm.extend([q] * n)
            arm_v.extend([np.zeros(7)] * n)
            grip.extend([opening] * n)
            base.extend(cur_base * n)
            base_v.extend([np.zeros(3)] * n)
            label.extend(cur_sub * n)

        def move(name: str, path: np.ndarray, limits: Limits, opening: float) -> None:
            phases[name] = len(arm)
            timed = time_path(path, limits, dt)
            n = len(timed.q) - 1
            arm.extend(list(timed.q[1:]))
            arm_v.extend(list(timed.qd[1:]))
            grip.extend([opening] * n)
            base.extend(cur_base * n)
            base_v.extend([np.zeros(3)] * n)
            label.extend(cur_sub * n)

        def drive(name: str, traj: BaseTrajectory, q: np.ndarray, opening: float) -> None:
            phases[name] = len(arm)
            n = len(traj.q) - 1
            arm.extend([q] * n)
            arm_v.extend([np.zeros(7)] * n)
            grip.extend([opening] * n)
            base.extend(list(traj.q[1:]))
            base_v.extend(list(traj.qd[1:]))
            label.extend(cur_sub * n)
            cur_base[0] = np.array(traj.q[-1])

        settle = self.motion.settle
        cur_sub[0] = 0
        hold("navigate_to_pick", STOW_QPOS, settle, STOW_FINGERS)
        drive("drive_to_pick", nav1, STOW_QPOS, STOW_FINGERS)
        hold("arrive_pick", STOW_QPOS, settle, STOW_FINGERS)
        cur_sub[0] = 1
        move("reach", pick.reach, self.fast, GRIP_OPEN)
        move("approach", np.stack([pick.q_pre, pick.q_grasp]), self.slow, GRIP_OPEN)
        hold("close", pick.q_grasp, mo.close, GRIP_CLOSED)
        move("lift", np.stack([pick.q_grasp, pick.q_lift]), self.slow, GRIP_CLOSED)
        move("to_carry", pick.to_carry, self.fast, GRIP_CLOSED)
        cur_sub[0] = 2
        hold("navigate_to_place", pick.q_carry, settle, GRIP_CLOSED)
        drive("drive_to_place", nav2, pick.q_carry, GRIP_CLOSED)
        hold("arrive_place", pick.q_carry, settle, GRIP_CLOSED)
        cur_sub[0] = 3
        move("to_place", place.to_pre, self.fast, GRIP_CLOSED)
        move("lower", np.stack([place.q_preplace, place.q_place]), self.slow, GRIP_CLOSED)
        hold("release", place.q_place, mo.release, GRIP_OPEN)
        move("retreat", np.stack([place.q_place, place.q_retreat]), self.slow, GRIP_OPEN)
        hold("hold", place.q_retreat, mo.hold, GRIP_OPEN)
        phases["end"] = len(arm)

        m, robot = self.model, self.robot
        arm_a, base_a = np.asarray(arm), np.asarray(base)
        ctrl = targets_to_ctrl(m, self._ridx, arm_a, np.asarray(arm_v), grip)
        cb = robot.ctrl_base
        lead = -m.actuator_biasprm[cb, 2] / m.actuator_gainprm[cb, 0]
        ctrl[:, cb] = base_a + lead * np.asarray(base_v)
        targets = np.concatenate([arm_a, np.asarray(grip)[:, None], base_a], axis=1)
        sub = np.asarray(label, np.int8)
        done = np.zeros(len(sub), bool)
        done[:-1] = sub[1:] != sub[:-1]
        done[-1] = True
        q0 = np.array(qpos)
        q0[robot.base_qpos] = spawn
        return MobileEpisodePlan(
            qpos0=q0,
            ctrl=ctrl,
            targets=targets,
            subtask=sub,
            subtask_done=done,
            phases=phases,
            spawn=np.asarray(spawn, float),
            pick_base=np.array(nav1.q[-1]),
            place_base=np.array(nav2.q[-1]),
            grasp_width=pick.width,
            plan_seconds=dict(self._seconds),
        )


def _xy_box(box: np.ndarray) -> tuple[float, float, float, float]:
    return float(box[0]), float(box[1]), float(box[3]), float(box[4])


_PRIORITY = (NO_PLACE_SUPPORT, NAV_FAILED, BASE_COLLISION)


def _worst(counts: Counter[str]) -> str:
    """The reason reported for a stage whose candidates all failed: navigation first (it
    says the route or the goal is the problem), else the most common arm reason."""
    for r in _PRIORITY:
        if counts.get(r) and all(counts[r] >= v for k, v in counts.items() if k in _PRIORITY):
            return r
    return counts.most_common(1)[0][0] if counts else "plan_failed"


# ---------------------------------------------------------------------------------------------
# Execution and recording


@dataclass(frozen=True)
class MobileRecordConfig:
    """What a mobile episode records.

    Attributes:
        fps: frames per second (Hz).
        width, height: pinhole image size (px); the fisheye images are ``width`` square.
        cameras: recording cameras, from :data:`ALL_CAMERAS`.
        depth: ``uint16_mm`` (millimetres) or ``float32`` (metres); pinhole depth is along the
            optical axis, fisheye depth is the ray length.
        render: render images (off: states and signals only).
        fisheye_fov_deg: full field of view of the fisheye cameras (deg).
    """

    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: tuple[str, ...] = ALL_CAMERAS
    depth: str = "uint16_mm"
    render: bool = True
    fisheye_fov_deg: float = 180.0

    def __post_init__(self) -> None:
        unknown = [c for c in self.cameras if c not in ALL_CAMERAS]
        if unknown:
            raise MobileTaskError(f"unknown camera(s) {unknown}: choose from {ALL_CAMERAS}")
        if self.depth not in ("uint16_mm", "float32"):
            raise MobileTaskError(f"depth must be uint16_mm or float32, got {self.depth!r}")


@dataclass
class MobileRecording:
    """One executed mobile episode (F frames) and its outcome.

    Attributes:
        time: (F,) s. state: (F, nstate) MuJoCo integration state (``mj_setState`` with
            ``mjSTATE_INTEGRATION`` reproduces the frame).
        base_pose: (F, 3) base x, y (m) and unwrapped yaw (rad), world frame.
        joint_pos: (F, 7) arm joints (rad). gripper: (F, 1) finger opening (m).
        ee_pose: (F, 7) tool site position (m) + quaternion wxyz, world frame.
        action: (F, 11) targets at the end of the frame: arm (7, rad), gripper (m), base x, y
            (m), yaw (rad).
        subtask: (F,) int8 label id (index into :data:`SUBTASKS`) of the frame's period.
        subtask_done: (F,) bool: true on the last frame of each sub-task.
        rgb: camera -> (F, H, W, 3) uint8; depth: camera -> (F, H, W) uint16 mm or float32 m.
        ctrl: (S, nu) the controls of every physics step simulated (S = (F - 1) x steps per
            frame): replaying them from ``state[0]`` reproduces the episode.
        outcome: the success check.
        max_base_penetration, max_arm_penetration: deepest contact of the base / the arm and
            hand with the scene over every physics step (m).
        sim_seconds, render_seconds: wall time (s).
    """

    time: np.ndarray
    state: np.ndarray
    base_pose: np.ndarray
    joint_pos: np.ndarray
    gripper: np.ndarray
    ee_pose: np.ndarray
    action: np.ndarray
    subtask: np.ndarray
    subtask_done: np.ndarray
    rgb: dict[str, np.ndarray] = field(default_factory=dict)
    depth: dict[str, np.ndarray] = field(default_factory=dict)
    ctrl: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    outcome: Outcome | None = None
    max_base_penetration: float = 0.0
    max_arm_penetration: float = 0.0
    sim_seconds: float = 0.0
    render_seconds: float = 0.0


class MobileRenderer:
    """Renders the mobile robot's recording cameras: the pinhole ones (``left``, ``right``,
    ``wrist``) side by side in one GL pass, RGB and depth read together (as
    :class:`factory.demos.execute.FrameRenderer`), and the fisheye ones through
    :class:`factory.sim.fisheye.FisheyeRenderer` (its own GL context).
    """

    def __init__(self, model: mujoco.MjModel, cfg: MobileRecordConfig) -> None:
        from factory.sim.fisheye import FisheyeRenderer, FisheyeSpec
        from factory.sim.gl import configure_gl

        configure_gl("auto")
        self.cfg = cfg
        self.pinhole = [c for c in cfg.cameras if c in CAMERAS]
        self.fisheye = [c for c in cfg.cameras if c in FISHEYE_CAMERAS]
        self.renderer: mujoco.Renderer | None = None
        self.fish: FisheyeRenderer | None = None
        n, w, h = len(self.pinhole), cfg.width, cfg.height
        if n:
            vis = model.vis
            vis.quality.offsamples = 0
            vis.global_.offwidth = max(vis.global_.offwidth, n * w)
            vis.global_.offheight = max(vis.global_.offheight, h)
            self.renderer = mujoco.Renderer(model, h, n * w)
            flags = self.renderer.scene.flags
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
            self.option = mujoco.MjvOption()
            self.option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
            self.option.sitegroup[:] = 0
            self.cams = [model.camera(CAMERAS[c]).id for c in self.pinhole]
            self._rgb = np.empty((h, n * w, 3), np.uint8)
            self._z = np.empty((h, n * w), np.float32)
            self._rect = mujoco.MjrRect(0, 0, n * w, h)
            extent = model.stat.extent
            self._near = np.float32(model.vis.map.znear * extent)
            self._far = np.float32(model.vis.map.zfar * extent)
        if self.fisheye:
            spec = FisheyeSpec(resolution=cfg.width, fov_deg=cfg.fisheye_fov_deg)
            self.fish = FisheyeRenderer(model, spec)
            self.fish_ids = {c: model.camera(FISHEYE_CAMERAS[c]).id for c in self.fisheye}

    def _metric(self, z: np.ndarray) -> np.ndarray:
        near, far = self._near, self._far
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        c = np.float32(-0.5) * c - np.float32(0.5)
        d = np.float32(-0.5) * d
        return (d / (z.astype(np.float64) + c)).astype(np.float32)

    def _depth(self, depth: np.ndarray) -> np.ndarray:
        if self.cfg.depth == "uint16_mm":
            return np.clip(np.round(depth * 1000.0), 0, 65535).astype(np.uint16)
        return depth.astype(np.float32)

    def render(self, data: mujoco.MjData) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB (H, W, 3) uint8, depth (H, W)) of the state in ``data`` (current
        kinematics needed)."""
        out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        r = self.renderer
        if r is not None:
            r._gl_context.make_current()
            ctx = r._mjr_context
            w, h = self.cfg.width, self.cfg.height
            for k, cam in enumerate(self.cams):
                r.update_scene(data, camera=cam, scene_option=self.option)
                mujoco.mjr_render(mujoco.MjrRect(k * w, 0, w, h), r.scene, ctx)
            mujoco.mjr_readPixels(self._rgb, self._z, self._rect, ctx)
            rgb = np.flipud(self._rgb)
            depth = self._depth(self._metric(np.flipud(self._z)))
            for k, c in enumerate(self.pinhole):
                out[c] = (rgb[:, k * w : (k + 1) * w].copy(), depth[:, k * w : (k + 1) * w].copy())
        if self.fish is not None:
            for c in self.fisheye:
                im, dp = self.fish.render(data, self.fish_ids[c])
                out[c] = (im, self._depth(dp))
        return out

    def close(self) -> None:
        """Frees the GL contexts."""
        if self.renderer is not None:
            self.renderer.close()
        if self.fish is not None:
            self.fish.close()


STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


def _penetrations(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    base_geom: np.ndarray,
    arm_geom: np.ndarray,
    arm_allowed: np.ndarray,
    base_allowed: np.ndarray,
) -> tuple[float, float]:
    """Deepest contact of a base geom and of an arm/hand geom with a scene geom (m)."""
    worst_base = worst_arm = 0.0
    robot = base_geom | arm_geom
    for c in data.contact[: data.ncon]:
        g1, g2 = int(c.geom[0]), int(c.geom[1])
        if robot[g1] == robot[g2]:
            continue
        rg, other = (g1, g2) if robot[g1] else (g2, g1)
        depth = -float(c.dist)
        if base_geom[rg] and not base_allowed[other]:
            worst_base = max(worst_base, depth)
        elif arm_geom[rg] and not arm_allowed[other]:
            worst_arm = max(worst_arm, depth)
    return worst_base, worst_arm


def simulate(
    setup: MobileSetup,
    state0: np.ndarray,
    ctrl: np.ndarray,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
    targets: np.ndarray | None = None,
    subtask: np.ndarray | None = None,
) -> MobileRecording:
    """Runs per-step controls from an integration state and records frames at ``cfg.fps``.

    Frame ``f`` is the state after ``f * k`` physics steps (``k`` steps per frame); each frame
    is recorded from a separate ``MjData`` (``mj_setState`` + ``mj_forward``), so the
    simulation is the same whether or not it is recorded, and a replay from ``state0`` with
    the same ``ctrl`` reproduces the states and images exactly.

    Args:
        setup: the composed scene.
        state0: initial integration state (nstate,).
        ctrl: controls per physics step (S, nu); S should be a multiple of the steps per frame.
        cfg: what to record.
        renderer: a renderer to reuse (made if None and ``cfg.render``).
        targets, subtask: per-step action (S, 11) and sub-task labels (S,); when given,
            recorded per frame: the action at the frame period's last step, the label at its
            first, and the done flag on the last frame of each sub-task.

    Returns:
        the recording, without outcome.
    """
    model, robot = setup.model, setup.robot
    dt = float(model.opt.timestep)
    k = max(1, round(1.0 / (cfg.fps * dt)))
    n_steps = len(ctrl)
    n_frames = math.ceil(n_steps / k) + 1
    total = (n_frames - 1) * k
    if total > n_steps:
        ctrl = np.concatenate([ctrl, np.repeat(ctrl[-1:], total - n_steps, axis=0)])
    nstate = mujoco.mj_stateSize(model, STATE_SPEC)
    depth_type = np.uint16 if cfg.depth == "uint16_mm" else np.float32
    rec = MobileRecording(
        time=np.arange(n_frames) / cfg.fps,
        state=np.zeros((n_frames, nstate)),
        base_pose=np.zeros((n_frames, 3)),
        joint_pos=np.zeros((n_frames, 7)),
        gripper=np.zeros((n_frames, 1)),
        ee_pose=np.zeros((n_frames, 7)),
        action=np.zeros((n_frames, 11)),
        subtask=np.zeros(n_frames, np.int8),
        subtask_done=np.zeros(n_frames, bool),
        ctrl=np.array(ctrl),
    )
    if cfg.render:
        for c in cfg.cameras:
            side = (cfg.width, cfg.width) if c in FISHEYE_CAMERAS else (cfg.height, cfg.width)
            rec.rgb[c] = np.zeros((n_frames, *side, 3), np.uint8)
            rec.depth[c] = np.zeros((n_frames, *side), depth_type)
    own = renderer
    if own is None and cfg.render:
        own = MobileRenderer(model, cfg)
    data = mujoco.MjData(model)
    view = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state0, STATE_SPEC)
    base_geom = np.zeros(model.ngeom, bool)
    base_geom[robot.base_geoms] = True
    arm_geom = np.zeros(model.ngeom, bool)
    arm_geom[robot.geoms] = True
    arm_geom &= ~base_geom
    objs = setup.objects
    pick = model.body(objs.pick.id).id
    supports = [model.body(objs.pick_support.id).id, model.body(objs.place_support.id).id]
    base_allowed = np.isin(model.geom_bodyid, [pick])
    arm_allowed = np.isin(model.geom_bodyid, [pick, *supports])
    worst_b = worst_a = 0.0
    sim_s = render_s = 0.0

    def record(f: int) -> None:
        mujoco.mj_getState(model, data, rec.state[f], STATE_SPEC)
        mujoco.mj_setState(model, view, rec.state[f], STATE_SPEC)
        mujoco.mj_forward(model, view)
        rec.base_pose[f] = view.qpos[robot.base_qpos]
        rec.joint_pos[f] = view.qpos[robot.qpos]
        fingers = view.qpos[robot.finger_qpos]
        rec.gripper[f, 0] = float(fingers[0] - fingers[1])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, view.site_xmat[robot.site])
        rec.ee_pose[f] = np.concatenate([view.site_xpos[robot.site], quat])
        last = min((f + 1) * k, n_steps) - 1
        if targets is not None:
            rec.action[f] = targets[last]
        if subtask is not None:
            first = min(f * k, n_steps - 1)
            rec.subtask[f] = subtask[first]
        if own is not None:
            for c, (im, dp) in own.render(view).items():
                rec.rgb[c][f] = im
                rec.depth[c][f] = dp

    t0 = time.perf_counter()
    record(0)
    render_s += time.perf_counter() - t0
    for f in range(1, n_frames):
        t0 = time.perf_counter()
        for s in range((f - 1) * k, f * k):
            data.ctrl[:] = ctrl[s]
            mujoco.mj_step(model, data)
            if data.ncon:
                b, a = _penetrations(model, data, base_geom, arm_geom, arm_allowed, base_allowed)
                worst_b, worst_a = max(worst_b, b), max(worst_a, a)
        t1 = time.perf_counter()
        record(f)
        sim_s += t1 - t0
        render_s += time.perf_counter() - t1
    if renderer is None and own is not None:
        own.close()
    if subtask is not None:
        rec.subtask_done[:-1] = rec.subtask[1:] != rec.subtask[:-1]
        rec.subtask_done[-1] = True
    rec.max_base_penetration = worst_b
    rec.max_arm_penetration = worst_a
    rec.sim_seconds, rec.render_seconds = sim_s, render_s
    return rec


def check_mobile_success(
    setup: MobileSetup,
    rec: MobileRecording,
    plan: MobileEpisodePlan,
    fps: float,
    settle_tol: float = 0.005,
    speed_tol: float = 0.02,
    above_tol: float = 0.03,
    penetration_tol: float = 0.02,
) -> Outcome:
    """Whether an executed mobile episode succeeded.

    The object rose with the hand during ``pick`` (else ``slip``), its bottom ends within
    ``above_tol`` (m) above the place support's top and its centre inside the support's
    footprint (else ``not_on_target``), no finger touches it (``not_released``), it moved less
    than ``settle_tol`` (m) over the last 0.5 s and its speed is below ``speed_tol`` (m/s)
    (``unstable``); the base never pressed more than ``penetration_tol`` (m) into the scene
    (``base_collision``) nor the arm or hand into anything but the task objects (``collision``).
    """
    model, robot = setup.model, setup.robot
    objs = setup.objects
    qs = slice(1, 1 + model.nq)
    vs = slice(1 + model.nq, 1 + model.nq + model.nv)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, rec.state[-1], STATE_SPEC)
    mujoco.mj_forward(model, data)
    pick = model.body(objs.pick.id).id
    support = model.body(objs.place_support.id).id
    adr = int(model.jnt_qposadr[model.body_jntadr[pick]])
    dof = int(model.jnt_dofadr[model.body_jntadr[pick]])
    obj_box = body_box(model, data, pick)
    sup_box = body_box(model, data, support)
    top = support_top(model, data, support)
    centre = data.xipos[pick]
    # the support's footprint: its top's rectangle in its own frame (scene dimensions)
    sup = objs.place_support
    local = data.xmat[support].reshape(3, 3).T @ (centre - data.xpos[support])
    inside = bool(
        abs(local[0]) <= sup.dimensions.width / 2 and abs(local[1]) <= sup.dimensions.length / 2
    ) and bool((centre[:2] >= sup_box[:2]).all() and (centre[:2] <= sup_box[3:5]).all())
    hold = max(1, round(0.5 * fps))
    q_end = rec.state[-1, qs]
    q_before = rec.state[max(0, len(rec.state) - 1 - hold), qs]
    moved = float(np.linalg.norm(q_end[adr : adr + 3] - q_before[adr : adr + 3]))
    speed = float(np.linalg.norm(rec.state[-1, vs][dof : dof + 3]))
    dt = float(model.opt.timestep)
    k = max(1, round(1.0 / (fps * dt)))
    start_z = float(rec.state[0, qs][adr + 2])
    lift_frame = min(len(rec.state) - 1, plan.phases["navigate_to_place"] // k)
    lifted = float(rec.state[lift_frame, qs][adr + 2]) - start_z
    touching = False
    for c in data.contact[: data.ncon]:
        bodies = [int(model.geom_bodyid[c.geom[0]]), int(model.geom_bodyid[c.geom[1]])]
        if pick in bodies and np.isin(bodies, robot.bodies).any():
            touching = True
    bottom = float(obj_box[2])
    details = {
        "lift_m": lifted,
        "bottom_above_top_m": bottom - top,
        "support_top_m": top,
        "inside_footprint": float(inside),
        "settle_motion_m": moved,
        "final_speed_m_s": speed,
        "base_penetration_m": rec.max_base_penetration,
        "robot_penetration_m": rec.max_arm_penetration,
    }
    if rec.max_base_penetration > penetration_tol:
        return Outcome(False, BASE_COLLISION, details)
    if rec.max_arm_penetration > penetration_tol:
        return Outcome(False, COLLISION, details)
    if lifted < 0.03:
        return Outcome(False, "slip", details)
    if not inside or not (-0.01 <= bottom - top <= above_tol):
        return Outcome(False, "not_on_target", details)
    if touching:
        return Outcome(False, "not_released", details)
    if moved > settle_tol or speed > speed_tol:
        return Outcome(False, "unstable", details)
    return Outcome(True, "", details)


def execute_mobile(
    setup: MobileSetup,
    plan: MobileEpisodePlan,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
) -> MobileRecording:
    """Simulates a planned episode on the CPU, records it and checks success.

    Args:
        setup: the composed scene.
        plan: the planned episode.
        cfg: what to record.
        renderer: a renderer to reuse.

    Returns:
        the recording with its ``outcome``.
    """
    model = setup.model
    data = mujoco.MjData(model)
    data.qpos[:] = plan.qpos0
    data.ctrl[:] = plan.ctrl[0]
    mujoco.mj_forward(model, data)
    state0 = np.zeros(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, state0, STATE_SPEC)
    rec = simulate(
        setup,
        state0,
        plan.ctrl,
        cfg,
        renderer,
        targets=plan.targets,
        subtask=plan.subtask,
    )
    rec.outcome = check_mobile_success(setup, rec, plan, cfg.fps)
    return rec


def replay(
    setup: MobileSetup,
    rec: MobileRecording,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
) -> MobileRecording:
    """Re-simulates a recording from its first state with its recorded controls (same frames,
    same images on the same machine)."""
    return simulate(setup, rec.state[0], rec.ctrl, cfg, renderer)
