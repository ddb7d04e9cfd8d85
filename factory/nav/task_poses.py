"""Where a mobile manipulator's base works for a pick-and-place between two supports.

The mobile task moves an object from one support (a coffee table) to another (a desk). Its
base must stand, arm stowed, somewhere its arm reaches the object, and somewhere its arm
reaches the place support's top, with the object in the hand. This module holds what the
demos (``factory.tasks.mobile_pick_place.scene``) and the scene checks (:mod:`factory.nav.route`)
share:
the task's objects read from their ``task_role``, the supports' boxes in a compiled model,
the points of a top where the object may go, and the base poses within reach of both
(:func:`task_work_poses`, over :func:`factory.nav.goals.work_poses`).

The grid both plan on is :func:`task_grid` (cell :data:`GRID_RESOLUTION`, height band
:data:`GRID_Z_BAND`): the route check, the demos' SE(2) base planner, their spawn and work
poses and :func:`factory.nav.route.clear_for_base` all take it from here, with the footprint
below, so a scene that passes the route check is judged by the demos on the same cells.

The robot's geometry enters as numbers: :data:`MOBILE_FOOTPRINT` and :data:`ARM_X` are the
mobile robot's (``factory.robots.mobile_panda.BASE_FOOTPRINT`` and ``ARM_MOUNT[0]``; this
package does not import the robot, and a test keeps them equal).

Frames: world frame, metres, radians; a base pose is the footprint centre's (x, y) and yaw.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from factory.errors import TaskError
from factory.nav.errors import NavError
from factory.nav.footprint import Footprint
from factory.nav.goals import BasePose, work_poses
from factory.nav.grid import OccupancyGrid, geom_points

if TYPE_CHECKING:
    from factory.schema import Scene, SceneObject

MOBILE_FOOTPRINT = Footprint(rear=0.35, front=0.40, half_width=0.25, margin=0.04)
"""The mobile robot's outline from above with the arm stowed (base frame, m): the wheeled
body (0.70 x 0.50 m) and the stowed hand ahead of it, 4 cm all round (the robot's
``BASE_FOOTPRINT``)."""
ARM_X = 0.20
"""The arm's base (link0) ahead of the base origin (m, base frame; the robot's
``ARM_MOUNT[0]``)."""
PICK_REACH: tuple[float, float] = (0.3, 0.75)
"""Horizontal distance (m) from the arm's base to the object within which a pick is tried."""
PLACE_REACH: tuple[float, float] = (0.3, 0.7)
"""Horizontal distance (m) from the arm's base to a place point within which a place is
tried."""
CARRY_X = 0.35
"""How far ahead of the base origin (m, base frame) the hand holds the object while driving."""
PLACE_MARGIN = 0.04
"""Clearance (m) between a placed object's footprint circle and the edge of the top."""

GRID_RESOLUTION = 0.05
"""Cell side (m) of the mobile task's occupancy grid (:func:`task_grid`): the route check's
and the demos' alike. The base's footprint is checked against the grid's distance transform to
within half a cell, and the SE(2) lattice of the route check steps one cell."""
GRID_Z_BAND: tuple[float, float] = (0.02, 1.9)
"""Heights (m, world z) of the mobile robot: collision geometry overlapping this band is an
obstacle of :func:`task_grid` (the floor slab below it and a door's lintel above it are not)."""

NO_PICK_OBJECT = "no_pick_object"
NO_PLACE_SUPPORT = "no_place_support"


class TaskSupportError(NavError):
    """The scene lacks an object of the mobile task (the pick object, what it stands on, or
    the place support).

    Attributes:
        reason: ``no_pick_object`` or ``no_place_support``.
    """

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


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


def resolve_supports(
    scene: Scene,
    pick: SceneObject,
    target: SceneObject | None = None,
    pick_support: str | None = None,
    place_support: str | None = None,
) -> MobileTaskObjects:
    """The task's supports for a known pick object.

    The pick's support is ``pick_support`` or what it stands on; the place support is
    ``place_support``, else the object with ``task_role`` ``place_support``, else the
    ``target`` when it stands on the floor (a desk), else what the target stands on (the desk
    under a tray).

    Raises:
        TaskSupportError: the pick stands on nothing (``no_pick_object``); no place support,
            or it is the pick's own support (``no_place_support``).
    """
    by_id = {o.id: o for o in scene.objects}
    sid = pick_support or pick.placement.support_id
    if not sid or sid not in by_id:
        raise TaskSupportError(
            f"scene {scene.id!r}: pick object {pick.id!r} stands on no support", NO_PICK_OBJECT
        )
    if place_support is None:
        role = next((o for o in scene.objects if o.task_role == "place_support"), None)
        if role is not None:
            place_support = role.id
        elif target is not None:
            on = target.placement.support_id
            floor = target.placement.kind == "floor" or not on or on not in by_id
            place_support = target.id if floor else on
    if place_support is None:
        raise TaskSupportError(
            f"scene {scene.id!r}: no place support (give an object task_role 'place_support' "
            "or 'place_target')",
            NO_PLACE_SUPPORT,
        )
    if place_support not in by_id:
        raise TaskSupportError(
            f"scene {scene.id!r} has no place support {place_support!r}", NO_PLACE_SUPPORT
        )
    if place_support == sid:
        raise TaskSupportError(
            f"scene {scene.id!r}: the place support {place_support!r} is the pick's own support",
            NO_PLACE_SUPPORT,
        )
    return MobileTaskObjects(pick, by_id[sid], by_id[place_support])


def role_objects(scene: Scene) -> MobileTaskObjects:
    """The task objects named by ``task_role``: ``pick``, and ``place_support`` (or
    ``place_target``, see :func:`resolve_supports`).

    Raises:
        TaskSupportError: an object is missing (the reason says which).
    """
    pick = next((o for o in scene.objects if o.task_role == "pick"), None)
    if pick is None:
        raise TaskSupportError(
            f"scene {scene.id!r} has no object with task_role 'pick'", NO_PICK_OBJECT
        )
    target = next((o for o in scene.objects if o.task_role == "place_target"), None)
    return resolve_supports(scene, pick, target)


def body_box(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> np.ndarray:
    """World axis-aligned box (6,) of a body's colliding geoms: xmin, ymin, zmin, xmax, ymax,
    zmax (m); ``data`` needs current kinematics.

    Raises:
        TaskError: the body has no collision geometry.
    """
    collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    geoms = np.flatnonzero((model.geom_bodyid == body) & collides)
    if not len(geoms):
        raise TaskError(f"body {model.body(body).name!r} has no collision geometry")
    pts = np.concatenate([geom_points(model, data, int(g)) for g in geoms])
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


def xy_box(box: np.ndarray) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of a box (6,) from :func:`body_box` (m)."""
    return float(box[0]), float(box[1]), float(box[3]), float(box[4])


def object_radius(obj: SceneObject) -> float:
    """Half the diagonal of an object's footprint (m)."""
    return 0.5 * float(np.hypot(obj.dimensions.width, obj.dimensions.length))


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class SupportTop:
    """A support's top as the box of its colliding geoms in its own (upright) body frame, so
    that a desk turned by any yaw is its own rectangle, not the world box around it.

    Attributes:
        origin: the body's world position (x, y) (m), (2,).
        rot: the body's heading as a planar rotation (2, 2), body -> world.
        lo, hi: the box's corners (x, y) in the body frame (m), (2,) each.
        top: the box's top, world z (m).
    """

    origin: np.ndarray
    rot: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    top: float

    @classmethod
    def of(cls, model: mujoco.MjModel, data: mujoco.MjData, body: int) -> SupportTop:
        """The top of ``body`` (``data`` needs current kinematics).

        Raises:
            TaskError: the body has no collision geometry.
        """
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        geoms = np.flatnonzero((model.geom_bodyid == body) & collides)
        if not len(geoms):
            raise TaskError(f"body {model.body(body).name!r} has no collision geometry")
        pts = np.concatenate([geom_points(model, data, int(g)) for g in geoms])
        xmat = np.asarray(data.xmat[body]).reshape(3, 3)
        local = (pts - data.xpos[body]) @ xmat
        yaw = math.atan2(xmat[1, 0], xmat[0, 0])
        c, s = math.cos(yaw), math.sin(yaw)
        return cls(
            origin=np.array(data.xpos[body][:2], float),
            rot=np.array([[c, -s], [s, c]]),
            lo=local[:, :2].min(axis=0),
            hi=local[:, :2].max(axis=0),
            top=float(pts[:, 2].max()),
        )

    def _inner(self, radius: float, margin: float) -> tuple[np.ndarray, np.ndarray]:
        return self.lo + radius + margin, self.hi - radius - margin

    def fits(self, radius: float, margin: float = PLACE_MARGIN) -> bool:
        """Whether an object of footprint radius ``radius`` (m) fits on the top with
        ``margin`` (m) to every edge."""
        lo, hi = self._inner(radius, margin)
        return bool((hi >= lo).all())

    def holds(self, xy: np.ndarray, radius: float, margin: float = PLACE_MARGIN) -> np.ndarray:
        """Whether an object of footprint radius ``radius`` centred at world points
        ``(..., 2)`` lies on the top with ``margin`` to every edge; bool ``(...)``."""
        lo, hi = self._inner(radius, margin)
        local = (np.asarray(xy, float) - self.origin) @ self.rot
        return np.asarray(((local >= lo) & (local <= hi)).all(axis=-1), bool)

    def points(
        self, radius: float, margin: float = PLACE_MARGIN, spacing: float = 0.15
    ) -> np.ndarray:
        """World points (n, 2) where the object's centre may go: a grid every ``spacing``
        (m) inside the top shrunk by ``radius`` and ``margin`` (m); the top's middle when it
        is too small for a grid."""
        lo, hi = self._inner(radius, margin)
        if (hi < lo).any():
            local = ((self.lo + self.hi) / 2)[None]
        else:
            axes = [
                np.linspace(lo[i], hi[i], max(1, int(np.floor((hi[i] - lo[i]) / spacing)) + 1))
                for i in range(2)
            ]
            gx, gy = np.meshgrid(*axes, indexing="ij")
            local = np.stack([gx.ravel(), gy.ravel()], axis=1)
        return np.asarray(local @ self.rot.T + self.origin, float)


def task_grid(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    exclude_bodies: Iterable[int] = (),
    resolution: float = GRID_RESOLUTION,
) -> OccupancyGrid:
    """The mobile task's raw occupancy grid of a scene: its collision geometry in the robot's
    band :data:`GRID_Z_BAND`, cells of ``resolution`` (m), the robots and ``exclude_bodies``
    (body ids, with their descendants) left out (:meth:`OccupancyGrid.from_model`).

    The route check builds it from the compiled scene, the demos from the scene composed with
    the robot (whose bodies are left out): the same cells. Obstacles are not inflated here;
    the footprint's discs are checked against the grid's clearance
    (:meth:`~factory.nav.footprint.Footprint.free`), and connectivity is judged on the grid
    inflated by one disc (:meth:`~factory.nav.footprint.Footprint.inscribed_grid`), by the
    route check and the base planner alike. ``data`` needs current kinematics.
    """
    return OccupancyGrid.from_model(
        model, data, resolution=resolution, z_band=GRID_Z_BAND, exclude_bodies=exclude_bodies
    )


def carry_footprint(footprint: Footprint, obj: SceneObject, carry_x: float = CARRY_X) -> Footprint:
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
    arm_x: float = ARM_X,
) -> tuple[list[BasePose], list[BasePose]]:
    """Base poses within reach of the object to pick and of the place support's top, best
    first (:func:`factory.nav.work_poses`; with ``start_xy`` only those a path may join).

    Both are checked with the footprint lengthened by the carried object
    (:func:`carry_footprint`): the base leaves the pick pose and arrives at the place pose
    with the object in the hand. The model's bodies are named by the objects' ids.
    """
    pick = model.body(objects.pick.id).id
    pick_box = body_box(model, data, model.body(objects.pick_support.id).id)
    place_box = body_box(model, data, model.body(objects.place_support.id).id)
    pick_xy = np.array(data.xpos[pick][:2])
    footprint = carry_footprint(footprint, objects.pick)
    pick_poses = work_poses(
        grid, footprint, xy_box(pick_box), arm_x, pick_xy[None], PICK_REACH, start_xy
    )
    place_body = model.body(objects.place_support.id).id
    targets = SupportTop.of(model, data, place_body).points(object_radius(objects.pick))
    place_poses = work_poses(
        grid, footprint, xy_box(place_box), arm_x, targets, PLACE_REACH, start_xy
    )
    return pick_poses, place_poses


__all__ = [
    "ARM_X",
    "CARRY_X",
    "GRID_RESOLUTION",
    "GRID_Z_BAND",
    "MOBILE_FOOTPRINT",
    "NO_PICK_OBJECT",
    "NO_PLACE_SUPPORT",
    "PICK_REACH",
    "PLACE_MARGIN",
    "PLACE_REACH",
    "MobileTaskObjects",
    "SupportTop",
    "TaskSupportError",
    "body_box",
    "carry_footprint",
    "object_radius",
    "resolve_supports",
    "role_objects",
    "task_grid",
    "task_work_poses",
    "xy_box",
]
