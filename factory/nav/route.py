"""The mobile task's route check: can the base work at both supports and drive between them?

A scene made for the mobile task (``task.kind == "mobile_pick_place"``, or an object with
``task_role`` ``place_support``) promises that the robot's base can stand within reach of the
object to pick, stand within reach of the place support's top, and drive from one to the
other. :func:`check_route` verifies that on the scene's compiled model, in order, each
failure a reason:

``no_pick_object``
    no object with ``task_role`` ``pick``, or it stands on nothing;
``no_place_support``
    no place support, it is the pick's own support, or it has no collision geometry;
``place_support_too_close``
    the supports' centres are less than :data:`MIN_SUPPORT_SEPARATION` (1.5 m) apart: the
    place support must be "away from" the pick's (another part of the room, another room);
``place_support_too_small``
    the place support's top cannot hold the object (the top, shrunk by the object's footprint
    radius and 4 cm, is empty);
``no_spawn_area``
    the base's footprint fits nowhere on the floor;
``no_pick_pose`` / ``no_place_pose``
    no free base pose within reach of the object / of the place support's top;
``no_route``
    no pose within reach of the object and none within reach of the place support lie in one
    connected free region of the occupancy grid (the grid inflated by one of the footprint's
    discs: doors between rooms are free, so the region spans rooms), or none lie in one
    connected region of the base's free poses (x, y, heading) while it carries the object
    (:func:`se2_labels`: a lattice of the grid's cells and 32 headings, so turning to pass a
    door lengthwise counts; deterministic, no sampling planner).

Work poses, footprints and the grid (:func:`factory.nav.task_poses.task_grid`) are
:mod:`factory.nav.task_poses`'s. :func:`task_route` is the check's core and its result, a
:class:`TaskRoute`, holds the base poses it verified: the pick and place poses that share a region
of the carrying base's free poses. The demos (``factory.tasks.mobile_pick_place.scene``) compute the
same :class:`TaskRoute` on the same grid and drive only to those poses, so a scene that passes here
is not failed by the demos' navigation for another reason. :func:`clear_for_base` names the fewest
light floor objects whose removal opens the way (the demos take them out; generation removes them as
a last resort). Frames: world, metres.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from factory.errors import TaskError
from factory.nav.errors import NavError
from factory.nav.footprint import Footprint
from factory.nav.goals import BasePose
from factory.nav.grid import OccupancyGrid
from factory.nav.support_gap import MIN_SUPPORT_GAP, footprint_gap
from factory.nav.task_poses import (
    GRID_RESOLUTION,
    MOBILE_FOOTPRINT,
    NO_PICK_OBJECT,
    NO_PLACE_SUPPORT,
    MobileTaskObjects,
    SupportTop,
    TaskSupportError,
    carry_footprint,
    object_radius,
    role_objects,
    task_grid,
    task_work_poses,
)

if TYPE_CHECKING:
    from factory.schema import Scene, SceneObject

log = logging.getLogger(__name__)

"""``Task.kind`` of a scene made for the mobile task."""
MIN_SUPPORT_SEPARATION = 1.5
"""Least horizontal distance (m) between the centres of the pick's support and the place
support: what "away from" means for the mobile task (generation aims at about 2.5 m)."""
MAX_CLEARED = 3
"""Most objects :func:`clear_for_base` takes out."""

PLACE_SUPPORT_TOO_CLOSE = "place_support_too_close"
PLACE_SUPPORT_TOO_SMALL = "place_support_too_small"
NO_SPAWN_AREA = "no_spawn_area"
NO_PICK_POSE = "no_pick_pose"
NO_PLACE_POSE = "no_place_pose"
NO_ROUTE = "no_route"
ROUTE_REASONS: tuple[str, ...] = (
    NO_PICK_OBJECT,
    NO_PLACE_SUPPORT,
    PLACE_SUPPORT_TOO_CLOSE,
    PLACE_SUPPORT_TOO_SMALL,
    NO_SPAWN_AREA,
    NO_PICK_POSE,
    NO_PLACE_POSE,
    NO_ROUTE,
)
"""Every reason of a failed route check, in the order they are checked."""
BLOCKED: frozenset[str] = frozenset({NO_PICK_POSE, NO_PLACE_POSE, NO_ROUTE})
"""Reasons that taking light floor objects out may cure (:func:`clear_for_base`)."""


@dataclass(frozen=True)
class RouteCheck:
    """The verdict of :func:`check_route`.

    Attributes:
        reason: ``""`` when the check passes, else one of :data:`ROUTE_REASONS`.
        detail: the failure in words, naming the fix ("" when it passes).
        pick_support, place_support: the supports' ids ("" when unknown).
        separation: horizontal distance between the supports' centres (m), or None.
        gap: horizontal distance between the supports' footprints' nearest edges (m), or None.
        spawn_area: floor area (m²) where the base's footprint fits at some heading, or None.
        pick_poses, place_poses: free base poses within reach of the object / of the top.
        clear: light floor objects whose removal cures a blocked route (asked for).
        seconds: time the check took (s).
        route_pick_poses, route_place_poses: of those, the poses the route verified (they
            share a region of the carrying base's free poses with a pose at the other support).
        route: the :class:`TaskRoute` behind the verdict (the verified poses; None when the
            check stopped before the work poses); not in :meth:`as_dict`.
    """

    reason: str = ""
    detail: str = ""
    pick_support: str = ""
    place_support: str = ""
    separation: float | None = None
    gap: float | None = None
    spawn_area: float | None = None
    pick_poses: int = 0
    place_poses: int = 0
    clear: tuple[str, ...] = ()
    seconds: float = 0.0
    route_pick_poses: int = 0
    route_place_poses: int = 0
    route: TaskRoute | None = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        """Whether the check passed."""
        return not self.reason

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields, with ``passed`` (:attr:`ok`); without :attr:`route`."""
        names = [f for f in self.__dataclass_fields__ if f != "route"]
        out: dict[str, Any] = {f: getattr(self, f) for f in names}
        out["clear"] = list(self.clear)
        out["passed"] = self.ok
        for key in ("separation", "gap", "spawn_area", "seconds"):
            if out[key] is not None:
                out[key] = round(float(out[key]), 3)
        return out


def is_mobile_task(scene: Scene) -> bool:
    """Whether a scene is made for a task whose robot drives between supports (a registered
    task with :attr:`~factory.tasks.base.Task.drives_base` that claims the scene: its
    ``task.kind``, or an object in its place-support role), so that it needs a route."""
    from factory.tasks import tasks

    return any(task.drives_base and task.claims(scene) for task in tasks())


def support_gap(objects: MobileTaskObjects) -> float:
    """Horizontal distance (m) between the two supports' footprints' nearest edges
    (:func:`~factory.nav.support_gap.footprint_gap`)."""

    def box(o: SceneObject) -> tuple[float, float, float, float, float]:
        d = o.dimensions
        return (o.position.x, o.position.y, d.width / 2, d.length / 2, math.radians(o.rotation.z))

    return footprint_gap(box(objects.pick_support), box(objects.place_support))


def support_separation(objects: MobileTaskObjects) -> float:
    """Horizontal distance (m) between the centres of the two supports."""
    a, b = objects.pick_support.position, objects.place_support.position
    return math.hypot(a.x - b.x, a.y - b.y)


HEADINGS = 32
"""Headings of the SE(2) lattice (11.25 deg apart: a footprint point 0.8 m from the base's
centre moves 0.16 m per step, about half a footprint disc)."""


def free_poses(grid: OccupancyGrid, footprint: Footprint, headings: int = HEADINGS) -> np.ndarray:
    """Where the footprint is free: bool ``(headings, ny, nx)``, the base centred on a cell's
    centre at heading ``2 pi k / headings`` (only cells of the footprint's inscribed grid can
    be free)."""
    inscribed = footprint.inscribed_grid(grid)
    iy, ix = np.nonzero(~inscribed.occupied)
    out = np.zeros((headings, *grid.shape), bool)
    if not len(iy):
        return out
    xy = grid.cell_to_world(np.stack([ix, iy], axis=1))
    for k in range(headings):
        yaw = np.full((len(xy), 1), 2 * math.pi * k / headings)
        out[k, iy, ix] = footprint.free(grid, np.concatenate([xy, yaw], axis=1))
    return out


def spawn_area(free: np.ndarray, resolution: float) -> float:
    """Floor area (m²) of the cells where the base is free at some heading, from
    :func:`free_poses`."""
    return float(free.any(axis=0).sum()) * resolution**2


def se2_labels(free: np.ndarray) -> np.ndarray:
    """Connected regions of the free poses of :func:`free_poses`: int ``(headings, ny, nx)``,
    0 where not free. Neighbours are the 8 cells around at the same heading and the same cell
    at the next heading either way (headings wrap round)."""
    from scipy import ndimage

    structure = np.zeros((3, 3, 3), bool)
    structure[1] = True
    structure[0, 1, 1] = structure[2, 1, 1] = True
    labels, n = ndimage.label(free, structure=structure)
    labels = np.asarray(labels, np.int64)
    a, b = labels[0], labels[-1]
    pairs = {
        (int(x), int(y)) for x, y in zip(a[(a > 0) & (b > 0)], b[(a > 0) & (b > 0)], strict=True)
    }
    if not pairs:
        return labels
    root = np.arange(n + 1)

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = int(root[i])
        return i

    for x, y in sorted(pairs):
        rx, ry = find(x), find(y)
        if rx != ry:
            root[max(rx, ry)] = min(rx, ry)
    flat = np.array([find(i) for i in range(n + 1)])
    return np.asarray(flat[labels], np.int64)


def pose_labels(labels: np.ndarray, grid: OccupancyGrid, poses: list[BasePose]) -> set[int]:
    """The SE(2) regions (:func:`se2_labels`) that base poses fall in: each pose's cell and
    heading, and the cells and headings next to them (a pose between lattice points)."""
    headings = labels.shape[0]
    ny, nx = grid.shape
    out: set[int] = set()
    for p in poses:
        ix, iy = (int(v) for v in grid.world_to_cell(p.xy))
        k = round(p.yaw / (2 * math.pi / headings)) % headings
        ks = [(k + d) % headings for d in (-1, 0, 1)]
        y0, y1, x0, x1 = max(iy - 1, 0), min(iy + 2, ny), max(ix - 1, 0), min(ix + 2, nx)
        if y0 >= y1 or x0 >= x1:
            continue
        near = labels[ks, y0:y1, x0:x1]
        out.update(int(v) for v in np.unique(near[near > 0]))
    return out


@dataclass(frozen=True, eq=False)  # holds a grid: compared by identity
class TaskRoute:
    """The base poses of a mobile pick-and-place that the route check verified.

    The demos drive to these poses only: navigation to the object ends at one of
    :meth:`route_picks`, the carry at one of :meth:`route_places` of the same region, on the
    same grid and footprint the check used; episodes spawn where the stowed base's lattice
    reaches a verified pick pose (:meth:`random_spawn`, :meth:`picks_from`).

    Attributes:
        reason: ``""`` when some pick pose and some place pose connect, else ``no_pick_pose``,
            ``no_place_pose`` or ``no_route``; detail: the failure in words, naming the fix.
        grid: the raw occupancy grid (:func:`~factory.nav.task_poses.task_grid`).
        footprint: the base's outline with the arm stowed; carry: while it carries the
            object (:func:`~factory.nav.task_poses.carry_footprint`).
        pick_poses, place_poses: every free base pose within reach of the object / of the
            place support's top, best first (:func:`~factory.nav.task_poses.task_work_poses`).
        pick_regions, place_regions: per pose, the regions of the carrying base's free poses
            (:func:`se2_labels`) it lies in; empty when the check stopped before the lattice.
        headings: headings of the lattice.
    """

    reason: str
    detail: str
    grid: OccupancyGrid = field(repr=False)
    footprint: Footprint
    carry: Footprint
    pick_poses: tuple[BasePose, ...] = ()
    place_poses: tuple[BasePose, ...] = ()
    pick_regions: tuple[frozenset[int], ...] = ()
    place_regions: tuple[frozenset[int], ...] = ()
    headings: int = HEADINGS

    @property
    def ok(self) -> bool:
        """Whether a pick pose and a place pose connect."""
        return not self.reason

    def route_picks(self) -> list[BasePose]:
        """Pick poses sharing a region with some place pose, best first."""
        if not self.pick_regions:
            return []
        places = frozenset().union(*self.place_regions) if self.place_regions else frozenset()
        return [p for p, r in zip(self.pick_poses, self.pick_regions, strict=True) if r & places]

    def route_places(self, pick: BasePose | np.ndarray | None = None) -> list[BasePose]:
        """Place poses sharing a region with ``pick`` (a pose of :attr:`pick_poses`, or its
        (x, y, yaw)), or with any pick pose, best first."""
        if not self.place_regions:
            return []
        if pick is None:
            want = frozenset().union(*self.pick_regions) if self.pick_regions else frozenset()
        else:
            i = self.pick_index(pick)
            want = self.pick_regions[i] if i >= 0 and self.pick_regions else frozenset()
        return [p for p, r in zip(self.place_poses, self.place_regions, strict=True) if r & want]

    def pick_index(self, pose: BasePose | np.ndarray) -> int:
        """Index of a pose in :attr:`pick_poses` (matched to 1 um and 1 urad, yaw modulo a
        turn), -1 when it is not one."""
        return _index(self.pick_poses, pose)

    def place_index(self, pose: BasePose | np.ndarray) -> int:
        """Index of a pose in :attr:`place_poses` (see :meth:`pick_index`), -1 when not one."""
        return _index(self.place_poses, pose)

    @functools.cached_property
    def stow_labels(self) -> np.ndarray:
        """Regions of the stowed base's free poses (:func:`se2_labels` of :attr:`footprint`),
        int ``(headings, ny, nx)``: where the base drives before it holds the object."""
        return se2_labels(free_poses(self.grid, self.footprint, self.headings))

    @functools.cached_property
    def _spawn_nodes(self) -> np.ndarray:
        """Lattice nodes ``(n, 3)`` (heading, iy, ix) of the stowed base's regions that hold a
        verified pick pose."""
        regions = set().union(*(self.stow_regions(p) for p in self.route_picks()))
        if not regions:
            return np.zeros((0, 3), int)
        return np.argwhere(np.isin(self.stow_labels, sorted(regions)))

    def stow_regions(self, pose: BasePose | np.ndarray) -> set[int]:
        """The stowed base's regions (:attr:`stow_labels`) a pose (x, y, yaw) lies in."""
        if isinstance(pose, BasePose):
            p = pose
        else:
            p = BasePose(float(pose[0]), float(pose[1]), float(pose[2]))
        return pose_labels(self.stow_labels, self.grid, [p])

    def picks_from(self, start: BasePose | np.ndarray) -> list[BasePose]:
        """Verified pick poses (:meth:`route_picks`) in a stowed-base region of ``start``
        (x, y, yaw), best first: where the base can drive from there, by the lattice."""
        here = self.stow_regions(start)
        return [p for p in self.route_picks() if self.stow_regions(p) & here]

    def random_spawn(self, rng: np.random.Generator) -> BasePose:
        """A random lattice pose (a cell's centre, one of :attr:`headings` headings) whose
        footprint is free, in a region of the stowed base's free poses that holds a verified
        pick pose: the base can drive from it to the object and on to the place support by
        the route's lattice. Uniform over those poses.

        Raises:
            NavError: the route has no verified pick pose (no such region).
        """
        nodes = self._spawn_nodes
        if not len(nodes):
            raise NavError("no free spawn pose from which the route's pick poses are reachable")
        k, iy, ix = (int(v) for v in nodes[int(rng.integers(len(nodes)))])
        x, y = self.grid.cell_to_world(np.array([ix, iy]))
        yaw = math.remainder(2 * math.pi * k / self.headings, 2 * math.pi)
        return BasePose(float(x), float(y), yaw)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the reason, the pose counts, the grid's cell and the footprints."""
        return {
            "reason": self.reason,
            "pick_poses": len(self.pick_poses),
            "place_poses": len(self.place_poses),
            "route_pick_poses": len(self.route_picks()),
            "route_place_poses": len(self.route_places()),
            "resolution": self.grid.resolution,
            "headings": self.headings,
            "footprint_radius": round(self.footprint.radius, 4),
            "carry_front": round(self.carry.front, 4),
        }


def _index(poses: tuple[BasePose, ...], pose: BasePose | np.ndarray) -> int:
    p = pose.as_array() if isinstance(pose, BasePose) else np.asarray(pose, float)[:3]
    yaw = float(p[2]) % (2 * math.pi)
    for i, q in enumerate(poses):
        dyaw = abs((q.yaw % (2 * math.pi)) - yaw)
        if (
            abs(q.x - p[0]) < 1e-6
            and abs(q.y - p[1]) < 1e-6
            and min(dyaw, 2 * math.pi - dyaw) < 1e-6
        ):
            return i
    return -1


def task_route(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    grid: OccupancyGrid,
    objects: MobileTaskObjects,
    footprint: Footprint,
    headings: int = HEADINGS,
    labels: np.ndarray | None = None,
) -> TaskRoute:
    """The route between the supports, and the base poses it verified.

    First :func:`route_reason` (a pick pose and a place pose in one free region of the grid
    inflated by one footprint disc), then the SE(2) lattice of the carrying base
    (:func:`se2_labels`): each pose gets the regions it lies in, and the route holds when a
    pick pose and a place pose share one.

    Args:
        model, data: the compiled scene (bodies named by object id) and its kinematics.
        grid: the raw occupancy grid (:func:`~factory.nav.task_poses.task_grid`).
        objects: the task objects.
        footprint: the base's outline with the arm stowed.
        headings: headings of the lattice.
        labels: the carrying base's lattice regions on ``grid``, if at hand
            (:func:`se2_labels` of :func:`free_poses` of the carrying footprint): they depend
            on the grid and the object's size only, so the configurations of one scene that
            leave the grid as it is share them.
    """
    carry = carry_footprint(footprint, objects.pick)
    reason, detail, picks, places = route_reason(model, data, grid, objects, footprint)
    route = TaskRoute(reason, detail, grid, footprint, carry, tuple(picks), tuple(places))
    if reason:
        return route
    if labels is None:
        labels = se2_labels(free_poses(grid, carry, headings))
    pick_regions = tuple(frozenset(pose_labels(labels, grid, [p])) for p in picks)
    place_regions = tuple(frozenset(pose_labels(labels, grid, [p])) for p in places)
    if not frozenset().union(*pick_regions) & frozenset().union(*place_regions):
        reason = NO_ROUTE
        detail = (
            f"the base carrying {objects.pick.id!r} cannot turn and drive from "
            f"{objects.pick_support.id!r} to {objects.place_support.id!r}: widen the way"
        )
    return TaskRoute(
        reason,
        detail,
        grid,
        footprint,
        carry,
        tuple(picks),
        tuple(places),
        pick_regions,
        place_regions,
        headings,
    )


def route_reason(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    grid: OccupancyGrid,
    objects: MobileTaskObjects,
    footprint: Footprint,
) -> tuple[str, str, list[BasePose], list[BasePose]]:
    """Whether a base pose within reach of the object and one within reach of the place
    support share a free region of ``grid`` for ``footprint`` (necessary for an episode).

    Returns:
        ``(reason, detail, pick_poses, place_poses)``: reason ``""`` (the regions connect),
        ``no_pick_pose``, ``no_place_pose`` or ``no_route``; detail names the fix.
    """
    picks, places = task_work_poses(model, data, grid, objects, footprint)
    if not picks:
        return (
            NO_PICK_POSE,
            f"no free base pose within reach of {objects.pick.id!r} on "
            f"{objects.pick_support.id!r}: leave ~0.6 m free beside it",
            picks,
            places,
        )
    if not places:
        return (
            NO_PLACE_POSE,
            f"no free base pose within reach of the top of {objects.place_support.id!r}: "
            "leave ~0.6 m free beside it",
            picks,
            places,
        )
    inscribed = footprint.inscribed_grid(grid)
    a = {int(inscribed.component(p.xy)) for p in picks}
    b = {int(inscribed.component(p.xy)) for p in places}
    if not (a & b):
        width = 2 * (footprint.half_width + footprint.margin)
        return (
            NO_ROUTE,
            f"no free route between {objects.pick_support.id!r} and "
            f"{objects.place_support.id!r} for the base ({width:.2f} m wide): leave a corridor",
            picks,
            places,
        )
    return "", "", picks, places


def reachability(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    grid: OccupancyGrid,
    objects: MobileTaskObjects,
    footprint: Footprint,
) -> str:
    """``""`` when some base pose within reach of the object and some within reach of the
    place support share a free region of ``grid`` for ``footprint``, else why not, in words
    naming the fix (:func:`route_reason`'s detail)."""
    return route_reason(model, data, grid, objects, footprint)[1]


def movable(obj: SceneObject) -> bool:
    """Floor objects light enough to move aside (chairs, stools, lamps, plants, bins), not
    fixtures or heavy furniture (at most 25 kg and 1 m across)."""
    return (
        not obj.is_static
        and obj.placement.kind == "floor"
        and obj.physics.mass <= 25.0
        and max(obj.dimensions.width, obj.dimensions.length) <= 1.0
    )


def has_body(model: mujoco.MjModel, name: str) -> bool:
    """Whether the model has a body of this name."""
    try:
        model.body(name)
    except KeyError:
        return False
    return True


def clear_for_base(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    scene: Scene,
    objects: MobileTaskObjects,
    footprint: Footprint,
    resolution: float = GRID_RESOLUTION,
    max_objects: int = MAX_CLEARED,
    candidates: int = 8,
) -> set[str]:
    """The fewest light floor objects (:func:`movable`) whose removal makes the route hold
    (:func:`task_route`: first the cheap test of :func:`reachability`, then the carrying
    base's SE(2) lattice), or an empty set when up to ``max_objects`` of the ``candidates``
    nearest to the two supports do not.

    Generated rooms are furnished without a robot in mind: an armchair beside the desk or a
    lamp in the only gap can close the way for a base 0.58 m wide. A person would move them;
    so does this, trying single objects, then pairs, then triples, nearest first (with what
    stands on them). Only the occupancy grid is recomputed per try (the model is not).
    """
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
            bodies = [model.body(i).id for i in ids if has_body(model, i)]
            grid = task_grid(model, data, exclude_bodies=bodies, resolution=resolution)
            if reachability(model, data, grid, objects, footprint):
                continue
            if task_route(model, data, grid, objects, footprint).ok:
                return set(ids)
    return set()


def check_route(
    scene: Scene,
    assets_root: str | Path | None = None,
    model: mujoco.MjModel | None = None,
    footprint: Footprint = MOBILE_FOOTPRINT,
    resolution: float = GRID_RESOLUTION,
    min_separation: float = MIN_SUPPORT_SEPARATION,
    min_gap: float = 0.0,
    suggest_clear: bool = False,
    qpos: np.ndarray | None = None,
) -> RouteCheck:
    """The route check of a mobile-task scene (see the module's description).

    Args:
        scene: the scene (its objects' ``task_role`` name the task objects).
        assets_root: the run's assets folder, to compile the scene when ``model`` is None
            (None: objects are boxes).
        model: the scene's compiled model (bodies named by object id), if at hand.
        footprint: the base's outline (the mobile robot's by default).
        resolution: occupancy grid cell (m).
        min_separation: least distance between the supports' centres (m).
        min_gap: least distance between the supports' nearest edges (m): generation asks for
            :data:`~factory.nav.support_gap.MIN_SUPPORT_GAP`, so that the base must travel;
            0 (the default) checks the centres only, as scenes made before were.
        suggest_clear: on a blocked route, name the light floor objects whose removal opens
            it (``clear``).
        qpos: positions (nq,) of ``model`` to judge instead of its ``qpos0`` (a
            configuration of the scene as rows of the parent's model, as
            :func:`factory.augment.check.pose_rows` makes them; ``scene`` is then that
            configuration's scene).

    Returns:
        the verdict; it never raises for a scene that cannot host the task.
    """
    t0 = time.perf_counter()

    def verdict(reason: str, detail: str, **kw: Any) -> RouteCheck:
        if reason:
            log.debug("scene %s: route check %s: %s", scene.id, reason, detail)
        return RouteCheck(reason, detail, seconds=time.perf_counter() - t0, **kw)

    try:
        objects = role_objects(scene)
    except TaskSupportError as e:
        return verdict(e.reason, str(e))
    ids = {"pick_support": objects.pick_support.id, "place_support": objects.place_support.id}
    sep = support_separation(objects)
    gap = support_gap(objects)
    if sep < min_separation or gap < min_gap:
        return verdict(
            PLACE_SUPPORT_TOO_CLOSE,
            f"{objects.place_support.id!r} stands {sep:.2f} m from {objects.pick_support.id!r} "
            f"({gap:.2f} m between their edges): put it at least {min_separation:.1f} m away"
            + (f", {min_gap:.1f} m between the edges" if min_gap else "")
            + " (another part of the room, or another room)",
            separation=sep,
            gap=gap,
            **ids,
        )
    if model is None:
        from factory.sim.compile import compile_scene

        model = compile_scene(scene, assets_root).model
    data = mujoco.MjData(model)
    if qpos is not None:
        data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    for obj in (objects.pick, objects.pick_support, objects.place_support):
        if not has_body(model, obj.id):
            reason = NO_PLACE_SUPPORT if obj is objects.place_support else NO_PICK_OBJECT
            return verdict(reason, f"the compiled scene has no body {obj.id!r}", **ids)
    try:
        top = SupportTop.of(model, data, model.body(objects.place_support.id).id)
    except TaskError as e:
        return verdict(NO_PLACE_SUPPORT, str(e), separation=sep, **ids)
    if not top.fits(object_radius(objects.pick)):
        width, depth = top.hi - top.lo
        size = f"{width:.2f} x {depth:.2f} m"
        return verdict(
            PLACE_SUPPORT_TOO_SMALL,
            f"the top of {objects.place_support.id!r} ({size}) cannot hold {objects.pick.id!r} "
            f"({2 * object_radius(objects.pick):.2f} m across): choose a larger support",
            separation=sep,
            gap=gap,
            **ids,
        )
    grid = task_grid(model, data, resolution=resolution)
    area = spawn_area(free_poses(grid, footprint), grid.resolution)
    if area <= 0.0:
        return verdict(
            NO_SPAWN_AREA,
            "the base's footprint (0.78 x 0.58 m) fits nowhere on the floor: free some floor",
            separation=sep,
            gap=gap,
            spawn_area=area,
            **ids,
        )
    route = task_route(model, data, grid, objects, footprint)
    reason, detail = route.reason, route.detail
    found = {
        "pick_poses": len(route.pick_poses),
        "place_poses": len(route.place_poses),
        "route_pick_poses": len(route.route_picks()),
        "route_place_poses": len(route.route_places()),
    }
    clear: tuple[str, ...] = ()
    if reason in BLOCKED and suggest_clear:
        clear = tuple(sorted(clear_for_base(model, data, scene, objects, footprint, resolution)))
    return verdict(
        reason,
        detail,
        separation=sep,
        gap=gap,
        spawn_area=area,
        clear=clear,
        route=route,
        **found,
        **ids,
    )


def route_scene_check(scene: Scene, model: mujoco.MjModel) -> dict[str, Any] | None:
    """``stage=validate``'s scene check: the route check's fields for a mobile-task scene
    (:func:`is_mobile_task`), None for any other."""
    if not is_mobile_task(scene):
        return None
    return check_route(scene, model=model).as_dict()


__all__ = [
    "BLOCKED",
    "HEADINGS",
    "MIN_SUPPORT_GAP",
    "MIN_SUPPORT_SEPARATION",
    "NO_PICK_POSE",
    "NO_PLACE_POSE",
    "NO_ROUTE",
    "NO_SPAWN_AREA",
    "PLACE_SUPPORT_TOO_CLOSE",
    "PLACE_SUPPORT_TOO_SMALL",
    "ROUTE_REASONS",
    "RouteCheck",
    "TaskRoute",
    "check_route",
    "clear_for_base",
    "free_poses",
    "is_mobile_task",
    "movable",
    "pose_labels",
    "reachability",
    "route_reason",
    "route_scene_check",
    "se2_labels",
    "spawn_area",
    "support_gap",
    "support_separation",
    "task_route",
]
