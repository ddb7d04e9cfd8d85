"""2-D footprints for placement: oriented rectangles and their overlap test (separating axes).

A footprint is an object's extent on the floor plane: centre ``(x, y)`` (m, world frame),
half sizes ``(hx, hy)`` along the object's own x and y axes, and ``yaw`` (rad). Heights are
``z0..z1`` so that a painting above a sofa does not collide with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Footprint:
    """An oriented box standing on ``z0`` up to ``z1`` (m)."""

    x: float
    y: float
    hx: float
    hy: float
    yaw: float = 0.0
    z0: float = 0.0
    z1: float = 1.0

    def corners(self) -> np.ndarray:
        """``(4, 2)`` corners in the world frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * [self.hx, self.hy]
        rot = np.array([[c, -s], [s, c]])
        return local @ rot.T + [self.x, self.y]

    def axes(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, s], [-s, c]])

    def grown(self, margin: float) -> Footprint:
        return Footprint(
            self.x, self.y, self.hx + margin, self.hy + margin, self.yaw, self.z0, self.z1
        )

    def aabb(self) -> tuple[float, float, float, float]:
        c = self.corners()
        return (
            float(c[:, 0].min()),
            float(c[:, 1].min()),
            float(c[:, 0].max()),
            float(c[:, 1].max()),
        )


def overlaps(a: Footprint, b: Footprint, margin: float = 0.0) -> bool:
    """Whether two footprints overlap in the plane (grown by ``margin``) and in height."""
    if a.z1 <= b.z0 or b.z1 <= a.z0:
        return False
    ca, cb = a.grown(margin).corners(), b.grown(margin).corners()
    for axis in np.vstack([a.axes(), b.axes()]):
        pa, pb = ca @ axis, cb @ axis
        if pa.max() <= pb.min() or pb.max() <= pa.min():
            return False
    return True


def inside(fp: Footprint, rect: tuple[float, float, float, float], margin: float = 0.0) -> bool:
    """Whether the footprint lies in the axis-aligned ``rect`` (x0, y0, x1, y1) shrunk by
    ``margin``."""
    x0, y0, x1, y1 = fp.aabb()
    return (
        x0 >= rect[0] + margin
        and y0 >= rect[1] + margin
        and x1 <= rect[2] - margin
        and y1 <= rect[3] - margin
    )
