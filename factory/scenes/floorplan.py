"""Floor plans: the rooms of a request (one room, or a home laid out in two dimensions by
:mod:`factory.scenes.plan_layout`), their walls, doors, windows and materials."""

from __future__ import annotations

import hashlib
import logging
import re
from typing import Any

import numpy as np

from factory.scenes.homes import OPEN_PLAN_ROOMS
from factory.scenes.plan_layout import (
    DOOR_MARGIN,
    DOOR_WIDTH,
    SIDES,
    TOL,
    Box,
    FloorPlanError,
    PlanLayout,
    Segment,
    outer_segments,
    plan_layout,
    with_circulation,
)
from factory.scenes.request import parse_request
from factory.scenes.rooms import ROOM_TYPES
from factory.schema import Door, Room, Scene, Size3, Vec3, Wall, Window, check_id

log = logging.getLogger(__name__)

_NO_SURFACE_WORDS = frozenset({"clean", "spotless", "pristine", "brand-new", "brand new"})
"""Condition words that leave floors and walls as they are."""


def _room(
    rid: str,
    rt_name: str,
    box: Box,
    height: float,
    rng: np.random.Generator,
    condition: str = "",
) -> Room:
    """One rectangular room on ``box`` (its four walls counter-clockwise from the south one);
    ``condition`` (the request's condition words, "dusty old") goes before its floor and wall
    materials, which the compiler's textures read. Doors and windows come later."""
    rt = ROOM_TYPES[rt_name]

    def worn(material: str) -> str:
        return f"{condition} {material}" if condition else material

    x0, y0 = box.x0, box.y0
    pts = [(x0, y0), (box.x1, y0), (box.x1, box.y1), (x0, box.y1)]
    walls = [
        Wall(
            id=f"{rid}_{n}",
            start=Vec3(*pts[i], 0.0),
            end=Vec3(*pts[(i + 1) % 4], 0.0),
            height=height,
            material=worn(str(rng.choice(rt.walls))),
        )
        for i, n in enumerate(SIDES)
    ]
    return Room(
        id=rid,
        room_type=rt_name,
        position=Vec3(x0, y0, 0),
        dimensions=Size3(box.width, box.length, height),
        walls=walls,
        floor_material=worn(str(rng.choice(rt.floors))),
        ceiling_height=height,
    )


def _at(room: Room, seg: Segment, t: float) -> tuple[str, float]:
    """The wall of ``room`` that holds ``seg``, and the ``position_on_wall`` (0..1 from the
    wall's start) of the point at fraction ``t`` of ``seg`` (from its low end).

    Raises:
        FloorPlanError: no wall of the room holds the segment.
    """
    for wall in room.walls:
        sx, sy, ex, ey = wall.start.x, wall.start.y, wall.end.x, wall.end.y
        along_x = abs(sy - ey) < TOL
        if (seg.axis == "x") != along_x or abs((sy if along_x else sx) - seg.at) > TOL:
            continue
        a, b = (sx, ex) if along_x else (sy, ey)
        if seg.lo < min(a, b) - TOL or seg.hi > max(a, b) + TOL:
            continue
        fa, fb = (seg.lo - a) / (b - a), (seg.hi - a) / (b - a)
        if abs(fa) < TOL:
            fa = 0.0
        if abs(fb - 1.0) < TOL:
            fb = 1.0
        if abs(fa - 1.0) < TOL:  # the wall runs against the segment
            fa = 1.0
        if abs(fb) < TOL:
            fb = 0.0
        if (fa, fb) == (0.0, 1.0):  # exact for a whole wall, either way round
            pos = t
        elif (fa, fb) == (1.0, 0.0):
            pos = 1.0 - t
        else:
            pos = fa + t * (fb - fa)
        return wall.id, min(1.0, max(0.0, pos))
    raise FloorPlanError(f"no wall of room {room.id!r} holds the wall segment {seg}")


def _doors(rooms: list[Room], plan: PlanLayout, rng: np.random.Generator) -> None:
    """The entrance (on an outer wall of the plan's entrance room) and a door in both rooms
    of each link, at a random place of the wall they share (a wide opening in the middle)."""
    first = rooms[plan.entrance_room]
    wall_id, pos = _at(first, plan.entrance, float(rng.uniform(0.3, 0.7)))
    first.doors.append(
        Door(
            id=f"{first.id}_entrance", wall_id=wall_id, position_on_wall=pos, width=0.9, height=2.1
        )
    )
    for link in plan.links:
        p = float(rng.uniform(0.3, 0.7))
        seg = link.segment
        if link.wide:
            p = 0.5
        else:  # keep the door off the ends of the shared wall
            half = (DOOR_WIDTH / 2 + DOOR_MARGIN) / seg.length
            p = min(max(p, half), 1.0 - half)
        for k, j in ((link.a, link.b), (link.b, link.a)):
            wall_id, pos = _at(rooms[k], seg, p)
            rooms[k].doors.append(
                Door(
                    id=f"{rooms[k].id}_to_{rooms[j].id}",
                    wall_id=wall_id,
                    position_on_wall=pos,
                    width=link.width,
                    height=2.1,
                    door_type="opening" if link.wide else "standard",
                    opening=True,
                )
            )


def _windows(rooms: list[Room], plan: PlanLayout) -> None:
    """A window per room, in the middle of its longest outer wall piece (north first, then
    south, east, west), never on the entrance's wall piece; a room with no outer wall piece
    of 1 m or more gets none."""
    for k, room in enumerate(rooms):
        for side in ("north", "south", "east", "west"):
            pieces = [
                s
                for s in outer_segments(k, plan.boxes, side)
                if s.length >= 1.0 and not (k == plan.entrance_room and s == plan.entrance)
            ]
            if not pieces:
                continue
            seg = max(pieces, key=lambda s: s.length)
            wall_id, pos = _at(room, seg, 0.5)
            room.windows.append(
                Window(
                    id=f"{room.id}_window",
                    wall_id=wall_id,
                    position_on_wall=pos,
                    width=min(1.4, 0.4 * seg.length),
                    height=1.2,
                    sill_height=0.9,
                )
            )
            break


def init_scene(
    request: str, seed: int = 0, scene_id: str | None = None, room_type: str | None = None
) -> tuple[Scene, dict[str, Any]]:
    """Builds the empty floor plan for the request: one room, or a home
    (:func:`~.request.parse_request` reads which; two rooms side by side, three or more around
    a hallway or the living room, :func:`~.plan_layout.plan_layout`); sizes, materials,
    walls, doors (an entrance on an outer wall, one where rooms meet), windows on outer
    walls. ``info["rooms"]`` lists the rooms with their zone, ``info["plan"]`` the plan's
    kind. ``info["request"]`` is the parsed request's summary (language, rooms,
    style, condition words, materials, translations, warnings).

    Raises:
        ValueError: a request too small to hold a room (e.g. "0.5 m wide").
    """
    rng = np.random.default_rng(seed)
    parsed = parse_request(request)
    types = [room_type] if room_type else list(parsed.room_types)
    m = re.search(r"(\d+(?:\.\d+)?)\s*(?:m|meters?|metres?)\s*(?:wide|by)", request.lower())
    forced_width = float(m.group(1)) if m else None
    if forced_width is not None and forced_width < 1.5:
        raise ValueError(
            f"a room {forced_width} m wide cannot hold furniture: ask for at least 1.5 m"
        )
    height = 2.7
    # condition words weather the rooms too ("clean" is no weathering)
    condition = " ".join(w for w in parsed.condition_words if w not in _NO_SURFACE_WORDS)
    types = with_circulation(types)
    sizes = []
    for t in types:
        (w0, w1), (l0, l1) = ROOM_TYPES[t].size
        sizes.append((forced_width or float(rng.uniform(w0, w1)), float(rng.uniform(l0, l1))))
    plan = plan_layout(types, sizes, OPEN_PLAN_ROOMS if parsed.open_plan else frozenset())
    rooms: list[Room] = []
    used: dict[str, int] = {}
    for t, box in zip(types, plan.boxes, strict=True):
        base = re.sub(r"[^a-z0-9]+", "_", t).strip("_") or "room"
        used[base] = used.get(base, 0) + 1
        rid = check_id(base if used[base] == 1 else f"{base}_{used[base]}", "room id")
        rooms.append(_room(rid, t, box, height, rng, condition))
    _windows(rooms, plan)
    _doors(rooms, plan, rng)
    first = rooms[0]
    digest = hashlib.sha1(f"{request}|{seed}".encode()).hexdigest()[:8]
    sid = scene_id or f"{first.id}_{digest}"
    scene = Scene(
        id=sid,
        rooms=rooms,
        description=request,
        source="text",
        seed=seed,
        building_style=parsed.style,
    )
    info: dict[str, Any] = {
        "room_type": first.room_type,
        "room_id": first.id,
        "rooms": [
            {
                "id": r.id,
                "room_type": r.room_type,
                "size_m": [round(r.dimensions.width, 2), round(r.dimensions.length, 2)],
                "zone": zone,
            }
            for r, zone in zip(rooms, plan.zones, strict=True)
        ],
        "size_m": [round(first.dimensions.width, 2), round(first.dimensions.length, 2)],
        "plan": plan.kind,
        "entrance_room": rooms[plan.entrance_room].id,
        "floor": first.floor_material,
        "request": parsed.summary(),
    }
    if room_type is None:
        for warning in parsed.warnings:  # words not understood, no room named
            log.warning("%s", warning)
    if room_type is None and not parsed.names_a_room:
        info["approximated"] = True
        info["note"] = (
            f"no known room type in {request!r} (another language?); built a {first.room_type}"
        )
    return scene, info
