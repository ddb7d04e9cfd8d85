"""Base paths for a base of a given footprint: OMPL RRTConnect in SE(2).

The state is the base pose (x, y, yaw) and a pose is valid when its
:class:`~factory.nav.footprint.Footprint` is free on the raw occupancy grid, so the base passes
lengthwise where a disc around it would not fit, and turns where there is room to turn (a
planner for such a disc came first and was removed). Motions between states are straight in
SE(2) (position linear, yaw linear the short way round), which is what a phase-synchronized
ruckig piece of :func:`factory.nav.base_trajectory.time_base_path` drives.

The search runs in OMPL's ``SE2StateSpace`` bounded by the grid; the path is shortened by
OMPL's ``PathSimplifier`` and by cutting corners (:func:`shortcut_se2`), its yaws are unwrapped
(:func:`~factory.nav.footprint.unwrap_yaw`) and the whole path is re-checked at a fine step
before it is returned. Failures are results with reason ``nav_failed``. OMPL is seeded with
the query's ``seed`` before each search (:func:`factory.nav.rrt.seed_ompl`), so a query's
path depends on its seed alone, not on the queries before it in the process.
"""

from __future__ import annotations

import itertools
import logging
import math
import time

import numpy as np

from factory.nav.footprint import Footprint, unwrap_yaw, wrap
from factory.nav.grid import OccupancyGrid
from factory.nav.rrt import NAV_FAILED, BasePath, NavPlannerConfig, seed_ompl, solve_rrt_connect

log = logging.getLogger(__name__)


def shortcut_se2(
    grid: OccupancyGrid,
    footprint: Footprint,
    path: np.ndarray,
    step: float,
    spacing: float = 0.1,
) -> np.ndarray:
    """A pose path (k, 3) with its corners cut where the footprint stays free.

    The path is resampled so that no footprint point moves more than ``spacing`` (m) between
    samples; from each kept pose the next one kept is the farthest later pose that a free
    straight SE(2) motion reaches (checked at ``step``, m). Start and goal stay.
    """
    path = np.asarray(path, float)
    if len(path) <= 2:
        return path
    dense = [path[:1]]
    for a, b in itertools.pairwise(path):
        dense.append(footprint.motion(a, b, spacing)[1:])
    pts = np.concatenate(dense)
    out = [pts[0]]
    i = 0
    while i < len(pts) - 1:
        j = len(pts) - 1
        while j > i + 1 and not footprint.motion_free(grid, pts[i], pts[j], step):
            j -= 1
        out.append(pts[j])
        i = j
    return np.array(out)


def plan_se2_path(
    grid: OccupancyGrid,
    footprint: Footprint,
    start: np.ndarray,
    goal: np.ndarray,
    cfg: NavPlannerConfig | None = None,
    seed: int = 0,
) -> BasePath:
    """A collision-free pose path from ``start`` to ``goal`` (3,) each: x, y (m), yaw (rad).

    Args:
        grid: the raw occupancy grid (not inflated).
        footprint: the base's outline.
        start, goal: base poses (world).
        cfg: planner parameters (``timeout``, ``attempts``, ``simplify``, ``edge_step`` and
            ``check_step`` as shares of a grid cell).
        seed: OMPL's seed for this query.

    Returns:
        the path (k, 3), yaws unwrapped from the start's, or ``ok=False`` with
        ``reason="nav_failed"``; a free straight motion is returned as is.
    """
    cfg = cfg or NavPlannerConfig()
    t0 = time.perf_counter()
    start = np.asarray(start, float)[:3]
    goal = np.asarray(goal, float)[:3].copy()
    goal[2] = start[2] + float(wrap(goal[2] - start[2]))

    def fail(detail: str) -> BasePath:
        log.debug("base path %s -> %s failed: %s", start.round(2), goal.round(2), detail)
        return BasePath(False, NAV_FAILED, detail, seconds=time.perf_counter() - t0)

    for name, p in (("start", start), ("goal", goal)):
        if not footprint.free(grid, p):
            return fail(f"{name} {p.round(3).tolist()} is not free for the base's footprint")
    fine = grid.resolution * cfg.check_step
    if footprint.motion_free(grid, start, goal, fine):
        return BasePath(True, path=np.stack([start, goal]), seconds=time.perf_counter() - t0)
    inscribed = footprint.inscribed_grid(grid)
    if inscribed.component(start[:2]) != inscribed.component(goal[:2]):
        return fail("start and goal are not connected through free space")

    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_WARN)
    seed_ompl(seed)
    space = ob.SE2StateSpace()
    bounds = ob.RealVectorBounds(2)
    xmin, ymin, xmax, ymax = grid.bounds
    bounds.setLow(0, xmin)
    bounds.setHigh(0, xmax)
    bounds.setLow(1, ymin)
    bounds.setHigh(1, ymax)
    space.setBounds(bounds)
    clear = np.maximum(grid.distance - grid.resolution / 2, 0.0)
    ox, oy, res = grid.origin[0], grid.origin[1], grid.resolution
    ny, nx = grid.shape
    centres = [float(c) for c in footprint.centres]
    radius = footprint.radius

    def valid(s: object) -> bool:
        x, y, yaw = s.getX(), s.getY(), s.getYaw()  # type: ignore[attr-defined]
        c, sn = math.cos(yaw), math.sin(yaw)
        for cx in centres:
            ix = math.floor((x + c * cx - ox) / res)
            iy = math.floor((y + sn * cx - oy) / res)
            if not (0 <= ix < nx and 0 <= iy < ny) or clear[iy, ix] < radius:
                return False
        return True

    detail = "no path"
    for attempt in range(cfg.attempts):
        setup = og.SimpleSetup(space)
        setup.setStateValidityChecker(valid)
        s, g = space.allocState(), space.allocState()
        s.setX(float(start[0]))
        s.setY(float(start[1]))
        s.setYaw(float(wrap(start[2])))
        g.setX(float(goal[0]))
        g.setY(float(goal[1]))
        g.setYaw(float(wrap(goal[2])))
        setup.setStartAndGoalStates(s, g)
        # the SE(2) metric weighs yaw by 0.5 m/rad; footprint points move up to ``reach``
        # m/rad, so the edge step is scaled down to keep them within ``edge_step`` cells
        scale = max(1.0, footprint.reach / 0.5)
        sol = solve_rrt_connect(
            setup, cfg, res * cfg.edge_step / scale / max(space.getMaximumExtent(), 1e-9), attempt
        )
        if isinstance(sol, str):
            detail = sol
            continue
        path = np.array(
            [
                [sol.getState(k).getX(), sol.getState(k).getY(), sol.getState(k).getYaw()]
                for k in range(sol.getStateCount())
            ]
        )
        path[0], path[-1] = start, goal
        path = unwrap_yaw(path)
        path = unwrap_yaw(shortcut_se2(grid, footprint, path, fine))
        if footprint.path_free(grid, path, fine):
            log.debug("base path of %d poses in %.2f s", len(path), time.perf_counter() - t0)
            return BasePath(True, path=path, seconds=time.perf_counter() - t0)
        detail = "the simplified path failed the fine re-check"
    return fail(detail)
