"""The gap between two supports: the horizontal distance between their footprints' nearest
edges, what the mobile task's "away from" is measured by (:data:`MIN_SUPPORT_GAP`).

Each footprint is a rectangle (centre, half width along its x, half length along its y, yaw);
the gap is measured between their axis-aligned bounds, so a turned support counts a little
larger than it is (the gap is never overestimated).
"""

from __future__ import annotations

import math

__all__ = ["MIN_SUPPORT_GAP", "footprint_gap"]

MIN_SUPPORT_GAP = 1.5
"""Least gap (m) between the pick's support and the place support of a generated mobile-task
scene (its feasibility critic, :meth:`MobilePickPlaceTask.feasibility`). The Panda reaches
about 0.85 m from its shoulder and needs about 0.1 m into a top: one base pose between two tops
reaches both only while their nearest edges are closer than about 1.5 m, so at this gap the
base must drive."""


def _extent(hw: float, hl: float, yaw: float) -> tuple[float, float]:
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    return hw * c + hl * s, hw * s + hl * c


def footprint_gap(
    a: tuple[float, float, float, float, float], b: tuple[float, float, float, float, float]
) -> float:
    """The gap (m) between two footprints ``(x, y, half width, half length, yaw rad)``; 0 when
    they overlap."""
    aex, aey = _extent(a[2], a[3], a[4])
    bex, bey = _extent(b[2], b[3], b[4])
    dx = max(0.0, abs(a[0] - b[0]) - aex - bex)
    dy = max(0.0, abs(a[1] - b[1]) - aey - bey)
    return math.hypot(dx, dy)
