"""Wall geometry: a wall minus its door and window openings, as axis-aligned boxes, and the
part of the floor plan each room's walls may fill.

Coordinates along a wall: ``u`` runs from the wall's start (0) to its end (``length``, m), ``z``
from the floor. An opening centred at ``position_on_wall`` (0..1) spans
``u = position_on_wall * length +- width / 2`` and, for doors, ``z = 0 .. height``; for windows
``z = sill_height .. sill_height + height``.

Shared walls: a room's walls are centred on the edges of its footprint, so where two rooms meet
both rooms' wall pieces would fill the same slab, and a renderer flickers between their
materials (z-fighting). :func:`wall_keepout` gives, per room, the plan rectangles its wall
pieces must leave out (:func:`subtract`): every other room's footprint (so each room's wall
keeps to its own side of a shared wall, half the thickness each) and the wall band around each
earlier room's footprint (the corners and ends where outer walls of two rooms meet go to the
first). Every point of the plan is thus filled by at most one room's walls.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

from factory.schema import Door, Room, Wall, Window


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


@dataclass(frozen=True)
class PlanRect:
    """An axis-aligned rectangle of the floor plan: ``x0 <= x <= x1``, ``y0 <= y <= y1``
    (world frame, m)."""

    x0: float
    y0: float
    x1: float
    y1: float

    def overlaps(self, other: PlanRect, eps: float = 1e-9) -> bool:
        """Whether the two rectangles share an area (touching edges do not count)."""
        return (
            min(self.x1, other.x1) - max(self.x0, other.x0) > eps
            and min(self.y1, other.y1) - max(self.y0, other.y0) > eps
        )

    def grown(self, d: float) -> PlanRect:
        """The rectangle grown by ``d`` (m) on every side."""
        return PlanRect(self.x0 - d, self.y0 - d, self.x1 + d, self.y1 + d)


def footprint(room: Room) -> PlanRect:
    """A room's footprint (its floor rectangle)."""
    x0, y0 = room.position.x, room.position.y
    return PlanRect(x0, y0, x0 + room.dimensions.width, y0 + room.dimensions.length)


def subtract(rect: PlanRect, holes: Sequence[PlanRect], eps: float = 1e-9) -> list[PlanRect]:
    """``rect`` minus the union of ``holes``, as disjoint rectangles.

    The rectangle is cut into a grid at the holes' edges; the cells outside every hole are
    merged along x within a row, then rows of equal spans along y.

    Returns:
        ``[rect]`` itself when no hole overlaps it; ``[]`` when the holes cover it.
    """
    holes = [h for h in holes if rect.overlaps(h, eps)]
    if not holes:
        return [rect]

    def cuts(lo: float, hi: float, edges: list[float]) -> list[float]:
        inner = sorted({e for e in edges if lo + eps < e < hi - eps})
        return [lo, *inner, hi]

    xs = cuts(rect.x0, rect.x1, [e for h in holes for e in (h.x0, h.x1)])
    ys = cuts(rect.y0, rect.y1, [e for h in holes for e in (h.y0, h.y1)])
    rows: list[tuple[float, float, list[tuple[float, float]]]] = []
    for y0, y1 in itertools.pairwise(ys):
        ym = (y0 + y1) / 2
        spans: list[tuple[float, float]] = []
        for x0, x1 in itertools.pairwise(xs):
            xm = (x0 + x1) / 2
            if any(h.x0 < xm < h.x1 and h.y0 < ym < h.y1 for h in holes):
                continue
            if spans and abs(spans[-1][1] - x0) <= eps:
                spans[-1] = (spans[-1][0], x1)
            else:
                spans.append((x0, x1))
        if rows and rows[-1][2] == spans and abs(rows[-1][1] - y0) <= eps:
            rows[-1] = (rows[-1][0], y1, spans)
        else:
            rows.append((y0, y1, spans))
    return [PlanRect(x0, y0, x1, y1) for y0, y1, spans in rows for x0, x1 in spans]


def wall_keepout(rooms: Sequence[Room]) -> list[list[PlanRect]]:
    """Per room (in order), the plan rectangles its wall pieces leave out: the other rooms'
    footprints, and for each earlier room the band of its walls (its footprint grown by its
    thickest wall's half thickness) outside this room's footprint. A room's own footprint is
    never left out, so each room keeps the inner half of all its walls."""
    feet = [footprint(r) for r in rooms]
    bands = [
        f.grown(max((w.thickness for w in r.walls), default=0.0) / 2)
        for f, r in zip(feet, rooms, strict=True)
    ]
    out: list[list[PlanRect]] = []
    for i, own in enumerate(feet):
        keep = [f for j, f in enumerate(feet) if j != i]
        for j in range(i):
            if bands[j].overlaps(bands[i]):
                keep += subtract(bands[j], [own])
        out.append(keep)
    return out
