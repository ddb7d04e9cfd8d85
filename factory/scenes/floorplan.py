"""Floor plans: the rooms of a request (single or multi-room with doors) and their materials."""

from __future__ import annotations

import hashlib
import itertools
import logging
import re
from typing import Any

import numpy as np

from factory.scenes.request import parse_request
from factory.scenes.rooms import ROOM_TYPES
from factory.schema import Door, Room, Scene, Size3, Vec3, Wall, Window, check_id

log = logging.getLogger(__name__)

_NO_SURFACE_WORDS = frozenset({"clean", "spotless", "pristine", "brand-new", "brand new"})
"""Condition words that leave floors and walls as they are."""


def _room(
    rid: str,
    rt_name: str,
    x0: float,
    width: float,
    length: float,
    height: float,
    rng: np.random.Generator,
    condition: str = "",
) -> Room:
    """One rectangular room; ``condition`` (the request's condition words, "dusty old") goes
    before its floor and wall materials, which the compiler's textures read."""
    rt = ROOM_TYPES[rt_name]

    def worn(material: str) -> str:
        return f"{condition} {material}" if condition else material

    pts = [(x0, 0.0), (x0 + width, 0.0), (x0 + width, length), (x0, length)]
    names = ["south", "east", "north", "west"]
    walls = [
        Wall(
            id=f"{rid}_{n}",
            start=Vec3(*pts[i], 0.0),
            end=Vec3(*pts[(i + 1) % 4], 0.0),
            height=height,
            material=worn(str(rng.choice(rt.walls))),
        )
        for i, n in enumerate(names)
    ]
    north = walls[2]
    return Room(
        id=rid,
        room_type=rt_name,
        position=Vec3(x0, 0, 0),
        dimensions=Size3(width, length, height),
        walls=walls,
        windows=[
            Window(
                id=f"{rid}_window",
                wall_id=north.id,
                position_on_wall=0.5,
                width=min(1.4, 0.4 * north.length),
                height=1.2,
                sill_height=0.9,
            )
        ],
        floor_material=worn(str(rng.choice(rt.floors))),
        ceiling_height=height,
    )


def init_scene(
    request: str, seed: int = 0, scene_id: str | None = None, room_type: str | None = None
) -> tuple[Scene, dict[str, Any]]:
    """Builds the empty floor plan for the request: one room, or several in a row joined by
    doors for a home (:func:`~.request.parse_request` reads which); sizes, materials, walls,
    doors, windows. ``info["request"]`` is the parsed request's summary (language, rooms,
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
    sizes = []
    for t in types:
        (w0, w1), (l0, l1) = ROOM_TYPES[t].size
        sizes.append((forced_width or float(rng.uniform(w0, w1)), float(rng.uniform(l0, l1))))
    length = max(ln for _, ln in sizes) if len(types) > 1 else sizes[0][1]
    rooms: list[Room] = []
    x = 0.0
    used: dict[str, int] = {}
    for t, (width, _) in zip(types, sizes, strict=True):
        base = re.sub(r"[^a-z0-9]+", "_", t).strip("_") or "room"
        used[base] = used.get(base, 0) + 1
        rid = check_id(base if used[base] == 1 else f"{base}_{used[base]}", "room id")
        rooms.append(_room(rid, t, x, width, length, height, rng, condition))
        x += width
    # doors: an entrance on the first room's south wall, and one in each shared wall
    first = rooms[0]
    first.doors.append(
        Door(
            id=f"{first.id}_entrance",
            wall_id=first.walls[0].id,
            position_on_wall=float(rng.uniform(0.3, 0.7)),
            width=0.9,
            height=2.1,
        )
    )
    for a, b in itertools.pairwise(rooms):
        p = float(rng.uniform(0.3, 0.7))
        a.doors.append(
            Door(
                id=f"{a.id}_to_{b.id}",
                wall_id=a.walls[1].id,
                position_on_wall=p,
                width=0.9,
                height=2.1,
                opening=True,
            )
        )
        b.doors.append(
            Door(
                id=f"{b.id}_to_{a.id}",
                wall_id=b.walls[3].id,
                position_on_wall=1.0 - p,
                width=0.9,
                height=2.1,
                opening=True,
            )
        )
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
            }
            for r in rooms
        ],
        "size_m": [round(first.dimensions.width, 2), round(first.dimensions.length, 2)],
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
