"""The mobile task's route check for configuration-level variants, batched per parent.

A layout or category variant is a new scene, compiled and route-checked on its own
(:func:`factory.augment.stage.check_route`). Configuration variants of one parent differ only
in the poses of its task objects on their supports, so they are judged as rows of the
parent's compiled model (:func:`factory.augment.check.pose_rows`, bit for bit each variant's
own ``qpos0``), the model compiled once: a row whose moved objects add no cell to the parent's
occupancy grid (a can on a table: the table's cells) keeps the parent's grid and lattice and
only its base poses within reach of the object are new (:class:`RouteCells`); any other row
gets the whole :func:`factory.nav.route.check_route`. Either way the verdict is that of the
variant scene compiled and checked alone (a test compares them).

What the route depends on (:mod:`factory.nav.route`): the occupancy grid (every colliding geom
in the robot's height band), the supports' poses and tops, the separation of the supports, and
the pick object's position (the base poses within reach of it) and size (the carrying
footprint). A configuration variant re-poses objects standing on supports, with their
footprints on their supports' tops, so the grid, the supports and the separation stay as they
are; what it can change is the pick object's position, or a support of the route that itself
stands on a support (a tray as the place support). Variants that move neither are not
re-checked (:func:`route_inputs` says why); the others are, and fail with the route check's
reason (``no_pick_pose``, ``no_route``, ...), as layout variants do.

Frames: world, metres; poses ``[x, y, z, yaw_deg]`` as the configuration level stores them.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import mujoco
import numpy as np

from factory.nav.grid import OccupancyGrid
from factory.nav.task_poses import MobileTaskObjects
from factory.schema import Scene

log = logging.getLogger(__name__)


def route_inputs(scene: Scene, ids: list[str]) -> str:
    """``""`` when configurations of ``scene`` that re-pose ``ids`` need the route check,
    else why not, in words.

    They need it when the scene is made for the mobile task
    (:func:`factory.nav.route.is_mobile_task`) and ``ids`` hold the pick object or one of the
    route's supports, or the task objects cannot be read (the check then names the fault).
    """
    from factory.nav.route import is_mobile_task
    from factory.nav.task_poses import TaskSupportError, role_objects

    if not is_mobile_task(scene):
        return f"scene {scene.id!r} is not made for the mobile task"
    try:
        objects = role_objects(scene)
    except TaskSupportError:
        return ""
    route = {objects.pick.id, objects.pick_support.id, objects.place_support.id}
    if route & set(ids):
        return ""
    return (
        f"the variants of {scene.id!r} move only {', '.join(ids)}, which stand on their "
        f"supports and are not {objects.pick.id!r} or a support of the route: the grid, the "
        "supports and the object's reach are the parent's"
    )


def configuration_routes(
    scene: Scene, ids: list[str], poses: np.ndarray, assets_root: str | Path | None
) -> list[str]:
    """The route check of each configuration of ``scene``: per configuration ``""`` when it
    passes (or cannot change the route, :func:`route_inputs`), else its reason.

    The verdict is :func:`factory.nav.route.check_route`'s on the variant scene. The parent is
    compiled and checked once; where the configurations move no support of the route, the
    checks before the route (supports, separation, top, spawn area) are the parent's, and a
    configuration whose moved objects' footprints fall on cells the rest of the scene already
    occupies (objects on a table: the table's cells) leaves the grid as it is, so only its
    base poses within reach of the object are new (:class:`RouteCells`); any other is checked
    whole (``check_route(..., qpos=row)``).

    Args:
        scene: the parent scene (its task objects name the route).
        ids: the ``k`` re-posed objects.
        poses: ``(n, k, 4)`` ``[x, y, z, yaw_deg]`` per configuration (bottom centre, world).
        assets_root: the run's assets folder (None: objects are boxes).
    """
    from factory.augment.check import pose_rows
    from factory.nav.route import check_route
    from factory.sim.compile import compile_scene

    poses = np.asarray(poses, float)
    skip = route_inputs(scene, ids)
    if skip:
        log.debug("configurations of %s not route-checked: %s", scene.id, skip)
        return [""] * len(poses)
    t0 = time.perf_counter()
    model = compile_scene(scene, assets_root).model
    rows = pose_rows(model, model.qpos0, ids, poses)
    cells = RouteCells.of(scene, model, ids)
    out = []
    fast = 0
    for i, row in enumerate(rows):
        verdict = cells.check(row) if cells is not None else None
        if verdict is None:
            full = check_route(scene, model=model, qpos=row)
            verdict = (full.reason, full.detail)
        else:
            fast += 1
        if verdict[0]:
            log.info("configuration %d of %s fails the route check: %s", i, scene.id, verdict[1])
        out.append(verdict[0])
    log.debug(
        "route check of %d configurations of %s in %.2f s (%d on the parent's grid)",
        len(rows),
        scene.id,
        time.perf_counter() - t0,
        fast,
    )
    return out


class RouteCells:
    """The route check of configurations that leave the parent's grid as it is.

    Attributes:
        model: the parent's compiled model; objects: its task objects.
        moved: body ids of the re-posed objects; others: every other body (world included).
        base: the grid without the moved objects (:func:`~factory.nav.task_poses.task_grid`).
        inner: (xmin, ymin, xmax, ymax) of the footprints behind ``base`` (m): the grid's
            extent less its padding.
        labels: the carrying base's lattice regions on ``base``.
        parent: the parent's verdict before the route, ``(reason, detail)``: empty, or the
            reason every configuration fails with (missing objects, supports too close, a top
            too small), which the grid does not decide.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        objects: MobileTaskObjects,
        moved: list[int],
        base: OccupancyGrid,
        inner: tuple[float, float, float, float],
        labels: np.ndarray,
        parent: tuple[str, str],
    ) -> None:
        self.model = model
        self.objects = objects
        self.moved = moved
        self.others = [b for b in range(model.nbody) if b not in set(moved)]
        self.base = base
        self.inner = inner
        self.labels = labels
        self.parent = parent
        self.data = mujoco.MjData(model)

    @classmethod
    def of(cls, scene: Scene, model: mujoco.MjModel, ids: list[str]) -> RouteCells | None:
        """The parent's grid and lattice without the moved objects, or None when the
        configurations move a support of the route (their checks are then whole)."""
        from factory.nav.grid import scene_footprints
        from factory.nav.route import (
            BLOCKED,
            NO_SPAWN_AREA,
            check_route,
            free_poses,
            se2_labels,
        )
        from factory.nav.task_poses import (
            GRID_Z_BAND,
            MOBILE_FOOTPRINT,
            TaskSupportError,
            carry_footprint,
            role_objects,
            task_grid,
        )

        try:
            objects = role_objects(scene)
        except TaskSupportError:
            return None
        if {objects.pick_support.id, objects.place_support.id} & set(ids):
            return None
        parent = check_route(scene, model=model)
        if parent.reason == NO_SPAWN_AREA:  # on the grid with the moved objects: check whole
            return None
        moved = [model.body(i).id for i in ids]
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        polygons = scene_footprints(model, data, GRID_Z_BAND, exclude_bodies=moved)
        if not polygons:
            return None
        pts = np.concatenate(polygons)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        base = task_grid(model, data, exclude_bodies=moved)
        carry = carry_footprint(MOBILE_FOOTPRINT, objects.pick)
        labels = se2_labels(free_poses(base, carry))
        before = (parent.reason, parent.detail) if parent.reason not in BLOCKED else ("", "")
        inner = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        return cls(model, objects, moved, base, inner, labels, before)

    def check(self, qpos: np.ndarray) -> tuple[str, str] | None:
        """``(reason, detail)`` of the configuration ``qpos`` (nq,) (``("", "")`` when it
        passes), or None when its moved objects change the grid (check it whole)."""
        from factory.nav.grid import scene_footprints
        from factory.nav.route import task_route
        from factory.nav.task_poses import GRID_Z_BAND, MOBILE_FOOTPRINT

        if self.parent[0]:
            return self.parent
        m, d = self.model, self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        polygons = scene_footprints(m, d, GRID_Z_BAND, exclude_bodies=self.others)
        if polygons:
            pts = np.concatenate(polygons)
            x0, y0, x1, y1 = self.inner
            if (pts[:, 0] < x0).any() or (pts[:, 1] < y0).any():
                return None
            if (pts[:, 0] > x1).any() or (pts[:, 1] > y1).any():
                return None
            mine = OccupancyGrid.from_model(
                m, d, self.base.resolution, GRID_Z_BAND, self.others, bounds=self.base.bounds
            )
            if mine.occupied.shape != self.base.occupied.shape:
                return None
            if (mine.occupied & ~self.base.occupied).any():
                return None
        route = task_route(m, d, self.base, self.objects, MOBILE_FOOTPRINT, labels=self.labels)
        return route.reason, route.detail


__all__ = ["RouteCells", "configuration_routes", "route_inputs"]
