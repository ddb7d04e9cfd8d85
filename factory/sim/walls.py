"""Wall geometry: a wall minus its door and window openings, as axis-aligned boxes.

Coordinates along a wall: ``u`` runs from the wall's start (0) to its end (``length``, m), ``z``
from the floor. An opening centred at ``position_on_wall`` (0..1) spans
``u = position_on_wall * length +- width / 2`` and, for doors, ``z = 0 .. height``; for windows
``z = sill_height .. sill_height + height``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from factory.schema import Door, Wall, Window


@dataclass(frozen=True)
class Rect:
    """A rectangle in wall coordinates: ``u0 <= u <= u1``, ``z0 <= z <= z1`` (m)."""

    u0: float
    u1: float
    z0: float
    z1: float


def opening_rect(wall: Wall, op: Door | Window) -> Rect:
    """The opening's rectangle in wall coordinates, clipped to the wall."""
    centre = op.position_on_wall * wall.length
    z0 = op.sill_height if isinstance(op, Window) else 0.0
    return Rect(
        max(0.0, centre - op.width / 2),
        min(wall.length, centre + op.width / 2),
        max(0.0, z0),
        min(wall.height, z0 + op.height),
    )


def solid_rects(wall: Wall, openings: list[Door | Window], eps: float = 1e-9) -> list[Rect]:
    """The solid part of a wall as disjoint rectangles (sweep over ``u``).

    Args:
        wall: the wall (its ``length`` and ``height``).
        openings: doors and windows on this wall.

    Returns:
        rectangles covering the wall minus the openings; adjacent columns with equal z-ranges
        are merged so a plain wall is one rectangle.
    """
    holes = [opening_rect(wall, op) for op in openings]
    holes = [h for h in holes if h.u1 - h.u0 > eps and h.z1 - h.z0 > eps]
    cuts = sorted({0.0, wall.length, *(h.u0 for h in holes), *(h.u1 for h in holes)})
    columns: list[tuple[float, float, list[tuple[float, float]]]] = []
    for u0, u1 in itertools.pairwise(cuts):
        if u1 - u0 <= eps:
            continue
        mid = (u0 + u1) / 2
        blocked = sorted((h.z0, h.z1) for h in holes if h.u0 < mid < h.u1)
        spans: list[tuple[float, float]] = []
        z = 0.0
        for b0, b1 in blocked:
            if b0 > z + eps:
                spans.append((z, b0))
            z = max(z, b1)
        if wall.height > z + eps:
            spans.append((z, wall.height))
        if columns and columns[-1][2] == spans and abs(columns[-1][1] - u0) <= eps:
            columns[-1] = (columns[-1][0], u1, spans)
        else:
            columns.append((u0, u1, spans))
    return [Rect(u0, u1, z0, z1) for u0, u1, spans in columns for z0, z1 in spans]
