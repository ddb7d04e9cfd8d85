"""Floor plans in two dimensions: where the rooms of a home go and where they meet.

Pure geometry, no randomness: :func:`plan_layout` takes the room types and their drawn sizes
and returns a :class:`PlanLayout` (each room's footprint box, the doors' wall segments, the
entrance's outer wall segment); :mod:`factory.scenes.floorplan` turns it into the scene's rooms,
walls, doors and windows. Kinds of plan:

``row``
    one or two rooms side by side along x (a studio and its bathroom), the entrance on the
    first room's south wall: the plan of a single room, and of two rooms, is what it was.
``spine``
    three rooms or more around a *spine*, a strip across the whole home: a hallway (asked
    for, or added by :func:`with_circulation` to a home of five rooms or more, or to one
    without a living room, studio, kitchen or dining room) or the living room (an open
    living-kitchen: the kitchen opens onto it through a wide opening). South of the spine
    the day rooms (living room, kitchen, dining room, ...), north of it the night rooms
    (bedrooms with a bathroom between each pair, so every bathroom is next to a bedroom);
    rooms that could go either way (an office, a library, a laundry room) move to the
    shorter band. Every band room has a door to the spine, the entrance is on the spine's
    west wall (an outer wall), and the outline is a rectangle: each band's rooms are
    stretched in x to the home's width (bathrooms and other small rooms keep theirs when a
    larger room can take the width) and share the band's depth.

Frames: world, metres, z up; a box's ``(x0, y0)`` is its minimum corner. Walls of rooms
that meet lie on the same line (each room keeps its own four walls, as the scene schema
has them), and a door between two rooms is an opening in both.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from factory.schema.errors import FactoryError

TOL = 1e-6
"""Two coordinates closer than this (m) are the same line."""
DOOR_WIDTH = 0.9
"""A door's clear width (m)."""
WIDE_OPENING = 1.6
"""The widest opening between an open kitchen and the living or dining room (m)."""
DOOR_MARGIN = 0.15
"""Wall kept between a door and the end of the shared wall (m)."""

NIGHT: frozenset[str] = frozenset(
    {
        "bedroom",
        "children's room",
        "nursery",
        "guest room",
        "bathroom",
        "restroom",
        "walk-in closet",
    }
)
"""Room types that go north of the spine (the night zone)."""
SLEEPING: frozenset[str] = frozenset({"bedroom", "children's room", "nursery", "guest room"})
BATHS: frozenset[str] = frozenset({"bathroom", "restroom"})
FLEXIBLE: frozenset[str] = frozenset(
    {
        "office",
        "library",
        "game den",
        "gym",
        "laundry room",
        "home bar",
        "classroom",
        "playroom",
        "music room",
        "home theater",
        "craft room",
        "sewing room",
        "art studio",
        "yoga studio",
        "japanese room",
        "sunroom",
        "workshop",
        "utility room",
        "storage room",
        "wine cellar",
    }
)
"""Room types that may go to either band, to even out the bands' widths (the other rooms
of a home that are neither night rooms nor these, a pantry or a mudroom, go to the day
band)."""
SMALL: frozenset[str] = frozenset(
    {
        "bathroom",
        "restroom",
        "laundry room",
        "hallway",
        "pantry",
        "walk-in closet",
        "mudroom",
        "utility room",
    }
)
"""Room types that keep their width when a band is stretched (a larger room takes it)."""
HUBS: tuple[str, ...] = ("hallway", "living room", "studio", "kitchen", "dining room")
"""Room types that can be the spine, first preferred."""
DAY_ORDER: tuple[str, ...] = ("living room", "kitchen", "dining room")
"""The day band's first rooms, west to east (the living room next to the entrance)."""
OPEN_PAIRS: frozenset[frozenset[str]] = frozenset(
    {frozenset({"living room", "kitchen"}), frozenset({"kitchen", "dining room"})}
)
"""Room type pairs that meet through a wide opening rather than a door."""
HALLWAY_FROM = 5
"""Homes of this many rooms or more get a hallway when the request names none."""


class FloorPlanError(FactoryError, ValueError):
    """A floor plan that cannot be built (for instance two rooms that must meet and cannot)."""


@dataclass(frozen=True)
class Box:
    """A room's footprint: minimum corner ``(x0, y0)`` and extents (m, world frame)."""

    x0: float
    y0: float
    width: float
    length: float

    @property
    def x1(self) -> float:
        return self.x0 + self.width

    @property
    def y1(self) -> float:
        return self.y0 + self.length

    def overlap_area(self, other: Box) -> float:
        """The area (m²) the two boxes share (0 for boxes that only touch)."""
        dx = min(self.x1, other.x1) - max(self.x0, other.x0)
        dy = min(self.y1, other.y1) - max(self.y0, other.y0)
        return max(0.0, dx) * max(0.0, dy)


@dataclass(frozen=True)
class Segment:
    """A straight, axis-aligned piece of wall line (m, world frame).

    Attributes:
        axis: ``"x"``: the segment runs along x at ``y = at``; ``"y"``: along y at ``x = at``.
        at: the fixed coordinate (m).
        lo, hi: the varying coordinate's ends, ``lo < hi`` (m).
    """

    axis: str
    at: float
    lo: float
    hi: float

    @property
    def length(self) -> float:
        return self.hi - self.lo

    def point(self, t: float) -> tuple[float, float]:
        """The point at fraction ``t`` (0..1) from ``lo`` to ``hi``: ``(x, y)`` (m)."""
        u = self.lo + t * (self.hi - self.lo)
        return (u, self.at) if self.axis == "x" else (self.at, u)


@dataclass(frozen=True)
class Link:
    """A door (or a wide opening) between rooms ``a`` and ``b`` (indices into the plan's
    rooms), somewhere on their shared wall ``segment``; ``width`` is its clear width (m)."""

    a: int
    b: int
    segment: Segment
    width: float
    wide: bool = False


@dataclass(frozen=True)
class PlanLayout:
    """Where the rooms of a home go.

    Attributes:
        kind: ``row`` or ``spine`` (see the module's description).
        boxes: each room's footprint, in the order of the room types given.
        zones: each room's place: ``row``, ``spine``, ``south`` (day band), ``north`` (night).
        links: the doors between rooms; every room is reachable from the entrance through them.
        entrance_room: the room with the front door.
        entrance: the outer wall segment the front door goes on.
    """

    kind: str
    boxes: tuple[Box, ...]
    zones: tuple[str, ...]
    links: tuple[Link, ...]
    entrance_room: int
    entrance: Segment


def side_segment(box: Box, side: str) -> Segment:
    """One side of a box as a segment (``south``, ``east``, ``north``, ``west``)."""
    if side == "south":
        return Segment("x", box.y0, box.x0, box.x1)
    if side == "north":
        return Segment("x", box.y1, box.x0, box.x1)
    if side == "west":
        return Segment("y", box.x0, box.y0, box.y1)
    if side == "east":
        return Segment("y", box.x1, box.y0, box.y1)
    raise FloorPlanError(f"unknown side {side!r}: use south, east, north or west")


SIDES: tuple[str, ...] = ("south", "east", "north", "west")
"""A room's sides in the order of its walls."""


def shared_segment(a: Box, b: Box, tol: float = TOL) -> Segment | None:
    """The wall segment two boxes share (they touch along it), or ``None``."""
    for sa, sb in (("east", "west"), ("west", "east"), ("north", "south"), ("south", "north")):
        p, q = side_segment(a, sa), side_segment(b, sb)
        if abs(p.at - q.at) <= tol:
            lo, hi = max(p.lo, q.lo), min(p.hi, q.hi)
            if hi - lo > tol:
                return Segment(p.axis, p.at, lo, hi)
    return None


def outer_segments(k: int, boxes: tuple[Box, ...] | list[Box], side: str) -> list[Segment]:
    """The parts of room ``k``'s ``side`` that touch no other room: its outer walls there."""
    seg = side_segment(boxes[k], side)
    covered = []
    for j, other in enumerate(boxes):
        if j == k:
            continue
        s = shared_segment(boxes[k], other)
        if s is not None and s.axis == seg.axis and abs(s.at - seg.at) <= TOL:
            covered.append((s.lo, s.hi))
    out: list[Segment] = []
    u = seg.lo
    for lo, hi in sorted(covered):
        if lo > u + TOL:
            out.append(Segment(seg.axis, seg.at, u, lo))
        u = max(u, hi)
    if seg.hi > u + TOL:
        out.append(Segment(seg.axis, seg.at, u, seg.hi))
    return out


def with_circulation(types: list[str]) -> list[str]:
    """The room types of a plan: ``types``, plus a hallway at the end when the home needs one
    (five rooms or more, or three or more without a room that can be the spine)."""
    if len(types) < 3 or "hallway" in types:
        return list(types)
    if len(types) >= HALLWAY_FROM or not any(t in HUBS for t in types):
        return [*types, "hallway"]
    return list(types)


def _night_order(rooms: list[int], types: list[str]) -> list[int]:
    """Sleeping rooms west to east, a bathroom after the 1st, 3rd, ... so each is next to one;
    then the rest."""
    sleeping = [k for k in rooms if types[k] in SLEEPING]
    baths = [k for k in rooms if types[k] in BATHS]
    rest = [k for k in rooms if k not in sleeping and k not in baths]
    out: list[int] = []
    for i, k in enumerate(sleeping):
        out.append(k)
        if i % 2 == 0 and baths:
            out.append(baths.pop(0))
    return out + baths + rest


def _day_order(rooms: list[int], types: list[str]) -> list[int]:
    first = [k for t in DAY_ORDER for k in rooms if types[k] == t]
    return first + [k for k in rooms if k not in first]


def _balance(bands: dict[str, list[int]], widths: list[float], types: list[str]) -> None:
    """Moves flexible rooms to the narrower band while that evens the widths out."""
    for _ in range(len(widths)):
        w = {z: sum(widths[k] for k in ks) for z, ks in bands.items()}
        big, small = ("south", "north") if w["south"] > w["north"] else ("north", "south")
        diff = w[big] - w[small]
        movable = [k for k in bands[big] if types[k] in FLEXIBLE and widths[k] < diff - TOL]
        if not movable:
            return
        k = min(movable, key=lambda j: (abs(diff - 2 * widths[j]), j))
        bands[big].remove(k)
        bands[small].append(k)


def _stretch(band: list[int], widths: list[float], types: list[str], total: float) -> list[float]:
    """The band's room widths (m) grown to ``total``: the extra goes to the larger rooms in
    proportion to their widths (to every room when all are small)."""
    have = sum(widths[k] for k in band)
    takers = [k for k in band if types[k] not in SMALL] or list(band)
    share = sum(widths[k] for k in takers)
    extra = max(0.0, total - have)
    return [widths[k] + (extra * widths[k] / share if k in takers else 0.0) for k in band]


def _row(sizes: list[tuple[float, float]], open_link: bool = False) -> PlanLayout:
    length = max(ln for _, ln in sizes) if len(sizes) > 1 else sizes[0][1]
    boxes: list[Box] = []
    x = 0.0
    for width, _ in sizes:
        boxes.append(Box(x, 0.0, width, length))
        x += width
    links = []
    for k in range(len(boxes) - 1):
        seg = shared_segment(boxes[k], boxes[k + 1])
        assert seg is not None
        if open_link:  # an open plan: the shared wall is open but for short stubs
            links.append(Link(k, k + 1, seg, seg.length - 2 * DOOR_MARGIN, True))
        else:
            links.append(Link(k, k + 1, seg, DOOR_WIDTH))
    return PlanLayout(
        "row",
        tuple(boxes),
        ("row",) * len(boxes),
        tuple(links),
        0,
        side_segment(boxes[0], "south"),
    )


def plan_layout(
    types: list[str],
    sizes: list[tuple[float, float]],
    open_rooms: frozenset[str] = frozenset(),
) -> PlanLayout:
    """Lays out the rooms of a home (see the module's description).

    Args:
        types: room types, in the scene's room order (with the hallway
            :func:`with_circulation` added, if any).
        sizes: each room's drawn ``(width, length)`` (m): its extents along x and y when it
            stands alone; in a band, width runs along the band and length is its depth.
        open_rooms: an open plan's room types (:data:`~.homes.OPEN_PLAN_ROOMS`; empty: none):
            two of them that share a wall meet through an opening as wide as that wall but
            for :data:`DOOR_MARGIN` at each end, so that they are zones of one open space.

    Returns:
        the plan; rooms keep their order.

    Raises:
        FloorPlanError: no rooms, sizes that do not match the types, or a door that does not
            fit on the wall two rooms share.
    """
    if not types or len(types) != len(sizes):
        raise FloorPlanError(
            f"a floor plan needs one size per room type, got {len(types)} types and "
            f"{len(sizes)} sizes"
        )
    if len(types) <= 2:
        return _row(sizes, len(types) == 2 and set(types) <= open_rooms)
    spine = next((types.index(t) for t in HUBS if t in types), None)
    if spine is None:
        raise FloorPlanError(
            f"rooms {types} have no hallway or living room to join them: add one with "
            "with_circulation(types) first"
        )
    rest = [k for k in range(len(types)) if k != spine]
    bands = {
        "north": [k for k in rest if types[k] in NIGHT],
        "south": [k for k in rest if types[k] not in NIGHT],
    }
    widths = [w for w, _ in sizes]
    _balance(bands, widths, types)
    bands["north"] = _night_order(bands["north"], types)
    bands["south"] = _day_order(bands["south"], types)
    total = max(
        widths[spine] if types[spine] != "hallway" else 0.0,
        *(sum(widths[k] for k in ks) for ks in bands.values()),
    )

    def depth(band: list[int]) -> float:
        big = [sizes[k][1] for k in band if types[k] not in SMALL]
        return max(big or [sizes[k][1] for k in band] or [0.0])

    spine_depth = widths[spine] if types[spine] == "hallway" else sizes[spine][1]
    d_south, d_north = depth(bands["south"]), depth(bands["north"])
    boxes: list[Box | None] = [None] * len(types)
    zones = [""] * len(types)
    boxes[spine] = Box(0.0, d_south, total, spine_depth)
    zones[spine] = "spine"
    for zone, y0, d in (("south", 0.0, d_south), ("north", d_south + spine_depth, d_north)):
        x = 0.0
        band = bands[zone]
        for k, w in zip(band, _stretch(band, widths, types, total), strict=True):
            boxes[k] = Box(x, y0, w, d)
            zones[k] = zone
            x += w
    done = tuple(b for b in boxes if b is not None)
    assert len(done) == len(types)
    links: list[Link] = []
    spine_open = types[spine] in ("living room", "dining room", "studio")
    for zone in ("south", "north"):
        for k in bands[zone]:
            seg = shared_segment(done[k], done[spine])
            if seg is None:  # pragma: no cover - every band room spans its part of the spine
                raise FloorPlanError(f"room {k} ({types[k]}) does not touch the spine")
            whole = {types[k], types[spine]} <= open_rooms
            wide = whole or (spine_open and frozenset({types[k], types[spine]}) in OPEN_PAIRS)
            links.append(_link(spine, k, seg, wide, types, whole))
    south = bands["south"]
    for a, b in itertools.pairwise(south):  # an open living-kitchen in the day band
        whole = {types[a], types[b]} <= open_rooms
        if whole or (types[spine] == "hallway" and frozenset({types[a], types[b]}) in OPEN_PAIRS):
            seg = shared_segment(done[a], done[b])
            if seg is not None:
                links.append(_link(a, b, seg, True, types, whole))
    return PlanLayout(
        "spine",
        done,
        tuple(zones),
        tuple(links),
        spine,
        side_segment(done[spine], "west"),
    )


def _link(a: int, b: int, seg: Segment, wide: bool, types: list[str], whole: bool = False) -> Link:
    room = seg.length - 2 * DOOR_MARGIN
    width = room if whole else min(WIDE_OPENING, room) if wide else DOOR_WIDTH
    if room < DOOR_WIDTH:
        raise FloorPlanError(
            f"the {types[a]} and the {types[b]} share only {seg.length:.2f} m of wall, too "
            f"little for a {DOOR_WIDTH} m door: make the rooms wider"
        )
    return Link(a, b, seg, width, wide and width > DOOR_WIDTH)


def reachable(n: int, links: list[tuple[int, int]], start: int) -> set[int]:
    """The rooms (of ``n``) reachable from ``start`` through the doors ``links`` (pairs)."""
    seen = {start}
    todo = [start]
    while todo:
        k = todo.pop()
        for a, b in links:
            for u, v in ((a, b), (b, a)):
                if u == k and v not in seen:
                    seen.add(v)
                    todo.append(v)
    return seen & set(range(n))


__all__ = [
    "Box",
    "FloorPlanError",
    "Link",
    "PlanLayout",
    "Segment",
    "outer_segments",
    "plan_layout",
    "reachable",
    "shared_segment",
    "side_segment",
    "with_circulation",
]
