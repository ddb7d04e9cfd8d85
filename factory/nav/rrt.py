"""Base paths on an occupancy grid: OMPL RRTConnect in the plane.

The base is a disc of the grid's inflation radius: a position (x, y) is valid when its cell of
the *inflated* grid is free (:meth:`OccupancyGrid.inflate` with the base's circumscribed
radius), so the base may turn in place anywhere along the path. The search runs in a 2-D
``RealVectorStateSpace`` bounded by the grid, checks edges every quarter cell, is shortened by
OMPL's ``PathSimplifier`` and by cutting corners on the grid (:func:`shortcut`), and is
re-checked at a finer step before it is returned.

Failures are results, not exceptions: ``ok`` is False and ``reason`` is ``nav_failed`` (the
``detail`` says why: start or goal blocked, not connected, no path within the time limit).

Seeding: OMPL has one process-wide random generator whose seed takes effect only before its
first use; as ``factory.demos.planner`` does, the seed is handed to ``ompl.util.RNG.setSeed``,
here only once per process (later calls would only make OMPL print an error). Paths are thus
reproducible for the same sequence of queries in a fresh process.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.nav.grid import OccupancyGrid

log = logging.getLogger(__name__)

NAV_FAILED = "nav_failed"
"""The failure reason of a base-navigation query that has no (found) path."""

_seeded = False


@dataclass(frozen=True)
class NavPlannerConfig:
    """Parameters of a base-path query.

    Attributes:
        timeout: seconds of RRTConnect per attempt.
        attempts: RRTConnect runs before giving up.
        range: RRTConnect's extension step (m); 0 lets OMPL choose.
        edge_step: edge-validation step as a share of a grid cell.
        simplify: seconds of path simplification (shortcuts, vertex reduction).
        check_step: step of the final re-check as a share of a grid cell.
    """

    timeout: float = 2.0
    attempts: int = 2
    range: float = 0.0
    edge_step: float = 0.25
    simplify: float = 0.3
    check_step: float = 0.1


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class BasePath:
    """A planned base path.

    Attributes:
        ok: whether a path was found.
        reason: ``""`` or ``nav_failed``.
        detail: why it failed, in words.
        path: waypoints (k, 2) in the world frame (m), start and goal included; (0, 2) on
            failure. A footprint path (:func:`factory.nav.se2.plan_se2_path`) has poses
            (k, 3): x, y (m) and unwrapped yaw (rad).
        seconds: wall time of the query.
    """

    ok: bool
    reason: str = ""
    detail: str = ""
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    seconds: float = 0.0

    @property
    def length(self) -> float:
        """Length of the path in the plane (m)."""
        return float(np.linalg.norm(np.diff(self.path[:, :2], axis=0), axis=1).sum())


def segment_free(grid: OccupancyGrid, a: np.ndarray, b: np.ndarray, step: float) -> bool:
    """Whether every point of the segment ``a``-``b`` (2,) at spacing <= ``step`` (m) is free."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
    pts = a + np.outer(np.linspace(0.0, 1.0, n + 1), b - a)
    return bool(grid.free(pts).all())


def path_free(grid: OccupancyGrid, path: np.ndarray, step: float) -> bool:
    """Whether a polyline (k, 2) is free at spacing <= ``step`` (m)."""
    path = np.asarray(path, float)
    if len(path) == 1:
        return bool(grid.free(path).all())
    return all(segment_free(grid, path[i], path[i + 1], step) for i in range(len(path) - 1))


def shortcut(
    grid: OccupancyGrid, path: np.ndarray, step: float, spacing: float = 0.1
) -> np.ndarray:
    """A polyline (k, 2) with its corners cut where the grid allows.

    The path is resampled every ``spacing`` (m) along its segments; from each kept point the
    next one kept is the farthest later point that a free straight segment reaches (checked
    at spacing <= ``step``, m). Start and goal stay; the result is never longer.

    OMPL's simplifier leaves detours of a few centimetres in narrow passages; each corner
    costs the base a stop and a turn in place, so fewer corners mean much shorter drives.
    """
    path = np.asarray(path, float)
    if len(path) <= 2:
        return path
    # Points every ``spacing`` along the path, so a cut may end inside a segment.
    dense = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / spacing))
        dense.append(a + np.outer(np.arange(1, n + 1) / n, b - a))
    path = np.concatenate(dense)
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not segment_free(grid, path[i], path[j], step):
            j -= 1
        out.append(path[j])
        i = j
    return np.array(out)


def solve_rrt_connect(setup: Any, cfg: NavPlannerConfig, resolution: float, attempt: int) -> Any:
    """Runs OMPL's RRTConnect on a prepared ``og.SimpleSetup`` (space, validity checker, start
    and goal set) and simplifies the solution.

    Args:
        resolution: the validity-checking resolution, a fraction of the space's extent.
        attempt: 0-based attempt number (for the message).

    Returns:
        the simplified ``og.PathGeometric``, or why there is none (a string).
    """
    from ompl import geometric as og

    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(resolution)
    planner = og.RRTConnect(info)
    if cfg.range > 0:
        planner.setRange(cfg.range)
    setup.setPlanner(planner)
    solved = setup.solve(cfg.timeout)
    if not solved or str(solved) != "Exact solution":
        return f"RRTConnect found no path in {cfg.timeout:.1f} s ({attempt + 1} attempts)"
    setup.simplifySolution(cfg.simplify)
    return setup.getSolutionPath()


def _seed(seed: int) -> None:
    global _seeded
    if _seeded:
        return
    from ompl import util as ou

    ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
    _seeded = True


def plan_base_path(
    grid: OccupancyGrid,
    start_xy: np.ndarray,
    goal_xy: np.ndarray,
    cfg: NavPlannerConfig | None = None,
    seed: int = 0,
) -> BasePath:
    """A collision-free base path from ``start_xy`` to ``goal_xy`` (2,) each (m, world).

    Args:
        grid: the occupancy grid inflated by the base's radius.
        start_xy, goal_xy: base centre positions.
        cfg: planner parameters; default :class:`NavPlannerConfig`.
        seed: OMPL's seed (taken once per process, see the module docstring).

    Returns:
        the path, or ``ok=False`` with ``reason="nav_failed"``. A free straight segment is
        returned as is; otherwise start and goal must lie in one connected free component
        before RRTConnect runs.
    """
    cfg = cfg or NavPlannerConfig()
    t0 = time.perf_counter()
    start, goal = np.asarray(start_xy, float)[:2], np.asarray(goal_xy, float)[:2]
    if grid.inflation <= 0:
        log.warning("planning on a grid that is not inflated: the base is taken as a point")

    def fail(detail: str) -> BasePath:
        log.debug("base path %s -> %s failed: %s", start, goal, detail)
        return BasePath(False, NAV_FAILED, detail, seconds=time.perf_counter() - t0)

    for name, p in (("start", start), ("goal", goal)):
        if not grid.free(p):
            where = "off the grid" if not grid.inside(p) else "in an (inflated) obstacle"
            return fail(f"{name} {p.round(3).tolist()} is {where}")
    fine = grid.resolution * cfg.check_step
    if segment_free(grid, start, goal, fine):
        return BasePath(True, path=np.stack([start, goal]), seconds=time.perf_counter() - t0)
    if grid.component(start) != grid.component(goal):
        return fail("start and goal are not connected through free space")

    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_WARN)
    _seed(seed)
    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    xmin, ymin, xmax, ymax = grid.bounds
    bounds.setLow(0, xmin)
    bounds.setHigh(0, xmax)
    bounds.setLow(1, ymin)
    bounds.setHigh(1, ymax)
    space.setBounds(bounds)
    occupied = grid.occupied
    ox, oy, res = grid.origin[0], grid.origin[1], grid.resolution
    ny, nx = grid.shape

    def valid(s: object) -> bool:
        ix = math.floor((s[0] - ox) / res)  # type: ignore[index]
        iy = math.floor((s[1] - oy) / res)  # type: ignore[index]
        return 0 <= ix < nx and 0 <= iy < ny and not occupied[iy, ix]

    detail = "no path"
    for attempt in range(cfg.attempts):
        setup = og.SimpleSetup(space)
        setup.setStateValidityChecker(valid)
        s, g = space.allocState(), space.allocState()
        s[0], s[1] = float(start[0]), float(start[1])
        g[0], g[1] = float(goal[0]), float(goal[1])
        setup.setStartAndGoalStates(s, g)
        sol = solve_rrt_connect(
            setup, cfg, res * cfg.edge_step / max(space.getMaximumExtent(), 1e-9), attempt
        )
        if isinstance(sol, str):
            detail = sol
            continue
        path = np.array(
            [[sol.getState(k)[0], sol.getState(k)[1]] for k in range(sol.getStateCount())]
        )
        path[0], path[-1] = start, goal
        path = shortcut(grid, path, fine)
        if path_free(grid, path, fine):
            log.debug("base path of %d waypoints in %.2f s", len(path), time.perf_counter() - t0)
            return BasePath(True, path=path, seconds=time.perf_counter() - t0)
        detail = "the simplified path failed the fine re-check"
    return fail(detail)
