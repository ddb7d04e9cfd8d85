"""The mobile task's scene: task objects, the scene composed with the mobile robot, geometry.

:func:`mobile_task_objects` finds the object to move, what it stands on and where it goes;
:func:`mobile_setup` compiles the scene with the Panda on the Omron base
(:mod:`factory.demos.mobile_robot`, :func:`compose_mobile`) and rasterizes its occupancy grid
(:mod:`factory.nav`). When the base cannot stand where its arm reaches the object or the
place support, or cannot drive from one to the other, the light floor objects in the way
(chairs, stools, lamps, plants, bins) are taken out of the scene, as the fixed task does for
chairs around its table (:func:`clear_for_base`); what was taken out is named in the set-up's
``cleared``.

Frames: world frame (m, rad); a base pose is the footprint centre's (x, y) and the yaw.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, cast

import mujoco
import numpy as np

from factory.demos.grasps import collision_pieces
from factory.demos.mobile_robot import (
    ARM_MOUNT,
    BASE_FOOTPRINT,
    CAMERAS,
    FISHEYE_CAMERA_QUAT,
    FISHEYE_MOUNTS,
    FOOTPRINT_RADIUS,
    PREFIX,
    MobileRobotIndex,
    add_mobile_robot,
)
from factory.demos.robot import pose_matrix, rot_z
from factory.errors import TaskError
from factory.nav import (
    BASE_COLLISION,
    NAV_FAILED,
    BasePose,
    Footprint,
    OccupancyGrid,
    work_poses,
)
from factory.nav.grid import geom_points

if TYPE_CHECKING:
    from factory.schema import Scene, SceneObject

log = logging.getLogger(__name__)

SUBTASKS: tuple[str, str, str, str] = ("navigate_to_pick", "pick", "navigate_to_place", "place")
"""Sub-task labels, in order; a step's label id is its index here."""

NO_SPAWN = "no_spawn"
NO_PLACE_SUPPORT = "no_place_support"
COLLISION = "collision"
PLAN_TIMEOUT = "plan_timeout"
REASONS: tuple[str, ...] = (
    NAV_FAILED,
    BASE_COLLISION,
    NO_SPAWN,
    NO_PLACE_SUPPORT,
    PLAN_TIMEOUT,
    "no_grasp",
    "ik_failed",
    "plan_failed",
    "approach_collision",
    "lift_collision",
    "retreat_collision",
)
"""Planning failure reasons (the grasp/IK ones are the fixed-base task's; ``plan_timeout``: the
episode's planning time budget ran out before a plan was found)."""

IMPRATIO = 10.0
"""Ratio of frictional to normal contact impedance of the mobile task's model (elliptic cones):
friction "harder" than contact, so a held object does not creep (see :func:`compose_mobile`)."""

NOSLIP_ITERATIONS = 5
"""Iterations of MuJoCo's no-slip solver in the mobile task's model: friction without the
soft constraints' creep (see :func:`compose_mobile`)."""

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
        scene: the scene (without the objects in ``cleared``); objects: its task objects.
        model: the composed model (robot, recording cameras, fisheye cameras).
        robot: the robot's addresses in it.
        grid: the occupancy grid of the scene (robot left out), not inflated.
        nav_grid: ``grid`` inflated by ``FOOTPRINT_RADIUS``: where the base centre may be at
            any yaw.
        arm_mount: pose (4, 4) of the arm's IK frame (link0) in the base frame.
        footprint: the base's outline with the arm stowed (poses and drives are checked with
            it on ``grid``).
        cleared: ids of the scene's objects taken out to make room for the base.
        reachable: ``""`` when a base pose within reach of the object and one within reach of
            the place support's top lie in one free region of ``grid`` for ``footprint``, else
            why not (the planner then fails every episode at once with ``nav_failed``).
    """

    scene: Scene
    objects: MobileTaskObjects
    model: mujoco.MjModel
    robot: MobileRobotIndex
    grid: OccupancyGrid
    nav_grid: OccupancyGrid
    arm_mount: np.ndarray
    footprint: Footprint = BASE_FOOTPRINT
    cleared: tuple[str, ...] = ()
    reachable: str = ""


def compose_mobile(
    scene: Scene,
    assets_root: str | Path | None = None,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> mujoco.MjModel:
    """Compiles a scene with the mobile robot at ``pose`` (x, y m, yaw rad; its ``qpos0``) and
    a camera in each fisheye mount (``mobile/fisheye_front``, ``mobile/fisheye_back``).

    Island sleeping is on (bodies at rest cost nothing until touched); friction cones are
    elliptic with ``impratio`` :data:`IMPRATIO` and the no-slip solver runs
    :data:`NOSLIP_ITERATIONS` iterations, so that an object carried for tens of seconds stays
    where the hand holds it."""
    from factory.sim.compile import compile_scene

    compiled = compile_scene(scene, assets_root)
    spec = compiled.spec
    add_mobile_robot(spec, pose)
    for name, mount in FISHEYE_MOUNTS.items():
        spec.body(mount).add_camera(name=FISHEYE_CAMERAS[name], quat=list(FISHEYE_CAMERA_QUAT))
    # Objects at rest sleep until something touches them (MuJoCo's island sleeping, as the
    # fixed task's ``compose``): a generated room's furniture then costs almost nothing.
    spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    # Elliptic friction cones with impratio 10 and the no-slip solver (MuJoCo's advice against
    # slip in grasping): with the default soft pyramidal cones the object creeps in the closed
    # hand over a carry of tens of seconds (1-2 mm/s even at constant speed, more in every
    # turn of the base) until it falls out.
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = IMPRATIO
    spec.option.noslip_iterations = NOSLIP_ITERATIONS
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
    clear: bool = True,
) -> MobileSetup:
    """Composes the scene with the robot, rasterizes its occupancy grid and, where the base
    cannot work at both supports, takes light floor objects out of the way.

    Args:
        scene: the scene.
        assets_root: the run's assets folder (None: objects are boxes).
        objects: the task objects; default :func:`mobile_task_objects`.
        resolution: grid cell side (m).
        clear: take movable floor objects out when the task is not reachable
            (:func:`clear_for_base`); the set-up's ``cleared`` names them.

    Raises:
        TaskError: the task objects are missing.
    """
    objects = objects or mobile_task_objects(scene)
    model = compose_mobile(scene, assets_root)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    grid = OccupancyGrid.from_model(model, data, resolution=resolution)
    why = reachability(model, data, grid, objects, BASE_FOOTPRINT)
    cleared: set[str] = set()
    if why and clear:
        cleared = clear_for_base(model, data, scene, objects, BASE_FOOTPRINT, resolution)
        if cleared:
            log.info(
                "scene %s: took out %s to make room for the robot's base (%s)",
                scene.id,
                sorted(cleared),
                why,
            )
            scene = replace(scene, objects=[o for o in scene.objects if o.id not in cleared])
            model = compose_mobile(scene, assets_root)
            data = mujoco.MjData(model)
            mujoco.mj_kinematics(model, data)
            grid = OccupancyGrid.from_model(model, data, resolution=resolution)
            why = reachability(model, data, grid, objects, BASE_FOOTPRINT)
    if why:
        log.warning("scene %s: the mobile task is not reachable: %s", scene.id, why)
    robot = MobileRobotIndex.of(model)
    return MobileSetup(
        scene=scene,
        objects=objects,
        model=model,
        robot=robot,
        grid=grid,
        nav_grid=grid.inflate(FOOTPRINT_RADIUS),
        arm_mount=_arm_mount(model, robot),
        footprint=BASE_FOOTPRINT,
        cleared=tuple(sorted(cleared)),
        reachable=why,
    )


# ---------------------------------------------------------------------------------------------
# Where the base can work, and making room for it

ARM_X = ARM_MOUNT[0]
"""The arm's base (link0) ahead of the base origin (m, base frame)."""
PICK_REACH: tuple[float, float] = (0.3, 0.75)
"""Horizontal distance (m) from the arm's base to the object within which a pick is tried."""
PLACE_REACH: tuple[float, float] = (0.3, 0.7)
"""Horizontal distance (m) from the arm's base to a place point within which a place is
tried."""
CARRY_TOOL: tuple[float, float, float] = (0.35, 0.0, 1.05)
"""Tool position (m, base frame) while driving with the object: above the base's front,
pointing down."""
MAX_CLEARED = 3
"""Most objects :func:`clear_for_base` takes out."""


def movable(obj: SceneObject) -> bool:
    """Floor objects light enough to move aside (chairs, stools, lamps, plants, bins), not
    fixtures or heavy furniture (the fixed task's rule)."""
    return (
        not obj.is_static
        and obj.placement.kind == "floor"
        and obj.physics.mass <= 25.0
        and max(obj.dimensions.width, obj.dimensions.length) <= 1.0
    )


def place_targets(
    box: np.ndarray, obj_radius: float, margin: float = 0.04, spacing: float = 0.15
) -> np.ndarray:
    """Points (n, 2) of a support's top where the object's centre may go: a grid every
    ``spacing`` (m) inside the top's box (6,) shrunk by the object's radius and ``margin``
    (m); the middle of the box when it is too small for a grid."""
    lo = box[:2] + obj_radius + margin
    hi = box[3:5] - obj_radius - margin
    if (hi < lo).any():
        return np.array([[(box[0] + box[3]) / 2, (box[1] + box[4]) / 2]])
    axes = [
        np.linspace(lo[i], hi[i], max(1, int(np.floor((hi[i] - lo[i]) / spacing)) + 1))
        for i in range(2)
    ]
    gx, gy = np.meshgrid(*axes, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def object_radius(obj: SceneObject) -> float:
    """Half the diagonal of an object's footprint (m)."""
    return 0.5 * float(np.hypot(obj.dimensions.width, obj.dimensions.length))


def carry_footprint(
    footprint: Footprint, obj: SceneObject, carry_x: float = CARRY_TOOL[0]
) -> Footprint:
    """The base's footprint while it carries ``obj`` in the hand ``carry_x`` (m) ahead of its
    origin: the front lengthened to cover the object (and 2 cm)."""
    front = carry_x + object_radius(obj) + 0.02
    return replace(footprint, front=max(footprint.front, front))


def task_work_poses(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    grid: OccupancyGrid,
    objects: MobileTaskObjects,
    footprint: Footprint,
    start_xy: np.ndarray | None = None,
) -> tuple[list[BasePose], list[BasePose]]:
    """Base poses within reach of the object to pick and of the place support's top, best
    first (:func:`factory.nav.work_poses`; with ``start_xy`` only those a path may join).

    Both are checked with the footprint lengthened by the carried object
    (:func:`carry_footprint`): the base leaves the pick pose and arrives at the place pose
    with the object in the hand."""
    pick = model.body(objects.pick.id).id
    pick_box = body_box(model, data, model.body(objects.pick_support.id).id)
    place_box = body_box(model, data, model.body(objects.place_support.id).id)
    pick_xy = np.array(data.xpos[pick][:2])
    footprint = carry_footprint(footprint, objects.pick)
    pick_poses = work_poses(
        grid, footprint, _xy_box(pick_box), ARM_X, pick_xy[None], PICK_REACH, start_xy
    )
    targets = place_targets(place_box, object_radius(objects.pick))
    place_poses = work_poses(
        grid, footprint, _xy_box(place_box), ARM_X, targets, PLACE_REACH, start_xy
    )
    return pick_poses, place_poses


def reachability(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    grid: OccupancyGrid,
    objects: MobileTaskObjects,
    footprint: Footprint,
) -> str:
    """``""`` when some base pose within reach of the object and some within reach of the
    place support share a free region of ``grid`` for ``footprint`` (necessary for an
    episode), else why not, in words naming the fix."""
    picks, places = task_work_poses(model, data, grid, objects, footprint)
    if not picks:
        return (
            f"no free base pose within reach of {objects.pick.id!r} on "
            f"{objects.pick_support.id!r}: leave ~0.6 m free beside it"
        )
    if not places:
        return (
            f"no free base pose within reach of the top of {objects.place_support.id!r}: "
            "leave ~0.6 m free beside it"
        )
    inscribed = footprint.inscribed_grid(grid)
    a = {int(inscribed.component(p.xy)) for p in picks}
    b = {int(inscribed.component(p.xy)) for p in places}
    if not (a & b):
        return (
            f"no free route between {objects.pick_support.id!r} and "
            f"{objects.place_support.id!r} for the base (0.58 m wide): leave a corridor"
        )
    return ""


def clear_for_base(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    scene: Scene,
    objects: MobileTaskObjects,
    footprint: Footprint,
    resolution: float = 0.05,
    max_objects: int = MAX_CLEARED,
    candidates: int = 8,
) -> set[str]:
    """The fewest light floor objects (:func:`movable`) whose removal makes the task
    reachable (:func:`reachability`), or an empty set when up to ``max_objects`` of the
    ``candidates`` nearest to the two supports do not.

    Generated rooms are furnished without a robot in mind: an armchair beside the desk or a
    lamp in the only gap can close the way for a base 0.58 m wide. A person would move them;
    so does this, trying single objects, then pairs, then triples, nearest first (with what
    stands on them). Only the occupancy grid is recomputed per try (the model is not).
    """
    from itertools import combinations

    keep = {objects.pick.id, objects.pick_support.id, objects.place_support.id}
    sup = [objects.pick_support, objects.place_support]

    def dist(o: SceneObject) -> float:
        return min(
            float(np.hypot(o.position.x - s.position.x, o.position.y - s.position.y)) for s in sup
        )

    pool = sorted(
        (o for o in scene.objects if o.id not in keep and movable(o) and dist(o) < 2.5),
        key=dist,
    )[:candidates]
    for n in range(1, max_objects + 1):
        for combo in combinations(pool, n):
            ids = scene.with_dependents({o.id for o in combo})
            if ids & keep:
                continue
            bodies = [model.body(i).id for i in ids if _has_body(model, i)]
            grid = OccupancyGrid.from_model(
                model, data, resolution=resolution, exclude_bodies=bodies
            )
            if not reachability(model, data, grid, objects, footprint):
                return set(ids)
    return set()


def _has_body(model: mujoco.MjModel, name: str) -> bool:
    try:
        model.body(name)
    except KeyError:
        return False
    return True


def _xy_box(box: np.ndarray) -> tuple[float, float, float, float]:
    return float(box[0]), float(box[1]), float(box[3]), float(box[4])


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
