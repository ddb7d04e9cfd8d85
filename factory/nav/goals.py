"""Where a mobile base may stand: beside a support to work at it, or anywhere free to spawn.

:func:`work_poses` and :func:`random_footprint_pose` work on the raw grid with the base's
:class:`~factory.nav.footprint.Footprint`, so a returned pose is free at its own yaw.
Reachability is connectivity: a pose counts as reachable from a start when both lie in one
connected component of the inflated grid's free cells (8-connected; for a footprint, the grid
inflated by one of its discs), which is necessary for a path;
:func:`factory.nav.se2.plan_se2_path` then finds one.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from factory.nav.errors import NavError
from factory.nav.footprint import Footprint, wrap
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


def work_poses(
    grid: OccupancyGrid,
    footprint: Footprint,
    support_aabb_xy: tuple[float, float, float, float],
    arm_x: float,
    targets_xy: np.ndarray,
    reach: tuple[float, float] = (0.35, 0.8),
    start_xy: np.ndarray | None = None,
    gaps: tuple[float, ...] = (0.03, 0.12, 0.25),
    distances: tuple[float, ...] = (0.45, 0.55, 0.65, 0.75),
    directions: int = 24,
    step: float = 0.1,
) -> list[BasePose]:
    """Base poses from which an arm on the base reaches points of a support, for a base of a
    given footprint, best first.

    Two families of candidates: poses square to each side of the support's box, the footprint's
    front ``gaps`` (m) from that side, every ``step`` (m) along it; and poses facing each
    target point from ``directions`` headings, the arm's base ``distances`` (m) from it (these
    reach round corners and past furniture that blocks a whole side). A pose is kept when its
    footprint is free on the raw grid (:meth:`Footprint.free`), some target lies within
    ``reach`` (m, horizontal, from the arm's base) and, with ``start_xy``, its position is in the
    start's component of the footprint's inscribed grid (necessary for a path).

    Ranking: the horizontal distance from the arm's base to the nearest target, off 0.55 m,
    plus 0.3 m per radian that the target lies off the heading, plus a tenth of the distance
    from the start.

    Args:
        grid: the raw occupancy grid.
        footprint: the base's outline.
        support_aabb_xy: (xmin, ymin, xmax, ymax) of the support's top (m, world).
        arm_x: the arm's base position ahead of the base origin (m, base frame).
        targets_xy: points (n, 2) the arm must reach (the object to pick, or points of the top
            to place on).
        reach: (nearest, farthest) horizontal distance of a target from the arm's base (m).
        start_xy: where the base is now (m).
        gaps, distances, directions, step: the candidate sets (see above).

    Returns:
        poses (``side`` names the side for a square pose, ``radial`` for the others;
        ``offset`` is the arm base's distance to the nearest target), best first.
    """
    xmin, ymin, xmax, ymax = support_aabb_xy
    if not (xmax > xmin and ymax > ymin):
        raise NavError(f"support box must have xmin < xmax and ymin < ymax: {support_aabb_xy}")
    targets = np.asarray(targets_xy, float).reshape(-1, 2)
    if not len(targets):
        raise NavError("work_poses needs at least one target point")
    cands: list[tuple[float, float, float, str]] = []
    front = footprint.front + footprint.margin
    for side in _SIDES:
        axis = 0 if side.endswith("x") else 1
        lo, hi = (ymin, ymax) if axis == 0 else (xmin, xmax)
        along = np.arange(lo + 0.05, hi - 0.05 + 1e-9, step) if hi - lo > 0.1 else [(lo + hi) / 2]
        edge = {"-x": xmin, "+x": xmax, "-y": ymin, "+y": ymax}[side]
        sign = 1.0 if side.startswith("+") else -1.0
        yaw = {"-x": 0.0, "+x": math.pi, "-y": math.pi / 2, "+y": -math.pi / 2}[side]
        for gap in gaps:
            across = edge + sign * (front + gap)
            for s in along:
                x, y = (across, s) if axis == 0 else (s, across)
                cands.append((float(x), float(y), yaw, side))
    for t in targets:
        for k in range(directions):
            yaw = -math.pi + 2 * math.pi * k / directions
            u = np.array([math.cos(yaw), math.sin(yaw)])
            for d in distances:
                x, y = t - (arm_x + d) * u
                cands.append((float(x), float(y), yaw, "radial"))
    poses = np.array([c[:3] for c in cands])
    keep = footprint.free(grid, poses)
    arm = poses[:, :2] + arm_x * np.stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])], axis=1)
    rel = targets[None, :, :] - arm[:, None, :]  # (n, t, 2)
    dist = np.linalg.norm(rel, axis=2)
    nearest = dist.argmin(axis=1)
    d_min = dist[np.arange(len(poses)), nearest]
    keep &= (d_min >= reach[0]) & (d_min <= reach[1])
    if start_xy is not None:
        inscribed = footprint.inscribed_grid(grid)
        label = int(inscribed.component(np.asarray(start_xy, float)[:2]))
        if label == 0:
            log.debug("start %s is not free for the footprint: no pose is reachable", start_xy)
            return []
        keep &= inscribed.component(poses[:, :2]) == label
    to_target = rel[np.arange(len(poses)), nearest]  # (n, 2)
    bearing = np.arctan2(to_target[:, 1], to_target[:, 0])
    off = np.abs(wrap(bearing - poses[:, 2]))
    score = np.abs(d_min - 0.55) + 0.3 * off
    if start_xy is not None:
        score += 0.1 * np.linalg.norm(poses[:, :2] - np.asarray(start_xy, float)[:2], axis=1)
    order = [int(i) for i in np.argsort(score, kind="stable") if keep[i]]
    return [BasePose(*cands[i][:3], side=cands[i][3], offset=float(d_min[i])) for i in order]


def random_footprint_pose(
    grid: OccupancyGrid,
    footprint: Footprint,
    rng: np.random.Generator,
    near_xy: np.ndarray | None = None,
    tries: int = 200,
) -> BasePose:
    """A random base pose whose footprint is free, for spawning the robot.

    Positions are drawn uniformly from the free cells of the footprint's inscribed grid (in the
    component of ``near_xy``, else the largest), each with a uniform yaw, until one is free.

    Args:
        grid: the raw occupancy grid.
        footprint: the base's outline.
        rng: the random generator (the episode's seed decides the pose).
        near_xy: draw where a path to this point may exist (e.g. a work pose).
        tries: draws before giving up.

    Raises:
        NavError: no free pose in ``tries`` draws.
    """
    inscribed = footprint.inscribed_grid(grid)
    label = (
        int(inscribed.component(np.asarray(near_xy, float)[:2]))
        if near_xy is not None
        else inscribed.largest_component()
    )
    cells = np.argwhere(inscribed.labels == label) if label else np.zeros((0, 2), int)
    if not len(cells):
        raise NavError("no free cell for the base's footprint")
    for _ in range(tries):
        iy, ix = cells[int(rng.integers(len(cells)))]
        x, y = inscribed.cell_to_world(np.array([ix, iy]))
        pose = BasePose(float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
        if footprint.free(grid, pose.as_array()):
            return pose
    raise NavError(f"no free pose for the base's footprint in {tries} draws")
