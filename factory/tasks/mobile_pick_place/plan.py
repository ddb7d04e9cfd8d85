"""Planning a mobile pick-and-place episode: spawn, drive, pick, carry, place.

:class:`MobilePlanner` plans the episodes of one scene
(:class:`~factory.tasks.mobile_pick_place.scene.MobileSetup`), each deterministic in its seed in a
fresh process (OMPL's generator is seeded once per process):

1. spawns the base at a random free pose from which the route's lattice reaches a verified
   pick pose (:meth:`factory.nav.route.TaskRoute.random_spawn`: a region of the stowed
   base's SE(2) lattice), arm stowed, hand closed;
2. ``navigate_to_pick``: base poses within reach of the object
   (:func:`~factory.tasks.mobile_pick_place.scene.task_work_poses`, all sides of the support and
   facing the object from every direction), of them only those the route check verified
   (``MobileSetup.route``, :class:`factory.nav.route.TaskRoute`: a place pose shares their region of
   the carrying base's free poses) in the spawn's region of the stowed base's free poses
   (:meth:`~factory.nav.route.TaskRoute.picks_from`), an SE(2) path for the base's footprint
   (:func:`factory.nav.plan_se2_path`), timed with ruckig under
   :data:`~factory.robots.mobile_panda.BASE_LIMITS`, re-checked with the robot's real shape;
3. ``pick``: the fixed-base machinery with the arm's base frame at the mobile arm mount: antipodal
   grasps ranked for carrying (:func:`carry_order`), mink IK (:class:`factory.robots.ik.IKSolver`,
   on the fixed robot alone in its link0 frame, here mapped through the mount pose), OMPL RRTConnect
   arm motions checked in the scene (:mod:`factory.demos.plan.planner`), ruckig timing
   (:mod:`factory.demos.plan.timing`); then the arm folds into a carry pose;
4. ``navigate_to_place``: as 2, to a pose within reach of the place support's top that the
   route verified in the region of the pick pose reached, with the footprint lengthened by
   the object and the object in the hand in the re-check;
5. ``place``: the object upright on the place support's top, released, the hand retreats.

Every candidate loop is bounded and the whole episode by ``MobileMotionConfig.plan_budget``
seconds (reason ``plan_timeout``). Everything is timed into per-physics-step control targets:
7 arm joints, the gripper and the base (x, y, yaw), with a sub-task label per step and a done
flag at each sub-task's last step.

Frames: world frame for poses (m, rad); the base pose is the footprint centre's (x, y) and the
unwrapped yaw (the base joints' values); tool site +z is the approach, +x the closing axis.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import mujoco
import numpy as np

from factory.demos.plan.grasps import (
    Grasp,
    GraspConfig,
    GripperShape,
    antipodal_candidates,
    collision_pieces,
    facing_order,
    gripper_clear,
)
from factory.demos.plan.planner import Attachment, CollisionChecker, PlannerConfig, plan
from factory.demos.plan.timing import Limits, time_path
from factory.nav import (
    BASE_COLLISION,
    NAV_FAILED,
    BaseLimits,
    BasePose,
    BaseTrajectory,
    Footprint,
    NavError,
    NavPlannerConfig,
    plan_se2_path,
    time_base_path,
)
from factory.nav.route import TaskRoute, task_route
from factory.robots.ik import IKConfig, IKSolver
from factory.robots.mobile_panda import (
    BASE_LIMITS,
    HAND_GEOM,
    STOW_FINGERS,
    STOW_QPOS,
)
from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN, HOME_QPOS, pose_matrix, rot_z
from factory.tasks.mobile_pick_place.scene import (
    ARM_X,
    CARRY_TOOL,
    NO_PLACE_SUPPORT,
    NO_SPAWN,
    PLAN_TIMEOUT,
    MobileSetup,
    MobileTaskError,
    SupportTop,
    base_matrix,
    body_box,
    carry_footprint,
    object_radius,
    support_top,
    task_work_poses,
)
from factory.tasks.pick_place.plan import MotionConfig, targets_to_ctrl

if TYPE_CHECKING:
    from factory.robots.panda import RobotIndex

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MobileMotionConfig:
    """Parameters of the mobile task beyond the fixed arm's :class:`MotionConfig`.

    Attributes:
        arm: the arm's timing and approach distances (shared with the fixed task).
        limits: base driving limits.
        nav: base path planner parameters (per drive query).
        carry_tool: tool position (m) in the base frame while driving with the object: above
            the base, pointing down.
        spawn_tries: spawn poses drawn before ``no_spawn``.
        max_base_poses: base poses tried per support and episode (each a drive and an arm
            plan).
        place_reach: distances (m) from the arm's base, straight ahead, of the place points
            tried, in order.
        place_lateral: sideways offsets of the place point (m).
        place_margin: clearance of the placed object from the support's edges (m).
        max_place_tries: place poses (point and turn) tried per episode over all base poses.
        drive_check_stride: physics steps between re-checked samples of a base trajectory.
        drive_tolerance: penetration allowed in the base re-check (m).
        settle: pause before and after each drive (s).
        hold_weight: preference for grasps that hold the object near its centre of mass
            (:func:`carry_order`; 0: the fixed task's ranking).
        rim: grasps whose contacts lie within this distance (m) of the object's top are tried
            last: the pads then hold a rim or lip, the object swings and slips during the
            carry, and the lip catches on a finger when the hand opens and retreats.
        palm_gap: among the others, grasps that leave at least this gap (m) between the palm
            and the object come first: an object that shifts into the palm during the carry
            can stay wedged against a finger when the hand opens.
        plan_budget: planning time per episode (s); past it the episode fails with
            ``plan_timeout``.
    """

    arm: MotionConfig = field(default_factory=MotionConfig)
    limits: BaseLimits = BASE_LIMITS
    nav: NavPlannerConfig = field(default_factory=NavPlannerConfig)
    carry_tool: tuple[float, float, float] = CARRY_TOOL
    spawn_tries: int = 20
    max_base_poses: int = 6
    place_reach: tuple[float, ...] = (0.5, 0.4, 0.6, 0.3, 0.7)
    place_lateral: tuple[float, ...] = (0.0, 0.1, -0.1, 0.2, -0.2)
    place_margin: float = 0.04
    max_place_tries: int = 24
    drive_check_stride: int = 25
    drive_tolerance: float = 0.02
    settle: float = 0.2
    hold_weight: float = 1.0
    rim: float = 0.012
    palm_gap: float = 0.005
    plan_budget: float = 60.0


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
        route: which of the route check's poses the drives ended at, JSON-ready
            (:meth:`MobilePlanner.route_record`): ``pick_pose`` / ``place_pose`` (x, y, yaw),
            their indices in the route's pose lists, and the route's summary (pose counts,
            grid cell, footprint).
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
    route: dict[str, Any] = field(default_factory=dict)

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
            :func:`~factory.demos.plan.grasps.facing_order`).
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
        collides = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        self._pick_geoms = np.flatnonzero((m.geom_bodyid == self.pick_body) & collides)
        palm = [k for k, g in enumerate(self.shape.geoms) if int(g) == _geom_id(m, HAND_GEOM)]
        self._palm = int(self.shape.geoms[palm[0]]) if palm else -1
        self._palm_in_tool = self.shape.pose_geom_in_tool[palm[0]] if palm else np.eye(4)
        self.dt = float(m.opt.timestep)
        mo = self.motion.arm
        self.fast = Limits.panda(mo.speed, mo.accel, mo.jerk)
        self.slow = Limits.panda(mo.speed * mo.slow, mo.accel * mo.slow, mo.jerk * mo.slow)
        self._rng = np.random.default_rng(0)
        self._where: Counter[str] = Counter()
        self._deadline = math.inf
        self._timing = dict.fromkeys(("nav", "pick", "place"), 0.0)
        # While carrying, the footprint's front grows by the object held ahead of the base.
        fp = setup.footprint
        self.carry_footprint = carry_footprint(fp, objs.pick, self.motion.carry_tool[0])
        data = mujoco.MjData(m)
        mujoco.mj_kinematics(m, data)
        self.pick_box = body_box(m, data, self.pick_support_body)
        self.place_box = body_box(m, data, self.place_support_body)
        self.place_area = SupportTop.of(m, data, self.place_support_body)
        self.place_top = support_top(m, data, self.place_support_body)
        # The route check's verdict and poses on this grid (a set-up made by hand gets them
        # here); drives end only at poses it verified.
        self.route: TaskRoute = setup.route or task_route(m, data, setup.grid, objs, fp)
        self.unusable = setup.reachable or self.route.detail

    # ---- helpers
    def _miss(self, counts: Counter[str], reason: str, where: str) -> None:
        """Counts a failed candidate under its reason, and where it failed (for the log)."""
        counts[reason] += 1
        self._where[where] += 1

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
        footprint: Footprint,
    ) -> BaseTrajectory:
        """A timed, re-checked base trajectory from ``start`` (3,) to ``goal``: an SE(2) path
        for ``footprint`` on the raw grid (:func:`factory.nav.plan_se2_path`), timed piece by
        piece (:func:`factory.nav.time_base_path`), re-checked with the real robot.

        Raises:
            _Fail: ``nav_failed`` or ``base_collision``.
        """
        mo = self.motion
        t0 = time.perf_counter()
        path = plan_se2_path(self.setup.grid, footprint, start, goal.as_array(), mo.nav, seed)
        if not path.ok:
            raise _Fail(NAV_FAILED, path.detail)
        traj = time_base_path(path.path, mo.limits, self.dt)
        stride = max(1, mo.drive_check_stride)
        ok, why = self._drive_ok(qpos, traj, q_arm, stride)
        self._timing["nav"] += time.perf_counter() - t0
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
        cands = carry_order(
            facing_order(cands, pose, arm_xy, self.grasp_facing),
            pose,
            self.model.body_ipos[self.pick_body],
            float(np.ptp(body_box(self.model, data, self.pick_body)[[2, 5]])),
            arm_xy,
            self.grasp_facing,
            self.motion.hold_weight,
        )
        back = np.eye(4)
        back[2, 3] = -self.grasp_cfg.pregrasp
        top = float(body_box(self.model, data, self.pick_body)[5])
        out: list[tuple[tuple[bool, bool], Grasp]] = []
        for g in cands:
            tool = pose @ g.pose_tool_in_obj
            clear = self.grasp_cfg.clearance
            if gripper_clear(
                self.model, data, self.shape, tool, clear, self.robot.bodies
            ) and gripper_clear(
                self.model, data, self.shape, tool @ back, clear, self.robot.bodies
            ):
                contact_z = float((pose[:3, :3] @ g.contacts_in_obj.T)[2].mean() + pose[2, 3])
                rim = contact_z > top - self.motion.rim
                tight = self._palm_gap(data, tool) < self.motion.palm_gap
                out.append(((rim, tight), g))
            if len(out) >= self.grasp_cfg.keep:
                break
        mujoco.mj_kinematics(self.model, data)
        # grasps below the rim first, then those leaving the palm clear of the object; the
        # carry order within each group
        return [g for _, g in sorted(out, key=lambda t: t[0])]

    def _palm_gap(self, data: mujoco.MjData, tool: np.ndarray) -> float:
        """Distance (m, up to 5 cm) from the hand's palm to the object to pick with the tool at
        ``tool`` (4, 4); ``data`` holds the scene's kinematics (the palm's pose is written)."""
        g = self._palm
        if g < 0:
            return math.inf
        pose = tool @ self._palm_in_tool
        data.geom_xpos[g] = pose[:3, 3]
        data.geom_xmat[g] = pose[:3, :3].reshape(-1)
        return min(
            (
                mujoco.mj_geomDistance(self.model, data, g, int(o), 0.05, None)
                for o in self._pick_geoms
            ),
            default=math.inf,
        )

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
            self._miss(counts, BASE_COLLISION, "pick: stowed arm at the base pose")
            return None
        data = mujoco.MjData(m)
        data.qpos[:] = state
        mujoco.mj_kinematics(m, data)
        arm_base = self._arm_base(base)
        grasps = self._grasps(data, arm_base[:2, 3])
        if not grasps:
            self._miss(counts, "no_grasp", "pick: no collision-free grasp")
            return None
        obj_pose = pose_matrix(data.xpos[self.pick_body], data.xmat[self.pick_body])
        carry_rot = np.diag([1.0, -1.0, -1.0])
        for g in grasps[: self.max_grasps]:
            self._check_time("picking")
            ck.attach(None)
            ck.ignore_bodies([])
            grasp = obj_pose @ g.pose_tool_in_obj
            pre = grasp.copy()
            pre[:3, 3] -= grasp[:3, 2] * mo.pregrasp
            lift = grasp.copy()
            lift[2, 3] += mo.lift
            q_pre = self._ik(arm_base, pre, [HOME_QPOS])
            if q_pre is None:
                self._miss(counts, "ik_failed", "pick: pre-grasp IK")
                continue
            q_grasp = self._ik(arm_base, grasp, [q_pre])
            if q_grasp is None:
                self._miss(counts, "ik_failed", "pick: grasp IK")
                continue
            if not ck.segment_valid(q_pre, q_grasp):
                self._miss(counts, "approach_collision", "pick: approach")
                continue
            obj_in_tool = np.linalg.inv(grasp) @ obj_pose
            attach = Attachment(self.pick_body, self.pick_adr, obj_in_tool)
            ck.attach(attach)
            ck.ignore_bodies([self.pick_support_body])
            q_lift = self._ik(arm_base, lift, [q_grasp])
            if q_lift is None:
                self._miss(counts, "ik_failed", "pick: lift IK")
                continue
            if not ck.segment_valid(q_grasp, q_lift):
                self._miss(counts, "lift_collision", "pick: lift")
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
                self._miss(counts, "ik_failed", "pick: carry pose IK")
                continue
            to_carry = plan(ck, q_lift, q_carry, self.planner_cfg, seed + 1)
            ck.attach(None)
            if to_carry.path is None:
                self._miss(counts, "plan_failed", "pick: lift to carry pose")
                continue
            reach = plan(ck, STOW_QPOS, q_pre, self.planner_cfg, seed)
            if reach.path is None:
                self._miss(counts, "plan_failed", "pick: stow to pre-grasp")
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

    def _place_points(self, base: np.ndarray, box: np.ndarray) -> list[np.ndarray]:
        """Candidate object positions (2,) on the support's top ahead of the arm's base with
        the base at ``base`` (3,): ``place_reach`` ahead, ``place_lateral`` aside, inside the
        top's box (6,) and inside the top itself (:class:`~factory.nav.task_poses.SupportTop`:
        a desk turned off the world axes is smaller than its world box) by the object's radius
        and ``place_margin``."""
        mo = self.motion
        r = object_radius(self.setup.objects.pick)
        fwd = np.array([math.cos(base[2]), math.sin(base[2])])
        side = np.array([-fwd[1], fwd[0]])
        arm = np.asarray(base[:2]) + ARM_X * fwd
        lo = box[:2] + r + mo.place_margin
        hi = box[3:5] - r - mo.place_margin
        out = []
        for depth in mo.place_reach:
            for lat in mo.place_lateral:
                xy = arm + fwd * depth + side * lat
                inside = (xy >= lo).all() and (xy <= hi).all()
                if inside and self.place_area.holds(xy, r, mo.place_margin):
                    out.append(xy)
        return out

    def _plan_place(
        self,
        qpos: np.ndarray,
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
        points = self._place_points(base, box)
        if not points:
            self._miss(counts, NO_PLACE_SUPPORT, "place: no point of the top in reach")
            return None
        for xy in points:
            for turn in (0.0, np.pi / 2, -np.pi / 2, np.pi):
                if self._place_tries >= self.motion.max_place_tries:
                    return None
                self._check_time("placing")
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
                    self._miss(counts, "ik_failed", "place: pre-place IK")
                    continue
                q_place = self._ik(arm_base, place, [q_pre])
                if q_place is None:
                    self._miss(counts, "ik_failed", "place: place IK")
                    continue
                if not ck.segment_valid(q_pre, q_place):
                    self._miss(counts, "ik_failed", "place: lowering collides")
                    continue
                retreat = place.copy()
                retreat[:3, 3] -= place[:3, 2] * mo.pregrasp
                ck.attach(None)
                ck.ignore_bodies([self.pick_body])
                q_ret = self._ik(arm_base, retreat, [q_place])
                if q_ret is None:
                    self._miss(counts, "ik_failed", "place: retreat IK")
                    continue
                if not ck.segment_valid(q_place, q_ret):
                    self._miss(counts, "retreat_collision", "place: retreat")
                    continue
                ck.ignore_bodies([])
                ck.attach(attach)
                to_pre = plan(ck, pick.q_carry, q_pre, self.planner_cfg, seed + 2)
                ck.attach(None)
                self._seconds["to_place"] = to_pre.seconds
                if to_pre.path is None:
                    self._miss(counts, "plan_failed", "place: carry pose to pre-place")
                    continue
                return _Place(to_pre.path, q_pre, q_place, q_ret)
        return None

    def _check_time(self, doing: str) -> None:
        """Raises ``plan_timeout`` once the episode's planning budget is spent."""
        if time.perf_counter() > self._deadline:
            raise _Fail(
                PLAN_TIMEOUT,
                f"planning budget of {self.motion.plan_budget:.0f} s spent while {doing}",
            )

    def plan_episode(self, seed: int) -> MobileEpisodePlan | MobilePlanFailure:
        """Plans one episode (deterministic in ``seed`` in a fresh process; see the module
        docstring). Every loop over candidates is bounded (``max_base_poses``,
        ``max_grasps``, ``max_place_tries``, ``spawn_tries``) and the whole plan by
        ``plan_budget`` seconds."""
        t0 = time.perf_counter()
        self._deadline = t0 + self.motion.plan_budget
        self._rng = np.random.default_rng(seed)
        self._seconds: dict[str, float] = {}
        self._timing = dict.fromkeys(("nav", "pick", "place"), 0.0)
        self._place_tries = 0
        self._where = Counter()
        counts: Counter[str] = Counter()
        try:
            if self.unusable:
                raise _Fail(NAV_FAILED, self.unusable)
            plan_ = self._plan(seed, counts)
        except _Fail as f:
            counts[f.reason] += 1
            where = ", ".join(f"{k} x{v}" for k, v in self._where.most_common(4))
            detail = f"{f}" + (f" (failed at: {where})" if where else "")
            log.debug("seed %d: %s in %.1f s", seed, detail, time.perf_counter() - t0)
            return MobilePlanFailure(f.reason, detail, time.perf_counter() - t0, dict(counts))
        plan_.seconds = time.perf_counter() - t0
        log.debug(
            "seed %d: planned in %.1f s (drives %.1f s, pick %.1f s, place %.1f s)",
            seed,
            plan_.seconds,
            self._timing["nav"],
            self._timing["pick"],
            self._timing["place"],
        )
        return plan_

    def _spawn(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """The episode's initial qpos (nq,) (arm stowed, hand closed, base at a random free
        pose from which the route's lattice reaches a verified pick pose,
        :meth:`~factory.nav.route.TaskRoute.random_spawn`) and the spawn pose (3,).

        Raises:
            _Fail: ``no_spawn``.
        """
        m, robot, mo = self.model, self.robot, self.motion
        qpos = np.array(m.qpos0)
        qpos[robot.qpos] = STOW_QPOS
        qpos[robot.finger_qpos] = robot.finger_pos(STOW_FINGERS)
        spawn: np.ndarray | None = None
        self.drive_checker.attach(None)
        self.drive_checker.ignore_bodies([])
        for _ in range(mo.spawn_tries):
            try:
                p = self.route.random_spawn(rng)
            except NavError as e:
                raise _Fail(NO_SPAWN, str(e)) from None
            self.drive_checker.set_scene(self._scene_state(qpos, p.as_array()))
            if not self.drive_checker.collisions(STOW_QPOS):
                spawn = p.as_array()
                break
        if spawn is None:
            raise _Fail(NO_SPAWN, f"no collision-free spawn pose in {mo.spawn_tries} draws")
        qpos[robot.base_qpos] = spawn
        return qpos, spawn

    def initial_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) that :meth:`plan_episode` starts episode ``seed`` from: the
        same random streams, so the same spawn pose (what the closed-loop env resets to).

        Raises:
            MobileTaskError: no free spawn pose (reason ``no_spawn``), or the robot's base
                cannot work in this scene.
        """
        if self.unusable:
            raise MobileTaskError(f"the robot's base cannot work here: {self.unusable}", NAV_FAILED)
        rng = np.random.default_rng(seed)
        rng.integers(2**31 - 1)  # the OMPL seed, drawn first as plan_episode draws it
        try:
            qpos, _ = self._spawn(rng)
        except _Fail as f:
            raise MobileTaskError(f"seed {seed}: {f}", f.reason) from None
        return qpos

    def _plan(self, seed: int, counts: Counter[str]) -> MobileEpisodePlan:
        m, mo, setup = self.model, self.motion, self.setup
        rng = self._rng
        ompl_seed = int(rng.integers(2**31 - 1))
        fp = setup.footprint

        # (a) spawn: a free pose in the region that holds the work poses
        qpos, spawn = self._spawn(rng)

        # (b, c) drive to a pose within reach of the object, pick there
        data = mujoco.MjData(m)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        picks, _ = task_work_poses(m, data, setup.grid, setup.objects, fp, spawn[:2])
        allowed = {_key(p) for p in self.route.picks_from(spawn)}
        picks = [p for p in picks if _key(p) in allowed]
        if not picks:
            raise _Fail(
                NAV_FAILED,
                f"no base pose within reach of {setup.objects.pick.id!r} that the route check "
                f"verified is reachable from the spawn pose {spawn.round(2).tolist()}",
            )
        nav1 = pick = None
        pick_goal = picks[0]
        for pose in picks[: mo.max_base_poses]:
            self._check_time("driving to the object")
            try:
                traj = self._navigate(qpos, spawn, pose, STOW_QPOS, ompl_seed, fp)
            except _Fail as f:
                self._miss(counts, f.reason, f"drive to pick: {f.reason}")
                log.debug("pick pose %s: %s", pose, f)
                continue
            t0 = time.perf_counter()
            pick = self._plan_pick(qpos, traj.q[-1], counts, ompl_seed)
            self._timing["pick"] += time.perf_counter() - t0
            if pick is not None:
                nav1 = traj
                pick_goal = pose
                break
        if nav1 is None or pick is None:
            raise _Fail(
                _worst(counts),
                f"no pick from {len(picks[: mo.max_base_poses])} base poses: {dict(counts)}",
            )
        pick_base = nav1.q[-1]

        # (d, e) carry to a pose within reach of the place support's top, place there
        _, places = task_work_poses(m, data, setup.grid, setup.objects, fp, pick_base[:2])
        allowed = {_key(p) for p in self.route.route_places(pick_goal)}
        places = [p for p in places if _key(p) in allowed]
        if not places:
            raise _Fail(
                NAV_FAILED,
                f"no base pose within reach of {setup.objects.place_support.id!r} that the "
                "route check verified is reachable from the pick",
            )
        # The drive is checked with the object in the hand (its pose taken in the carry pose).
        self.drive_checker.attach(Attachment(self.pick_body, self.pick_adr, pick.obj_in_tool))
        counts2: Counter[str] = Counter()
        nav2 = place = None
        place_goal = places[0]
        try:
            for pose in places[: mo.max_base_poses]:
                self._check_time("carrying to the place support")
                try:
                    traj = self._navigate(
                        qpos, pick_base, pose, pick.q_carry, ompl_seed + 3, self.carry_footprint
                    )
                except _Fail as f:
                    self._miss(counts2, f.reason, f"drive to place: {f.reason}")
                    continue
                t0 = time.perf_counter()
                place = self._plan_place(
                    qpos, traj.q[-1], pick, self.place_top, self.place_box, counts2, ompl_seed
                )
                self._timing["place"] += time.perf_counter() - t0
                if place is not None:
                    nav2 = traj
                    place_goal = pose
                    break
        finally:
            self.drive_checker.attach(None)
        if nav2 is None or place is None:
            counts.update(counts2)
            raise _Fail(
                _worst(counts2),
                f"no place at {setup.objects.place_support.id!r} from "
                f"{len(places[: mo.max_base_poses])} base poses: {dict(counts2)}",
            )
        out = self._timeline(qpos, spawn, nav1, pick, nav2, place)
        out.route = self.route_record(pick_goal, place_goal)
        return out

    def route_record(self, pick_goal: BasePose, place_goal: BasePose) -> dict[str, Any]:
        """JSON-ready: the route check's poses an episode drove to (x, y m, yaw rad, as the
        route lists them), their indices in the route's pick and place pose lists (best
        first) and the route's summary (:meth:`factory.nav.route.TaskRoute.summary`)."""
        return {
            "pick_pose": [round(float(v), 6) for v in pick_goal.as_array()],
            "place_pose": [round(float(v), 6) for v in place_goal.as_array()],
            "pick_index": self.route.pick_index(pick_goal),
            "place_index": self.route.place_index(place_goal),
            **self.route.summary(),
        }

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


def _key(pose: BasePose) -> tuple[float, float, float]:
    """A base pose as a hashable key (x, y m, yaw rad modulo a turn, to 1 um and 1 urad):
    work poses from the same candidates compare equal."""
    return (round(pose.x, 6), round(pose.y, 6), round(pose.yaw % (2 * math.pi), 6))


def _geom_id(model: mujoco.MjModel, name: str) -> int:
    try:
        return int(model.geom(name).id)
    except KeyError:
        return -1


def carry_order(
    grasps: list[Grasp],
    pose_obj_in_world: np.ndarray,
    com_in_obj: np.ndarray,
    height: float,
    base_xy_in_world: np.ndarray,
    facing_weight: float,
    hold_weight: float,
) -> list[Grasp]:
    """Grasps ranked for carrying the object across a room, best first.

    The fixed task lifts and lowers an object in place; here it rides on a driving base for
    tens of seconds, and a grasp on the object's top rim lets it swing about the closing axis
    until it slips out (seen on generated living rooms: a can held 3 mm below its top fell
    during every drive). So to the grasp's own score (:attr:`Grasp.score`) this adds
    ``hold_weight * (contact - 2 |dz| / h)``: ``contact`` the share of the finger pads on
    material, ``dz`` the height of the grasp centre above or below the centre of mass and
    ``h`` the object's height (m, world z); and ``facing_weight * cos(azimuth)`` of
    :func:`~factory.demos.plan.grasps.facing_order`, without its sign flips for grasps within
    5 mm of the object's axis (there the azimuth is noise).

    Args:
        grasps: candidates (object frame), as :func:`~factory.demos.plan.grasps.facing_order`
            returns them (closing axes already turned away from the robot).
        pose_obj_in_world: the object's pose (4, 4).
        com_in_obj: its centre of mass (3,), object frame (m).
        height: its height (m, world z).
        base_xy_in_world: the robot's arm base position (2,), world (m).
        facing_weight: weight of the side facing the robot (``demos.grasp_facing``).
        hold_weight: weight of the hold (0 keeps the facing order).
    """
    if not grasps or hold_weight <= 0:
        return list(grasps)
    rot = pose_obj_in_world[:3, :3]
    obj_xy = pose_obj_in_world[:2, 3]
    toward = np.asarray(base_xy_in_world, float) - obj_xy
    toward /= max(float(np.linalg.norm(toward)), 1e-9)
    z = np.array([(rot @ g.contacts_in_obj.T)[2] for g in grasps])  # (n, 2), object origin 0
    com_z = float((rot @ com_in_obj)[2])
    height = max(height, 1e-3)
    ranked = []
    for g, zc in zip(grasps, z, strict=True):
        world = pose_obj_in_world @ g.pose_tool_in_obj
        off = world[:2, 3] - obj_xy
        norm = float(np.linalg.norm(off))
        facing = float(off @ toward) / norm if norm > 0.005 else 0.0
        dz = abs(float(zc.mean()) - com_z)
        hold = g.contact - 2.0 * dz / height
        ranked.append((g.score + facing_weight * facing + hold_weight * hold, g))
    ranked.sort(key=lambda t: -t[0])
    return [g for _, g in ranked]


_PRIORITY = (PLAN_TIMEOUT, NO_PLACE_SUPPORT, NAV_FAILED, BASE_COLLISION)


def _worst(counts: Counter[str]) -> str:
    """The reason reported for a stage whose candidates all failed: navigation first (it
    says the route or the goal is the problem), else the most common arm reason."""
    for r in _PRIORITY:
        if counts.get(r) and all(counts[r] >= v for k, v in counts.items() if k in _PRIORITY):
            return r
    return counts.most_common(1)[0][0] if counts else "plan_failed"
