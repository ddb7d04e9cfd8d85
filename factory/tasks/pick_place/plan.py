"""Planning one pick-and-place demonstration: grasp, IK, RRTConnect, ruckig -> control targets.

Per scene, :func:`setup_scene` composes the scene with the robot at a base spot from which the
workspace is reachable and the robot is free. Per episode, :func:`plan_episode` randomizes the
task objects' poses, picks a grasp, solves IK for pre-grasp, grasp, lift, pre-place, place and
retreat, plans the two free-space motions with RRTConnect (the object attached during
transport), times every segment with ruckig, and returns per-physics-step control targets.
Nothing is simulated here: :mod:`factory.demos.execute.cpu` runs the targets through the
controller.
"""

from __future__ import annotations

import logging
import time
import zlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from factory.demos.plan.grasps import (
    Grasp,
    GraspConfig,
    GraspPool,
    GripperShape,
    collision_pieces,
    facing_order,
    gripper_clear,
)
from factory.demos.plan.planner import Attachment, CollisionChecker, PlannerConfig, plan
from factory.demos.plan.timing import Limits, time_path
from factory.errors import TaskError
from factory.robots.ik import IKConfig, IKSolver
from factory.robots.panda import (
    CAMERAS,
    GRIP_CLOSED,
    GRIP_OPEN,
    HOME_QPOS,
    SCENE_CAMERAS,
    CameraRig,
    RobotIndex,
    RobotPlacement,
    add_robot,
    pose_matrix,
    rot_z,
)
from factory.schema import Scene, SceneObject
from factory.tasks.pick_place.objects import (
    TaskObjects,
    Workspace,
    base_candidates,
    initial_state,
    move_robot,
    randomize,
    task_objects,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MotionConfig:
    """Timing of the demonstration.

    Attributes:
        speed, accel, jerk: shares of the Panda's limits for free-space motions.
        slow: extra share for the short approach, lift, lower and retreat moves.
        pregrasp: approach distance (m); lift: lift height (m); place_drop: the object is
            released this far above the target's surface (m); preplace: height above the
            place pose (m).
        settle, close, release, hold: pauses (s): before moving, closing the hand, opening it,
            at the end.
    """

    speed: float = 0.5
    accel: float = 0.3
    jerk: float = 0.2
    slow: float = 0.5
    pregrasp: float = 0.10
    lift: float = 0.15
    place_drop: float = 0.015
    preplace: float = 0.10
    settle: float = 0.2
    close: float = 0.6
    release: float = 0.4
    hold: float = 0.6


@dataclass
class SceneSetup:
    """A scene ready for planning: composed model at a chosen base spot."""

    scene: Scene
    objects: TaskObjects
    placement: RobotPlacement
    model: mujoco.MjModel
    robot: RobotIndex
    rig: CameraRig
    cleared: tuple[str, ...] = ()
    """Objects taken out of the scene to free the base spot or as look-alikes of the task's
    objects near it (:func:`lookalikes`), with what stood on them."""
    frozen: tuple[str, ...] = ()
    """Objects out of the robot's reach compiled without their free joint (static)."""


@dataclass
class EpisodePlan:
    """What execution needs for one episode.

    Attributes:
        qpos0: initial state (nq,).
        ctrl: actuator controls per physics step (T, nu): desired joint positions plus a
            velocity lead (``kv/kp * qd``) so that the PD actuators track without lag.
        targets: desired arm joint positions (rad) and gripper command (m) per physics step
            (T, 8): the recorded action.
        phases: phase name -> first physics step.
        grasp_width: span of the chosen grasp (m).
        plan_seconds: planning time per planned segment (s), by segment name.
        seconds: total planning time of the episode (s).
        attempts: grasp candidates tried.
    """

    qpos0: np.ndarray
    ctrl: np.ndarray
    targets: np.ndarray
    phases: dict[str, int]
    grasp_width: float
    plan_seconds: dict[str, float]
    seconds: float
    attempts: int


@dataclass
class PlanFailure:
    """Why an episode could not be planned: reason key and detail (every fixed-base task's
    planner reports it)."""

    reason: str
    detail: str
    seconds: float
    counts: dict[str, int] = field(default_factory=dict)

    @classmethod
    def of_counts(cls, counts: Counter[str], default: str, detail: str, t0: float) -> PlanFailure:
        """The failure of a planner whose candidates (grasps) all failed: the most common
        reason in ``counts`` (``default`` when none was counted), ``detail`` followed by the
        counts, the seconds since ``t0`` (``time.perf_counter``)."""
        reason = counts.most_common(1)[0][0] if counts else default
        return cls(reason, f"{detail}: {dict(counts)}", time.perf_counter() - t0, dict(counts))


FREEZE_BEYOND = 1.0
"""Objects whose footprint stays this far (m, horizontally) from the robot's base are static
in the demos' model: the arm (0.86 m from the shoulder, plus the hand) cannot touch them."""
FURNITURE_RADIUS = 0.4
"""Floor objects with a footprint radius from this (m) up, or holding other objects, are
furniture: static in the demos' model unless they are task objects."""
LOOKALIKE_RADIUS = 1.5
"""Movable objects of the pick's or the target's category whose centre lies within this (m,
horizontally) of the robot's base are taken out of the scene (:func:`lookalikes`): a policy
that sees only camera images cannot tell which of two mugs in front of the robot is "the
mug", as a person asked to pick up the mug expects one mug within reach. 1.5 m is the arm's
reach (0.86 m from the shoulder, plus the hand) with a margin; a look-alike farther away may
still show at the edge of a camera image."""


def lookalikes(scene: Scene, objects: TaskObjects, spot: RobotPlacement, radius: float) -> set[str]:
    """Objects a camera image confuses with the task's own: they are taken out of the scene.

    Look-alikes are movable objects of the pick's or the target's category (other than the
    pick and the target) whose centre lies less than ``radius`` (m) from the robot's base
    horizontally. What stands on them goes with them (``Scene.with_dependents``); a look-alike
    carrying a task object stays.

    Args:
        scene: the scene.
        objects: its task objects.
        spot: the robot's base pose (world frame).
        radius: horizontal distance from the base (m); ``<= 0`` keeps every look-alike.

    Returns:
        the ids to take out: the look-alikes and what stands on them (empty when none).
    """
    if radius <= 0:
        return set()
    keep = {objects.pick.id, objects.target.id, objects.support.id}
    categories = {objects.pick.category, objects.target.category}
    out: set[str] = set()
    for o in scene.objects:
        if o.is_static or o.id in keep or o.category not in categories:
            continue
        if float(np.hypot(o.position.x - spot.x, o.position.y - spot.y)) >= radius:
            continue
        gone = scene.with_dependents({o.id})
        if not gone & keep:
            out |= gone
    return out


def far_objects(scene: Scene, placement: RobotPlacement, keep: set[str], radius: float) -> set[str]:
    """Movable objects the robot cannot move: they are compiled static for the demos.

    Static are (unless in ``keep``): objects whose footprint disc lies wholly more than
    ``radius`` (m) from the robot's base horizontally, and floor furniture (tables, counters,
    cabinets: a footprint radius of :data:`FURNITURE_RADIUS` or more, or something stands on
    it), which the arm may brush but not shift. Objects standing on a movable object that stays
    free (a box on a chair) stay free too.

    Args:
        scene: the scene.
        placement: the robot's base pose (world frame).
        keep: ids that must stay free bodies (the task's objects).
        radius: reach radius (m); ``<= 0`` freezes nothing.

    Returns:
        the ids to compile without a free joint.
    """
    if radius <= 0:
        return set()
    base = np.array([placement.x, placement.y])
    by_id = {o.id: o for o in scene.objects}
    holds = {o.placement.support_id for o in scene.objects if o.placement.support_id}
    free: set[str] = set(keep)
    for o in scene.objects:
        if o.is_static or o.id in keep:
            continue
        r = 0.5 * float(np.hypot(o.dimensions.width, o.dimensions.length))
        far = np.linalg.norm(np.array([o.position.x, o.position.y]) - base) - r > radius
        furniture = o.placement.kind == "floor" and (r >= FURNITURE_RADIUS or o.id in holds)
        if not far and not furniture:
            free.add(o.id)

    def on_free(o: SceneObject) -> bool:
        seen: set[str] = set()
        sid = o.placement.support_id
        while sid and sid in by_id and sid not in seen:
            if sid in free:
                return True
            seen.add(sid)
            sid = by_id[sid].placement.support_id
        return False

    return {o.id for o in scene.objects if not o.is_static and o.id not in free and not on_free(o)}


def compose(
    scene: Scene,
    assets_root: str | Path | None,
    placement: RobotPlacement,
    rig: CameraRig,
    frozen: set[str] | frozenset[str] = frozenset(),
) -> mujoco.MjModel:
    """Compiles a scene with the robot at ``placement`` (scene masses as in compile).

    Island sleeping is on: bodies at rest stop being simulated until touched (MuJoCo's
    ``mjENBL_SLEEP``), which makes the furniture of a large scene almost free. Objects named
    in ``frozen`` lose their free joint (static at their scene pose): the simulation, the
    recorded state and the GPU executor's per-world cost shrink with them.
    """
    from factory.sim.compile import compile_scene

    compiled = compile_scene(scene, assets_root)
    for oid in sorted(frozen):
        compiled.spec.delete(compiled.spec.joint(f"{oid}/free"))
    add_robot(compiled.spec, placement, rig)
    # Objects at rest sleep until something touches them: 4x faster, same outcome.
    compiled.spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    return compiled.spec.compile()


def _top_down(xyz: np.ndarray, yaw: float) -> np.ndarray:
    """A tool pose (4, 4) at ``xyz`` pointing straight down, turned by ``yaw`` rad."""
    return pose_matrix(xyz, rot_z(yaw) @ np.diag([1.0, -1.0, -1.0]))


def setup_scene(
    scene: Scene,
    assets_root: str | Path | None,
    ws: Workspace | None = None,
    rig: CameraRig | None = None,
    ik: IKSolver | None = None,
    max_spots: int = 24,
    freeze_beyond: float = FREEZE_BEYOND,
    lookalike_radius: float = LOOKALIKE_RADIUS,
) -> SceneSetup:
    """Chooses the robot's base spot and composes the scene with the robot there.

    A spot is taken when the robot at home collides with nothing and a top-down tool pose
    above the middle of the reachable workspace has an IK solution. When every spot is
    blocked only by movable floor objects (chairs around a table, a bin), the nearest such
    spot is freed by taking those objects (and what stands on them) out of the scene. A spot
    is preferred where the episodes' sampler finds room for the task objects within reach
    (:func:`has_room`); where no spot has room, the objects crowding the support nearest to
    the robot are taken off it (:func:`clear_clutter`). The setup's ``cleared`` names every
    object taken out; its ``frozen`` the objects beyond ``freeze_beyond`` (m) of the base,
    compiled static (:func:`far_objects`; ``<= 0``: none). Once the spot is chosen, the other
    mugs and bowls (the pick's and the target's categories) within ``lookalike_radius`` (m,
    horizontally) of the base are taken out too, with what stands on them
    (:func:`lookalikes`; ``<= 0``: kept), and named in ``cleared``: near the robot, the
    task's pick and target are the only objects of their categories.

    Raises:
        TaskError: the scene lacks task objects, or no spot around the support works.
    """
    ws = ws or Workspace()
    rig = rig or CameraRig()
    objects = task_objects(scene)
    spots = base_candidates(objects)
    if not spots:
        raise TaskError(f"scene {scene.id!r}: no base spot around {objects.support.id!r}")
    model = compose(scene, assets_root, spots[0], rig)
    robot = RobotIndex.of(model)
    base_body = model.body("panda/robot0_base").id
    ik = ik or IKSolver()
    qpos = initial_state(model, robot)
    checker = CollisionChecker(model, robot, qpos)
    mid = 0.5 * (ws.reach_min + ws.reach_max)
    tool = _top_down(np.array([mid, 0.0, 0.12]), 0.0)
    if ik.solve(tool, [HOME_QPOS]) is None:  # pragma: no cover - the pose is well inside
        raise TaskError("the robot cannot reach its own workspace centre")
    keep = {objects.pick.id, objects.target.id, objects.support.id}
    scene_ids = {o.id for o in scene.objects}

    def done(spot: RobotPlacement, sc: Scene, cleared: set[str], why: str) -> SceneSetup:
        if cleared:
            log.info("scene %s: cleared %s %s", scene.id, sorted(cleared), why)
        alike = lookalikes(sc, objects, spot, lookalike_radius)
        if alike:
            log.info(
                "scene %s: took out look-alikes %s (within %.2f m of the base)",
                scene.id,
                sorted(alike),
                lookalike_radius,
            )
            sc = replace(sc, objects=[o for o in sc.objects if o.id not in alike])
            cleared = cleared | alike
        cams = aim_cameras(sc, assets_root, spot, rig)
        frozen = far_objects(sc, spot, {objects.pick.id, objects.target.id}, freeze_beyond)
        out = compose(sc, assets_root, spot, cams, frozen)
        return SceneSetup(
            sc,
            objects,
            spot,
            out,
            RobotIndex.of(out),
            cams,
            tuple(sorted(cleared)),
            tuple(sorted(frozen)),
        )

    def room(sc: Scene, spot: RobotPlacement) -> bool:
        return has_room(checker.model, qpos, sc, objects, spot, ws)

    free: list[RobotPlacement] = []
    blocked: list[tuple[RobotPlacement, set[str]]] = []
    for spot in spots[:max_spots]:
        move_robot(checker.model, spot, base_body)
        hits = checker.collisions(HOME_QPOS)
        if not hits:
            if room(scene, spot):
                return done(spot, scene, set(), "")
            free.append(spot)
            continue
        names = {b for pair in hits for b in pair[:2] if not b.startswith("panda/")}
        if names and all(
            n in scene_ids and n not in keep and _movable(scene.object(n)) for n in names
        ):
            blocked.append((spot, names))
    for spot, names in blocked[:3]:
        cleared = scene.with_dependents(names)
        trimmed = replace(scene, objects=[o for o in scene.objects if o.id not in cleared])
        model = compose(trimmed, assets_root, spot, rig)
        trimmed_robot = RobotIndex.of(model)
        check = CollisionChecker(model, trimmed_robot, initial_state(model, trimmed_robot))
        if check.valid(HOME_QPOS) and room(trimmed, spot):
            return done(spot, trimmed, cleared, "for the robot's base")
    for spot in free[:3]:
        trimmed, cleared = clear_clutter(checker.model, qpos, scene, objects, spot, ws)
        if cleared:
            return done(spot, trimmed, cleared, "from the task's table to make room for the task")
    if free:  # no room anywhere: each episode's object placement fails with its own reason
        return done(free[0], scene, set(), "")
    raise TaskError(
        f"scene {scene.id!r}: no free base spot next to {objects.support.id!r} "
        f"(tried {min(len(spots), max_spots)})"
    )


ROOM_SEEDS = 10
"""Seeds tried by :func:`has_room` (an episode's placement is one seed)."""
ROOM_SHARE = 0.5
"""Least share of them that must place the task objects for a spot to have room."""
MAX_CLUTTER = 8
"""Most objects :func:`clear_clutter` takes off the task's support."""


def has_room(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    scene: Scene,
    objects: TaskObjects,
    spot: RobotPlacement,
    ws: Workspace,
    seeds: int = ROOM_SEEDS,
) -> bool:
    """Whether the episodes' sampler (:func:`~factory.tasks.pick_place.objects.randomize`) puts the
    task
    objects within reach of a base at ``spot`` for at least :data:`ROOM_SHARE` of ``seeds``
    seeds (a table so crowded that most episodes cannot be set up is not used as it is).

    Args:
        model: a composed model holding the task objects' free joints.
        qpos: its initial state (nq,).
        scene: the scene whose objects occupy the support.
    """
    need, placed = ROOM_SHARE * seeds, 0
    for s in range(seeds):
        try:
            randomize(model, qpos, scene, objects, spot, ws, np.random.default_rng(s))
            placed += 1
        except TaskError:
            pass
        if placed >= need:
            return True
        if placed + (seeds - s - 1) < need:
            return False
    return False


def clear_clutter(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    scene: Scene,
    objects: TaskObjects,
    spot: RobotPlacement,
    ws: Workspace,
) -> tuple[Scene, set[str]]:
    """Takes objects off the task's support, nearest to the robot first (with what stands on
    them), until the task objects fit within reach (:func:`has_room`).

    A generated table can be set so fully (plates, bowls, mugs) that no spot within the arm's
    reach is free for the task's two objects; a person would clear a corner of it first.

    Returns:
        ``(scene without them, their ids)``; ``(scene, set())`` when clearing up to
        :data:`MAX_CLUTTER` objects does not make room.
    """
    base = spot.pos()[:2]
    clutter = sorted(
        (
            o
            for o in scene.objects
            if o.placement.support_id == objects.support.id
            and o.id not in (objects.pick.id, objects.target.id)
        ),
        key=lambda o: float(np.hypot(o.position.x - base[0], o.position.y - base[1])),
    )
    for k in range(1, min(len(clutter), MAX_CLUTTER) + 1):
        cleared = scene.with_dependents({o.id for o in clutter[:k]})
        trimmed = replace(scene, objects=[o for o in scene.objects if o.id not in cleared])
        if has_room(model, qpos, trimmed, objects, spot, ws):
            return trimmed, cleared
    return scene, set()


def _movable(obj: SceneObject) -> bool:
    """Floor objects light enough to move aside (chairs, stools, bins), not fixtures."""
    return (
        not obj.is_static
        and obj.placement.kind == "floor"
        and obj.physics.mass <= 25.0
        and max(obj.dimensions.width, obj.dimensions.length) <= 1.0
    )


def _clear_view(
    model: mujoco.MjModel, data: mujoco.MjData, eye: np.ndarray, targets: np.ndarray
) -> bool:
    """Whether every ray from ``eye`` reaches within 5 cm of each target point (3,)."""
    geomid = np.zeros(1, np.int32)
    for t in targets:
        d = t - eye
        dist = float(np.linalg.norm(d))
        hit = mujoco.mj_ray(model, data, eye, d / dist, None, 1, -1, geomid)
        if 0 <= hit < dist - 0.05:
            return False
    return True


def aim_cameras(
    scene: Scene, assets_root: str | Path | None, placement: RobotPlacement, rig: CameraRig
) -> CameraRig:
    """Moves the third-person cameras until nothing in the scene blocks their view of the
    workspace (rays to a grid on the table top), trying turns around it and higher eyes."""
    from dataclasses import replace

    from factory.sim.compile import compile_scene

    model = compile_scene(scene, assets_root).model
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    top = placement.z
    grid = [
        placement.to_world(np.array([rig.workspace + dx, dy, 0.02]))
        for dx in (-0.2, 0.0, 0.2)
        for dy in (-0.25, 0.0, 0.25)
    ]
    targets = np.array(grid)
    targets[:, 2] = top + 0.02
    centre = np.array([rig.workspace, 0.0, 0.0])
    chosen: dict[str, tuple[float, ...]] = {}
    for side, offset in (("left", rig.left_offset), ("right", rig.right_offset)):
        best: tuple[float, ...] = offset
        for turn in (0.0, 20.0, -20.0, 40.0, -40.0, 60.0, -60.0):
            for lift, pull in ((0.0, 1.0), (0.25, 1.0), (0.1, 0.75)):
                a = np.radians(turn)
                cand = rot_z(a) @ (np.asarray(offset) * [1.0, pull, 1.0]) + [0, 0, lift]
                if _clear_view(model, data, placement.to_world(centre + cand), targets):
                    best = tuple(float(v) for v in cand)
                    break
            else:
                continue
            break
        else:
            log.info("scene %s: every %s camera pose is partly blocked", scene.id, side)
        chosen[side] = best
    return replace(rig, left_offset=chosen["left"], right_offset=chosen["right"])


def camera_calibration(
    setup: SceneSetup, cameras: Sequence[str], patch: Any = None
) -> tuple[dict[str, list[float]], dict[str, float]]:
    """The calibration of those of ``cameras`` fixed in the scene
    (:data:`~factory.robots.panda.SCENE_CAMERAS`, as :func:`aim_cameras` placed them): each
    one's pose in the robot's base frame (the base spot's frame) and vertical field of view, as
    drawn with an episode's appearance ``patch`` (a
    :class:`~factory.demos.record.appearance.ModelPatch`; None: the rig's pose)
    (:func:`factory.demos.record.calibration.camera_calibration`).

    Returns:
        camera name -> 12 values (position m, rotation rows), camera name -> fovy (deg).
    """
    from factory.demos.record.calibration import camera_calibration as calibrate

    cams = {c: CAMERAS[c] for c in cameras if c in SCENE_CAMERAS}
    p = setup.placement
    return calibrate(setup.model, cams, p.pos(), rot_z(p.yaw), patch)


def _surface_height(model: mujoco.MjModel, body: int, pose: np.ndarray) -> float:
    """World height of the topmost surface of ``body`` on the vertical line through its origin."""
    from factory.demos.plan.grasps import _line_intervals

    pieces = collision_pieces(model, body)
    up = pose[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    origin = (up * 2.0)[None]
    t_in, t_out, _ = _line_intervals(pieces, origin, -up[None])
    hit = t_in < t_out
    if not hit.any():
        return float(pose[2, 3])
    return float(pose[2, 3] + 2.0 - t_in[hit].min())


def initial_configuration(
    setup: SceneSetup,
    rng: np.random.Generator,
    ws: Workspace | None = None,
    randomize_objects: bool = True,
) -> np.ndarray:
    """An episode's initial qpos (nq,): the robot at home with the hand open and, with
    ``randomize_objects``, the pick object and the target re-placed by :func:`randomize`
    (``np.random.default_rng(seed)`` gives the demos' configuration of that seed).

    Raises:
        TaskError: no free spot for the objects within reach.
    """
    qpos = initial_state(setup.model, setup.robot)
    if randomize_objects:
        qpos = randomize(
            setup.model, qpos, setup.scene, setup.objects, setup.placement, ws or Workspace(), rng
        )
    return qpos


class EpisodePlanner:
    """Plans the episodes of one scene.

    Args:
        setup: the scene with the robot placed.
        grasp_cfg, ik_cfg, planner_cfg, motion: parameters.
        ws: where task objects are put per episode.
        max_grasps: grasp candidates tried per episode.
        grasp_facing: preference for grasps on the object's side facing the robot, in one hand
            orientation (:func:`~factory.demos.plan.grasps.facing_order`; 0: geometric ranking).
    """

    def __init__(
        self,
        setup: SceneSetup,
        grasp_cfg: GraspConfig | None = None,
        ik_cfg: IKConfig | None = None,
        planner_cfg: PlannerConfig | None = None,
        motion: MotionConfig | None = None,
        ws: Workspace | None = None,
        max_grasps: int = 12,
        grasp_facing: float = 1.0,
    ) -> None:
        self.setup = setup
        self.grasp_cfg = grasp_cfg or GraspConfig()
        self.ik = IKSolver(ik_cfg)
        self.planner_cfg = planner_cfg or PlannerConfig()
        self.motion = motion or MotionConfig()
        self.ws = ws or Workspace()
        self.max_grasps = max_grasps
        self.grasp_facing = grasp_facing
        m = setup.model
        self.model = m
        self.robot = setup.robot
        self.checker = CollisionChecker(m, self.robot, initial_state(m, self.robot))
        self.shape = GripperShape.of(m, self.robot, GRIP_OPEN)
        self.pick_body = m.body(setup.objects.pick.id).id
        self.target_body = m.body(setup.objects.target.id).id
        self.support_body = m.body(setup.objects.support.id).id
        jnt = int(m.body_jntadr[self.pick_body])
        self.pick_adr = int(m.jnt_qposadr[jnt])
        self.pieces = collision_pieces(m, self.pick_body)
        self._pool: GraspPool | None = None
        self.base = setup.placement.matrix()
        self.base_inv = np.linalg.inv(self.base)
        self.dt = float(m.opt.timestep)
        mo = self.motion
        self.fast = Limits.panda(mo.speed, mo.accel, mo.jerk)
        self.slow = Limits.panda(mo.speed * mo.slow, mo.accel * mo.slow, mo.jerk * mo.slow)

    # ---- helpers
    def _ik(self, pose_world: np.ndarray, seeds: list[np.ndarray]) -> np.ndarray | None:
        return self.ik.solve(self.base_inv @ pose_world, seeds, accept=self.checker.valid)

    def _grasps(self, data: mujoco.MjData) -> list[Grasp]:
        pose = pose_matrix(data.xpos[self.pick_body], data.xmat[self.pick_body])
        if self._pool is None:  # the object's pairs, once per planner (deterministic)
            key = f"{self.setup.scene.id}/{self.setup.objects.pick.id}".encode()
            self._pool = GraspPool(
                self.pieces, self.grasp_cfg, zlib.crc32(key), self.model.body_ipos[self.pick_body]
            )
        cands = self._pool.candidates(pose[:3, :3], self._rng)
        cands = facing_order(cands, pose, self.base[:2, 3], self.grasp_facing)
        out = []
        back = np.eye(4)
        back[2, 3] = -self.grasp_cfg.pregrasp
        for g in cands:
            tool = pose @ g.pose_tool_in_obj
            if gripper_clear(
                self.model, data, self.shape, tool, self.grasp_cfg.clearance, self.robot.bodies
            ) and gripper_clear(
                self.model,
                data,
                self.shape,
                tool @ back,
                self.grasp_cfg.clearance,
                self.robot.bodies,
            ):
                out.append(g)
            if len(out) >= self.grasp_cfg.keep:
                break
        mujoco.mj_kinematics(self.model, data)  # undo the probe's geom poses
        return out

    def plan_episode(self, seed: int, randomize_objects: bool = True) -> EpisodePlan | PlanFailure:
        """Plans one episode (deterministic in ``seed``)."""
        t0 = time.perf_counter()
        self._rng = np.random.default_rng(seed)
        m, setup = self.model, self.setup
        try:
            qpos = initial_configuration(setup, self._rng, self.ws, randomize_objects)
        except TaskError as e:
            return PlanFailure("no_object_pose", str(e), time.perf_counter() - t0)
        data = mujoco.MjData(m)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        self.checker.set_scene(qpos)
        self.checker.attach(None)
        self.checker.ignore_bodies([])
        if not self.checker.valid(HOME_QPOS):
            return PlanFailure("collision", "robot at home collides", time.perf_counter() - t0)
        grasps = self._grasps(data)
        if not grasps:
            return PlanFailure(
                "no_grasp",
                f"no collision-free antipodal grasp on {setup.objects.pick.id!r}",
                time.perf_counter() - t0,
            )
        counts: Counter[str] = Counter()
        obj_pose = pose_matrix(data.xpos[self.pick_body], data.xmat[self.pick_body])
        target_pose = pose_matrix(data.xpos[self.target_body], data.xmat[self.target_body])
        surface = _surface_height(m, self.target_body, target_pose)
        pick_bottom = qpos[self.pick_adr + 2]
        for attempt, g in enumerate(grasps[: self.max_grasps]):
            result = self._try_grasp(g, qpos, obj_pose, surface, pick_bottom, counts)
            if isinstance(result, EpisodePlan):
                result.seconds = time.perf_counter() - t0
                result.attempts = attempt + 1
                return result
        tried = f"{len(grasps[: self.max_grasps])} grasps tried"
        return PlanFailure.of_counts(counts, "plan_failed", tried, t0)

    def _try_grasp(
        self,
        g: Grasp,
        qpos: np.ndarray,
        obj_pose: np.ndarray,
        surface: float,
        pick_bottom: float,
        counts: Counter[str],
    ) -> EpisodePlan | None:
        mo, ck = self.motion, self.checker
        grasp = obj_pose @ g.pose_tool_in_obj
        pre = grasp.copy()
        pre[:3, 3] -= grasp[:3, 2] * mo.pregrasp
        lift = grasp.copy()
        lift[2, 3] += mo.lift
        ck.attach(None)
        ck.ignore_bodies([])
        q_pre = self._ik(pre, [HOME_QPOS])
        if q_pre is None:
            counts["ik_failed"] += 1
            return None
        q_grasp = self._ik(grasp, [q_pre])
        if q_grasp is None or not ck.segment_valid(q_pre, q_grasp):
            counts["ik_failed" if q_grasp is None else "approach_collision"] += 1
            return None
        pose_obj_in_tool = np.linalg.inv(grasp) @ obj_pose
        ck.attach(Attachment(self.pick_body, self.pick_adr, pose_obj_in_tool))
        ck.ignore_bodies([self.support_body])
        q_lift = self._ik(lift, [q_grasp])
        if q_lift is None or not ck.segment_valid(q_grasp, q_lift):
            counts["ik_failed" if q_lift is None else "lift_collision"] += 1
            return None
        ck.ignore_bodies([])
        # Place: the object upright above the target, turned by the first yaw that works.
        plan_place = None
        for turn in (0.0, np.pi / 2, -np.pi / 2, np.pi, np.pi / 4, -np.pi / 4):
            place_obj = np.eye(4)
            place_obj[:3, :3] = rot_z(turn) @ obj_pose[:3, :3]
            place_obj[:2, 3] = self._target_xy
            place_obj[2, 3] = surface + mo.place_drop + (obj_pose[2, 3] - pick_bottom)
            place = place_obj @ np.linalg.inv(pose_obj_in_tool)
            preplace = place.copy()
            preplace[2, 3] += mo.preplace
            q_preplace = self._ik(preplace, [q_lift])
            if q_preplace is None:
                continue
            q_place = self._ik(place, [q_preplace])
            if q_place is None or not ck.segment_valid(q_preplace, q_place):
                continue
            plan_place = (q_preplace, q_place, place)
            break
        if plan_place is None:
            counts["ik_failed"] += 1
            return None
        q_preplace, q_place, place = plan_place
        retreat = place.copy()
        retreat[:3, 3] -= place[:3, 2] * mo.pregrasp
        ck.attach(None)
        ck.ignore_bodies([self.pick_body])
        q_retreat = self._ik(retreat, [q_place])
        if q_retreat is None or not ck.segment_valid(q_place, q_retreat):
            counts["ik_failed" if q_retreat is None else "retreat_collision"] += 1
            return None
        # Free-space motions.
        ck.ignore_bodies([])
        seconds: dict[str, float] = {}
        seed = int(self._rng.integers(2**31 - 1))
        reach = plan(ck, HOME_QPOS, q_pre, self.planner_cfg, seed)
        seconds["reach"] = reach.seconds
        if reach.path is None:
            counts["plan_failed"] += 1
            return None
        ck.attach(Attachment(self.pick_body, self.pick_adr, pose_obj_in_tool))
        carry = plan(ck, q_lift, q_preplace, self.planner_cfg, seed + 1)
        seconds["transport"] = carry.seconds
        ck.attach(None)
        if carry.path is None:
            counts["plan_failed"] += 1
            return None
        return self._timeline(
            qpos,
            reach.path,
            q_pre,
            q_grasp,
            q_lift,
            carry.path,
            q_preplace,
            q_place,
            q_retreat,
            g.width,
            seconds,
        )

    @property
    def _target_xy(self) -> np.ndarray:
        return np.array(self.checker.base[self._target_adr : self._target_adr + 2])

    @property
    def _target_adr(self) -> int:
        return int(self.model.jnt_qposadr[self.model.body_jntadr[self.target_body]])

    def _timeline(
        self,
        qpos: np.ndarray,
        reach: np.ndarray,
        q_pre: np.ndarray,
        q_grasp: np.ndarray,
        q_lift: np.ndarray,
        carry: np.ndarray,
        q_preplace: np.ndarray,
        q_place: np.ndarray,
        q_retreat: np.ndarray,
        width: float,
        seconds: dict[str, float],
    ) -> EpisodePlan:
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

        def move(name: str, path: np.ndarray, limits: Limits, opening: float) -> None:
            phases[name] = len(arm)
            timed = time_path(path, limits, dt)
            arm.extend(list(timed.q[1:]))
            vel.extend(list(timed.qd[1:]))
            grip.extend([opening] * (len(timed.q) - 1))

        hold("settle", HOME_QPOS, mo.settle, GRIP_OPEN)
        move("reach", reach, self.fast, GRIP_OPEN)
        move("approach", np.stack([q_pre, q_grasp]), self.slow, GRIP_OPEN)
        hold("close", q_grasp, mo.close, GRIP_CLOSED)
        move("lift", np.stack([q_grasp, q_lift]), self.slow, GRIP_CLOSED)
        move("transport", carry, self.fast, GRIP_CLOSED)
        move("lower", np.stack([q_preplace, q_place]), self.slow, GRIP_CLOSED)
        hold("release", q_place, mo.release, GRIP_OPEN)
        move("retreat", np.stack([q_place, q_retreat]), self.slow, GRIP_OPEN)
        hold("hold", q_retreat, mo.hold, GRIP_OPEN)
        phases["end"] = len(arm)
        ctrl = targets_to_ctrl(self.model, self.robot, np.asarray(arm), np.asarray(vel), grip)
        targets = np.concatenate([np.asarray(arm), np.asarray(grip)[:, None]], axis=1)
        return EpisodePlan(qpos, ctrl, targets, phases, width, seconds, 0.0, 0)


def targets_to_ctrl(
    model: mujoco.MjModel,
    robot: RobotIndex,
    arm: np.ndarray,
    vel: np.ndarray,
    grip: Sequence[float] | np.ndarray,
) -> np.ndarray:
    """The controller: joint targets -> actuator controls, per physics step.

    The arm's PD position actuators get the desired joint positions plus a velocity lead
    (``kv/kp * qd``, so that they track a moving target without lag); the fingers get the
    targets of the gripper command. Controls are clipped to the actuators' ranges.

    Args:
        model, robot: the composed model and its robot index.
        arm: desired arm joint positions (T, 7) rad; vel: their velocities (T, 7) rad/s.
        grip: gripper commands (T,): total opening (m), negative squeezes.

    Returns:
        ctrl (T, nu).
    """
    lead = -model.actuator_biasprm[robot.ctrl_arm, 2] / model.actuator_gainprm[robot.ctrl_arm, 0]
    ctrl = np.zeros((len(arm), model.nu))
    ctrl[:, robot.ctrl_arm] = arm + lead * vel
    ctrl[:, robot.ctrl_fingers] = robot.gripper_ctrls(np.asarray(grip, float).reshape(-1))
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    return np.clip(ctrl, lo, hi)
