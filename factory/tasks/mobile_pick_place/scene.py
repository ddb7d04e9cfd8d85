"""The mobile task's scene: task objects, the scene composed with the mobile robot, geometry.

:func:`mobile_task_objects` finds the object to move, what it stands on and where it goes;
:func:`mobile_setup` compiles the scene with the Panda on the Omron base
(:mod:`factory.robots.mobile_panda`, :func:`compose_mobile`) and rasterizes its occupancy grid
(:mod:`factory.nav`) and judges the route between the supports as the scene checks do
(:func:`factory.nav.route.task_route` on :func:`factory.nav.task_poses.task_grid`: the same
grid, footprint and work poses), keeping the base poses it verified (``MobileSetup.route``):
the planner drives to those only. When the base cannot stand where its arm reaches the object
or the place support, or cannot drive from one to the other, the light floor objects in the way
(chairs, stools, lamps, plants, bins) are taken out of the scene, as the fixed task does for
chairs around its table (:func:`factory.nav.route.clear_for_base`); what was taken out is
named in the set-up's ``cleared``. Where the base works (work poses, supports, reach) is
:mod:`factory.nav.task_poses`, shared with the scene checks' route check
(:mod:`factory.nav.route`); its names are re-exported here.

Frames: world frame (m, rad); a base pose is the footprint centre's (x, y) and the yaw.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, cast

import mujoco
import numpy as np

from factory.demos.plan.grasps import collision_pieces
from factory.errors import TaskError
from factory.nav import BASE_COLLISION, NAV_FAILED, Footprint, OccupancyGrid
from factory.nav.route import (
    MAX_CLEARED,
    TaskRoute,
    clear_for_base,
    movable,
    reachability,
    task_route,
)
from factory.nav.task_poses import (
    ARM_X,
    CARRY_X,
    GRID_RESOLUTION,
    NO_PLACE_SUPPORT,
    PICK_REACH,
    PLACE_REACH,
    MobileTaskObjects,
    SupportTop,
    TaskSupportError,
    body_box,
    carry_footprint,
    object_radius,
    resolve_supports,
    task_grid,
    task_work_poses,
)
from factory.robots.mobile_panda import (
    BASE_FOOTPRINT,
    CAMERAS,
    FISHEYE_CAMERA_QUAT,
    FISHEYE_MOUNTS,
    PREFIX,
    MobileRobotIndex,
    add_mobile_robot,
)
from factory.robots.panda import pose_matrix, rot_z

if TYPE_CHECKING:
    from factory.schema import Scene

log = logging.getLogger(__name__)

SUBTASKS: tuple[str, str, str, str] = ("navigate_to_pick", "pick", "navigate_to_place", "place")
"""Sub-task labels, in order; a step's label id is its index here."""

NO_SPAWN = "no_spawn"
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


def mobile_task_objects(
    scene: Scene,
    pick: str | None = None,
    pick_support: str | None = None,
    place_support: str | None = None,
) -> MobileTaskObjects:
    """The pick object, its support and the place support of a scene.

    Without ids, they are read as :func:`factory.tasks.pick_place.objects.task_objects` reads them
    (objects
    with ``task_role`` ``pick`` / ``place_target``, else the task instruction); the supports
    then as :func:`factory.nav.task_poses.resolve_supports` finds them: the pick's support is
    what it stands on; the place support is an object with ``task_role`` ``place_support``,
    else the target when it stands on the floor (a desk), else what the target stands on (the
    desk under a tray).

    Raises:
        TaskError: no pick object or it stands on nothing.
        MobileTaskError: no place support (reason ``no_place_support``), or it is the pick's
            own support.
    """
    from factory.tasks.pick_place.objects import task_objects

    by_id = {o.id: o for o in scene.objects}
    role_support = any(o.task_role == "place_support" for o in scene.objects)
    target = None
    if pick is None or (place_support is None and not role_support):
        try:
            objs = task_objects(scene)
            target = objs.target
            pick = pick or objs.pick.id
        except TaskError:
            if pick is None:
                pick = next((o.id for o in scene.objects if o.task_role == "pick"), None)
                if pick is None:
                    raise
    if pick not in by_id:
        raise MobileTaskError(f"scene {scene.id!r} has no pick object {pick!r}")
    if pick_support is not None and pick_support not in by_id:
        raise MobileTaskError(f"scene {scene.id!r} has no pick support {pick_support!r}")
    try:
        return resolve_supports(scene, by_id[pick], target, pick_support, place_support)
    except TaskSupportError as e:
        reason = NO_PLACE_SUPPORT if e.reason == NO_PLACE_SUPPORT else ""
        raise MobileTaskError(str(e), reason) from None


@dataclass
class MobileSetup:
    """A scene composed with the mobile robot, ready for planning.

    Attributes:
        scene: the scene (without the objects in ``cleared``); objects: its task objects.
        model: the composed model (robot, recording cameras, fisheye cameras).
        robot: the robot's addresses in it.
        grid: the occupancy grid of the scene (robot left out), not inflated.
        arm_mount: pose (4, 4) of the arm's IK frame (link0) in the base frame.
        footprint: the base's outline with the arm stowed (poses and drives are checked with
            it on ``grid``).
        cleared: ids of the scene's objects taken out to make room for the base.
        reachable: ``""`` when the route holds (``route``), else why not (the planner then
            fails every episode at once with ``nav_failed``).
        route: the route check's verdict on ``grid`` with ``footprint``
            (:func:`factory.nav.route.task_route`) and the base poses it verified: the
            planner's goals (None only for a set-up made by hand).
    """

    scene: Scene
    objects: MobileTaskObjects
    model: mujoco.MjModel
    robot: MobileRobotIndex
    grid: OccupancyGrid
    arm_mount: np.ndarray
    footprint: Footprint = BASE_FOOTPRINT
    cleared: tuple[str, ...] = ()
    reachable: str = ""
    route: TaskRoute | None = None


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
    from factory.robots.panda import robot_model

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
    resolution: float = GRID_RESOLUTION,
    clear: bool = True,
) -> MobileSetup:
    """Composes the scene with the robot, rasterizes its occupancy grid, judges the route
    between the supports as the route check does and, where it does not hold, takes light
    floor objects out of the way.

    The grid is :func:`~factory.nav.task_poses.task_grid` (the robot left out) and the route
    :func:`~factory.nav.route.task_route` with the robot's footprint: what
    :func:`factory.nav.route.check_route` computes on the scene compiled without the robot,
    cell for cell, so the set-up's ``route`` holds the poses the route check verified.

    Args:
        scene: the scene.
        assets_root: the run's assets folder (None: objects are boxes).
        objects: the task objects; default :func:`mobile_task_objects`.
        resolution: grid cell side (m); the route check's by default
            (:data:`~factory.nav.task_poses.GRID_RESOLUTION`).
        clear: take movable floor objects out when the route does not hold
            (:func:`clear_for_base`); the set-up's ``cleared`` names them.

    Raises:
        TaskError: the task objects are missing.
    """
    objects = objects or mobile_task_objects(scene)
    model = compose_mobile(scene, assets_root)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    grid = task_grid(model, data, resolution=resolution)
    route = task_route(model, data, grid, objects, BASE_FOOTPRINT)
    cleared: set[str] = set()
    if route.reason and clear:
        cleared = clear_for_base(model, data, scene, objects, BASE_FOOTPRINT, resolution)
        if cleared:
            log.info(
                "scene %s: took out %s to make room for the robot's base (%s)",
                scene.id,
                sorted(cleared),
                route.detail,
            )
            scene = replace(scene, objects=[o for o in scene.objects if o.id not in cleared])
            model = compose_mobile(scene, assets_root)
            data = mujoco.MjData(model)
            mujoco.mj_kinematics(model, data)
            grid = task_grid(model, data, resolution=resolution)
            route = task_route(model, data, grid, objects, BASE_FOOTPRINT)
    if route.reason:
        log.warning("scene %s: the mobile task is not reachable: %s", scene.id, route.detail)
    robot = MobileRobotIndex.of(model)
    return MobileSetup(
        scene=scene,
        objects=objects,
        model=model,
        robot=robot,
        grid=grid,
        arm_mount=_arm_mount(model, robot),
        footprint=BASE_FOOTPRINT,
        cleared=tuple(sorted(cleared)),
        reachable=route.detail,
        route=route,
    )


# ---------------------------------------------------------------------------------------------
# Where the base can work, and making room for it

CARRY_TOOL: tuple[float, float, float] = (CARRY_X, 0.0, 1.05)
"""Tool position (m, base frame) while driving with the object: above the base's front,
pointing down."""

# Where the base can work (:mod:`factory.nav.task_poses`) and making room for it
# (:mod:`factory.nav.route`) are shared with the scene checks; their names stay importable
# from here: ARM_X, PICK_REACH, PLACE_REACH, MAX_CLEARED, movable,
# object_radius, carry_footprint, task_work_poses, reachability, clear_for_base, body_box,
# SupportTop.


def base_matrix(pose: np.ndarray) -> np.ndarray:
    """The base frame (4, 4) in the world for a base pose (3,): x, y (m), yaw (rad)."""
    return pose_matrix(np.array([pose[0], pose[1], 0.0]), rot_z(float(pose[2])))


def support_top(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> float:
    """World height (m) of a support's top at its centre: the topmost surface on the vertical
    line through the middle of its box (the fixed task's ``_surface_height`` there)."""
    from factory.demos.plan.grasps import _line_intervals

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


__all__ = [
    "ALL_CAMERAS",
    "ARM_X",
    "CARRY_TOOL",
    "COLLISION",
    "FISHEYE_CAMERAS",
    "IMPRATIO",
    "MAX_CLEARED",
    "NOSLIP_ITERATIONS",
    "NO_PLACE_SUPPORT",
    "NO_SPAWN",
    "PICK_REACH",
    "PLACE_REACH",
    "PLAN_TIMEOUT",
    "REASONS",
    "SUBTASKS",
    "MobileSetup",
    "MobileTaskError",
    "MobileTaskObjects",
    "SupportTop",
    "TaskRoute",
    "base_matrix",
    "body_box",
    "carry_footprint",
    "clear_for_base",
    "compose_mobile",
    "mobile_setup",
    "mobile_task_objects",
    "movable",
    "object_radius",
    "reachability",
    "support_top",
    "task_route",
    "task_work_poses",
]
