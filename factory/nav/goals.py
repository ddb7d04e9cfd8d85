"""Where a mobile base may stand: beside a support to work at it, or anywhere free to spawn.

Both work on the occupancy grid inflated by the base's radius, so a returned pose is free for
the base at any yaw. Reachability is connectivity: a pose counts as reachable from a start when
both lie in one connected component of the inflated grid's free cells (8-connected), which is
necessary for a path; :func:`factory.nav.rrt.plan_base_path` then finds one.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from factory.nav.errors import NavError
from factory.nav.grid import OccupancyGrid

log = logging.getLogger(__name__)

_SIDES = ("-x", "+x", "-y", "+y")


@dataclass(frozen=True)
class BasePose:
    """A base pose in the world frame: centre (x, y) (m) and heading ``yaw`` (rad about +z).

    Attributes:
        side: the side of the support it faces (``-x``, ``+x``, ``-y``, ``+y``), or ``""``.
        offset: distance from the support's edge to the base centre (m), or 0.
    """

    x: float
    y: float
    yaw: float
    side: str = ""
    offset: float = 0.0

    @property
    def xy(self) -> np.ndarray:
        """(2,) position (m)."""
        return np.array([self.x, self.y])

    def as_array(self) -> np.ndarray:
        """(3,) x, y (m) and yaw (rad)."""
        return np.array([self.x, self.y, self.yaw])


def base_pose_beside(
    grid: OccupancyGrid,
    support_aabb_xy: tuple[float, float, float, float],
    start_xy: np.ndarray | None = None,
    target_xy: np.ndarray | None = None,
    offsets: tuple[float, ...] = (0.55, 0.65, 0.75),
    step: float = 0.1,
    edge_margin: float = 0.1,
) -> list[BasePose]:
    """Base poses facing a support (table, desk) from outside, at a reach distance.

    Candidates lie on lines parallel to each side of the support's box, ``offsets`` (m) out
    from that side's edge, every ``step`` (m) along the side (``edge_margin`` in from the
    corners, the middle of the side for a short one), each facing the support squarely.

    Args:
        grid: the occupancy grid inflated by the base's radius.
        support_aabb_xy: (xmin, ymin, xmax, ymax) of the support's top (m, world).
        start_xy: when given, only poses in the start's free component are kept.
        target_xy: a point of interest on the support (the object to pick): poses nearest to
            it come first; without it, poses nearest to ``start_xy`` (or to the side's middle)
            come first.
        offsets: edge-to-base-centre distances (m).
        step: spacing of candidates along a side (m).
        edge_margin: how far from the corners candidates start (m).

    Returns:
        free, reachable poses, best first; empty when none is.
    """
    xmin, ymin, xmax, ymax = support_aabb_xy
    if not (xmax > xmin and ymax > ymin):
        raise NavError(f"support box must have xmin < xmax and ymin < ymax: {support_aabb_xy}")
    component = None
    if start_xy is not None:
        component = int(grid.component(np.asarray(start_xy, float)[:2]))
        if component == 0:
            log.debug("start %s is not free in the inflated grid: no pose is reachable", start_xy)
            return []
    out: list[tuple[float, BasePose]] = []
    for side in _SIDES:
        axis = 0 if side.endswith("x") else 1
        lo, hi = (ymin, ymax) if axis == 0 else (xmin, xmax)
        a, b = lo + edge_margin, hi - edge_margin
        along = np.arange(a, b + 1e-9, step) if b > a else np.array([(lo + hi) / 2])
        edge = {"-x": xmin, "+x": xmax, "-y": ymin, "+y": ymax}[side]
        sign = 1.0 if side.startswith("+") else -1.0
        yaw = {"-x": 0.0, "+x": math.pi, "-y": math.pi / 2, "+y": -math.pi / 2}[side]
        for off in offsets:
            across = edge + sign * off
            for s in along:
                xy = np.array([across, s]) if axis == 0 else np.array([s, across])
                if not grid.free(xy):
                    continue
                if component is not None and int(grid.component(xy)) != component:
                    continue
                if target_xy is not None:
                    key = float(np.linalg.norm(xy - np.asarray(target_xy, float)[:2]))
                elif start_xy is not None:
                    key = float(np.linalg.norm(xy - np.asarray(start_xy, float)[:2]))
                else:
                    key = abs(s - (lo + hi) / 2) + off
                out.append((key, BasePose(float(xy[0]), float(xy[1]), yaw, side, float(off))))
    out.sort(key=lambda kv: kv[0])
    return [p for _, p in out]


def random_free_pose(
    grid: OccupancyGrid,
    rng: np.random.Generator,
    near_xy: np.ndarray | None = None,
    min_clearance: float = 0.0,
) -> BasePose:
    """A uniformly drawn free base pose, for spawning the robot.

    Args:
        grid: the occupancy grid inflated by the base's radius.
        rng: the random generator (the episode's seed decides the pose).
        near_xy: draw in the free component of this point (e.g. the goal); default the largest
            free component.
        min_clearance: extra clearance (m) from the inflated obstacles.

    Returns:
        a pose at a free cell centre, with a uniform yaw in [-pi, pi).

    Raises:
        NavError: no free cell qualifies.
    """
    label = (
        int(grid.component(np.asarray(near_xy, float)[:2]))
        if near_xy is not None
        else grid.largest_component()
    )
    mask = grid.labels == label if label else np.zeros(grid.shape, bool)
    if min_clearance > 0:
        mask &= grid.distance - grid.resolution / 2 >= min_clearance
    cells = np.argwhere(mask)  # (iy, ix)
    if not len(cells):
        where = "the given point's component" if near_xy is not None else "the grid"
        raise NavError(f"no free cell for the base in {where}")
    iy, ix = cells[int(rng.integers(len(cells)))]
    x, y = grid.cell_to_world(np.array([ix, iy]))
    return BasePose(float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
