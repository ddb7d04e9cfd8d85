"""The footprint of a mobile base as a row of discs, and pose and motion checks on a grid.

A holonomic base is a rectangle seen from above, not a disc: robosuite's Omron base is 0.70 x
0.50 m, so a disc around it (radius 0.45 m with its margin) needs corridors 0.9 m wide where
the base itself passes through 0.55 m lengthwise. Generated living rooms have few corridors
that wide (4-16 % of the floor was free for the disc's centre in 12 generated rooms, 9-28 %
for this footprint's discs).

:class:`Footprint` is a rectangle in the base frame (x forward from ``-rear`` to ``front``,
y within ``+-half_width``) grown by ``margin``, covered by ``discs`` equal discs centred on its
x axis. A base pose (x, y, yaw) is free when every disc centre's clearance on the *raw*
occupancy grid (:meth:`OccupancyGrid.clearance`, to within a cell) is at least the disc
radius. A straight SE(2) motion (position linear, yaw linear the short way round, as a
phase-synchronized ruckig piece drives it) is free when its poses are, sampled so that no point
of the footprint moves more than ``step`` between samples.

Frames: world frame, metres, radians; the base frame has +x forward.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from factory.nav.errors import NavError
from factory.nav.grid import OccupancyGrid


def wrap(a: np.ndarray | float) -> np.ndarray:
    """Angles (rad) wrapped to [-pi, pi)."""
    return (np.asarray(a, float) + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class Footprint:
    """A base's outline from above, in its own frame, as a row of discs.

    Attributes:
        rear: extent behind the base origin (m, > 0 means behind).
        front: extent ahead of it (m).
        half_width: half the width (m).
        margin: clearance added all round (m).
        discs: number of discs covering the rectangle.
    """

    rear: float = 0.35
    front: float = 0.40
    half_width: float = 0.25
    margin: float = 0.04
    discs: int = 4

    def __post_init__(self) -> None:
        if not (self.rear + self.front > 0 and self.half_width > 0 and self.discs >= 1):
            raise NavError(f"a footprint needs a positive length, width and disc count: {self}")
        if self.margin < 0:
            raise NavError(f"footprint margin must not be negative, got {self.margin}")

    @property
    def centres(self) -> np.ndarray:
        """x of the disc centres in the base frame (discs,) (m)."""
        length = self.rear + self.front
        return -self.rear + (np.arange(self.discs) + 0.5) * length / self.discs

    @property
    def radius(self) -> float:
        """Radius of each disc (m): covers its share of the rectangle, plus the margin."""
        half = (self.rear + self.front) / (2 * self.discs)
        return math.hypot(half, self.half_width) + self.margin

    @property
    def reach(self) -> float:
        """Largest distance of a footprint point from the base origin (m): how far a point of
        the footprint moves per radian of turn."""
        far = max(abs(self.centres[0]), abs(self.centres[-1]))
        return far + self.radius

    def disc_xy(self, poses: np.ndarray) -> np.ndarray:
        """World centres (..., discs, 2) of the discs at base poses (..., 3) (x, y, yaw)."""
        poses = np.asarray(poses, float)
        c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
        cx = self.centres
        x = poses[..., 0, None] + c[..., None] * cx
        y = poses[..., 1, None] + s[..., None] * cx
        return np.stack([x, y], axis=-1)

    def free(self, grid: OccupancyGrid, poses: np.ndarray) -> np.ndarray:
        """Whether base poses (..., 3) are free on a raw (not inflated) grid; bool (...)."""
        clear = grid.clearance(self.disc_xy(poses))
        return np.asarray((clear >= self.radius).all(axis=-1), bool)

    def motion(self, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
        """Poses (n, 3) of the straight SE(2) motion from ``a`` to ``b`` (3,), both included,
        such that no footprint point moves more than ``step`` (m) between two of them; the
        yaw goes the short way round and is not wrapped (it continues from ``a``'s)."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        dyaw = float(wrap(b[2] - a[2]))
        move = math.hypot(b[0] - a[0], b[1] - a[1]) + abs(dyaw) * self.reach
        n = max(1, math.ceil(move / step))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        out = a + t * np.array([b[0] - a[0], b[1] - a[1], dyaw])
        return out

    def motion_free(self, grid: OccupancyGrid, a: np.ndarray, b: np.ndarray, step: float) -> bool:
        """Whether the straight SE(2) motion ``a`` -> ``b`` is free (see :meth:`motion`)."""
        return bool(self.free(grid, self.motion(a, b, step)).all())

    def path_free(self, grid: OccupancyGrid, path: np.ndarray, step: float) -> bool:
        """Whether every straight motion of a path (k, 3) is free."""
        path = np.asarray(path, float)
        if len(path) == 1:
            return bool(self.free(grid, path).all())
        return all(self.motion_free(grid, path[i], path[i + 1], step) for i in range(len(path) - 1))

    def inscribed_grid(self, grid: OccupancyGrid) -> OccupancyGrid:
        """The raw grid inflated by one disc's radius: where a disc centre may be. A pose is
        free only where all its disc centres are free in it, so a path of poses lies in one
        of its components: a necessary test of connectivity (not a sufficient one)."""
        return grid.inflate(self.radius)


def unwrap_yaw(path: np.ndarray) -> np.ndarray:
    """A path (k, 3) with each yaw moved by whole turns to within pi of the one before it, so
    consecutive poses turn the short way and the yaws are continuous (as the base's hinge joint
    expects)."""
    out = np.array(path, float)
    for i in range(1, len(out)):
        out[i, 2] = out[i - 1, 2] + float(wrap(out[i, 2] - out[i - 1, 2]))
    return out
