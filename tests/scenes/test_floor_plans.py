"""Floor plans of homes: rooms in two dimensions around a hallway or the living room, doors
where rooms meet, windows on outer walls, the entrance outside; cameras inside the rooms."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from factory.scenes.floorplan import init_scene
from factory.scenes.plan_layout import (
    SLEEPING,
    Box,
    FloorPlanError,
    Segment,
    outer_segments,
    plan_layout,
    reachable,
    shared_segment,
    with_circulation,
)
from factory.scenes.render import PLAN, ROOMS, expand_views, render_views, view_cameras
from factory.scenes.rooms import ROOM_TYPES
from factory.schema import Door, Room, Scene, Wall, Window, scene_from_json, scene_to_json, validate

HOMES = [
    "a flat",
    "a family home",
    "a family home with three bedrooms",
    "a two-bedroom flat",
    "a villa",
    "a mansion",
    "a four-room apartment",
    "a three-room apartment",
    "a five-room apartment",
    "a flat with two bedrooms, a study and a laundry room",
    "a house with a hallway, a kitchen and two bedrooms",
]


def _box(room: Room) -> Box:
    return Box(room.position.x, room.position.y, room.dimensions.width, room.dimensions.length)


def _span(wall: Wall, op: Door | Window) -> tuple[tuple[float, float], tuple[float, float]]:
    ux, uy = (wall.end.x - wall.start.x) / wall.length, (wall.end.y - wall.start.y) / wall.length
    c = op.position_on_wall * wall.length
    return (
        (wall.start.x + ux * (c - op.width / 2), wall.start.y + uy * (c - op.width / 2)),
        (wall.start.x + ux * (c + op.width / 2), wall.start.y + uy * (c + op.width / 2)),
    )


def _on(seg: Segment, p: tuple[float, float], q: tuple[float, float], tol: float = 1e-6) -> bool:
    """Whether the span p..q lies on the segment."""
    k = 1 if seg.axis == "x" else 0  # the fixed coordinate's index
    u = [p[1 - k], q[1 - k]]
    return (
        abs(p[k] - seg.at) <= tol
        and abs(q[k] - seg.at) <= tol
        and seg.lo - tol <= min(u)
        and max(u) <= seg.hi + tol
    )


def _door_graph(scene: Scene) -> tuple[list[tuple[int, int]], int]:
    """Doors as pairs of room indices (each door matched by one at the same place in the other
    room), and the room with the entrance."""
    index = {r.id: k for k, r in enumerate(scene.rooms)}
    boxes = [_box(r) for r in scene.rooms]
    pairs: list[tuple[int, int]] = []
    entrance = -1
    for k, room in enumerate(scene.rooms):
        walls = {w.id: w for w in room.walls}
        for door in room.doors:
            p, q = _span(walls[door.wall_id], door)
            if door.id.endswith("_entrance"):
                entrance = k
                outer = [
                    s
                    for side in ("south", "east", "north", "west")
                    for s in outer_segments(k, boxes, side)
                ]
                assert any(_on(s, p, q) for s in outer), f"{door.id} is not on an outer wall"
                continue
            other = door.id.split("_to_", 1)[1]
            j = index[other]
            seg = shared_segment(boxes[k], boxes[j])
            assert seg is not None, f"{door.id}: {room.id} and {other} do not meet"
            assert _on(seg, p, q), f"{door.id} is not on the wall {room.id} shares with {other}"
            back = [d for d in scene.rooms[j].doors if d.id == f"{other}_to_{room.id}"]
            assert len(back) == 1, f"{door.id} has no opening on the other side"
            bw = {w.id: w for w in scene.rooms[j].walls}[back[0].wall_id]
            bp, bq = _span(bw, back[0])
            assert {tuple(np.round(p, 6)), tuple(np.round(q, 6))} == {
                tuple(np.round(bp, 6)),
                tuple(np.round(bq, 6)),
            }, f"{door.id} and its other side do not line up"
            pairs.append((k, j))
    return pairs, entrance


@pytest.mark.parametrize("request_text", HOMES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_home_plans_are_real_floor_plans(request_text: str, seed: int) -> None:
    scene, info = init_scene(request_text, seed)
    validate(scene)
    n = len(scene.rooms)
    assert n >= 3, [r.room_type for r in scene.rooms]
    assert info["plan"] == "spine"
    boxes = [_box(r) for r in scene.rooms]
    # no overlap; the rooms fill a rectangle (no outside space inside the outline)
    for a in range(n):
        for b in range(a + 1, n):
            assert boxes[a].overlap_area(boxes[b]) < 1e-9, (scene.rooms[a].id, scene.rooms[b].id)
    xmin, ymin, xmax, ymax = scene.bounds_xy()
    assert sum(b.width * b.length for b in boxes) == pytest.approx((xmax - xmin) * (ymax - ymin))
    assert len({round(b.y0, 6) for b in boxes}) >= 2, "the rooms are in a row"
    # every room reachable from the entrance through doors that lie on shared walls
    pairs, entrance = _door_graph(scene)
    assert entrance >= 0
    assert reachable(n, pairs, entrance) == set(range(n))
    # the entrance is in the hallway, or in the living room when there is no hallway
    types = [r.room_type for r in scene.rooms]
    assert types[entrance] == ("hallway" if "hallway" in types else types[entrance])
    if "hallway" not in types and "living room" in types:
        assert types[entrance] == "living room"
    # windows only on outer walls, and every room but the hallway has one
    for k, room in enumerate(scene.rooms):
        walls = {w.id: w for w in room.walls}
        outer = [
            s for side in ("south", "east", "north", "west") for s in outer_segments(k, boxes, side)
        ]
        for win in room.windows:
            assert any(_on(s, *_span(walls[win.wall_id], win)) for s in outer), win.id
        if room.room_type != "hallway":
            assert room.windows, f"{room.id} has no window"
    # bathrooms next to a bedroom or the hallway
    near = SLEEPING | {"hallway"}
    if any(t in SLEEPING for t in types):
        for k, t in enumerate(types):
            if t == "bathroom":
                assert any(
                    (s := shared_segment(boxes[k], boxes[j])) is not None and s.length > 1.0
                    for j in range(n)
                    if types[j] in near
                ), f"{scene.rooms[k].id} is next to no bedroom or hallway"
    # sensible sizes: never smaller than the room type's smallest
    for room in scene.rooms:
        (w0, _), (l0, _) = ROOM_TYPES[room.room_type].size
        assert min(room.dimensions.width, room.dimensions.length) >= min(w0, l0) - 1e-9, room.id


def test_plans_are_deterministic_per_seed() -> None:
    a, _ = init_scene("a family home", 5)
    b, _ = init_scene("a family home", 5)
    c, _ = init_scene("a family home", 6)
    assert scene_to_json(a) == scene_to_json(b) != scene_to_json(c)


def test_one_and_two_rooms_keep_their_plan() -> None:
    """A single room and two rooms side by side are what they were: the entrance on the first
    room's south wall, the second room east of the first, a door in the wall between."""
    scene, info = init_scene("a two-room apartment with a living room and a study", 0)
    assert info["plan"] == "row"
    a, b = scene.rooms
    assert a.position.x + a.dimensions.width == pytest.approx(b.position.x)
    assert a.position.y == b.position.y == 0.0
    assert [d.wall_id for d in a.doors] == [f"{a.id}_south", f"{a.id}_east"]
    assert [d.wall_id for d in b.doors] == [f"{b.id}_west"]
    assert a.doors[1].position_on_wall == pytest.approx(1.0 - b.doors[0].position_on_wall)
    single, info = init_scene("a cozy bedroom", 0)
    assert info["plan"] == "row" and len(single.rooms) == 1
    assert single.rooms[0].windows[0].wall_id.endswith("_north")


def test_circulation_and_layout_rules() -> None:
    assert with_circulation(["bedroom", "kitchen"]) == ["bedroom", "kitchen"]
    assert with_circulation(["bedroom", "living room", "kitchen", "bathroom"])[-1] == "bathroom"
    big = ["bedroom", "bedroom", "living room", "kitchen", "bathroom"]
    assert with_circulation(big) == [*big, "hallway"]
    assert with_circulation(["bedroom", "bedroom", "bathroom"])[-1] == "hallway"
    with pytest.raises(FloorPlanError, match="no hallway or living room"):
        plan_layout(["bedroom", "bedroom", "bathroom"], [(4.0, 4.0)] * 3)
    with pytest.raises(FloorPlanError, match="one size per room type"):
        plan_layout(["bedroom"], [])
    # an open living-kitchen: the kitchen opens onto the living room through a wide opening
    plan = plan_layout(
        ["bedroom", "living room", "kitchen", "bathroom"], [(4, 4), (5, 5), (4, 4), (2.5, 3)]
    )
    kitchen = [link for link in plan.links if {link.a, link.b} == {1, 2}]
    assert len(kitchen) == 1 and kitchen[0].wide and kitchen[0].width > 0.9
    assert plan.zones[1] == "spine" and plan.zones[0] == plan.zones[3] == "north"


def test_cameras_stand_inside_rooms() -> None:
    """Corner and room views stand inside a room (not across a wall); the plan view is
    orthographic over the whole home."""
    scene, _ = init_scene("a family home", 1)
    cams = view_cameras(scene)
    views = expand_views(scene, ["top", PLAN, "corner_0", ROOMS])
    assert views[:3] == ["top", "plan", "corner_0"]
    assert sorted(views[3:]) == sorted(f"room_{r.id}" for r in scene.rooms)
    assert cams[PLAN].orthographic and cams[PLAN].elevation == -90.0
    xmin, ymin, xmax, ymax = scene.bounds_xy()
    assert cams[PLAN].fovy >= max(ymax - ymin, (xmax - xmin) * 3 / 4)

    def eye(name: str) -> tuple[float, float]:
        c = cams[name]
        az, el = math.radians(c.azimuth), math.radians(c.elevation)
        return (
            c.lookat[0] - c.distance * math.cos(el) * math.cos(az),
            c.lookat[1] - c.distance * math.cos(el) * math.sin(az),
        )

    def inside(room: Room, p: tuple[float, float]) -> bool:
        t = 0.1  # the wall's inner face is 5 cm in
        return (
            room.position.x + t < p[0] < room.position.x + room.dimensions.width - t
            and room.position.y + t < p[1] < room.position.y + room.dimensions.length - t
        )

    for room in scene.rooms:
        name = f"room_{room.id}"
        assert inside(room, eye(name)), name
        assert inside(room, cams[name].lookat[:2]), name  # looks at its own floor
    for k in range(4):
        e = eye(f"corner_{k}")
        holder = [r for r in scene.rooms if inside(r, e)]
        assert len(holder) == 1 and inside(holder[0], cams[f"corner_{k}"].lookat[:2])


def test_home_views_render(tmp_path: Path) -> None:
    from factory.sim.compile import compile_scene

    scene, _ = init_scene("a four-room apartment", 2)
    model = compile_scene(scene).model
    room = scene.rooms[0].id
    images = render_views(model, scene, [PLAN, f"room_{room}"], 96, 72)
    assert list(images) == [PLAN, f"room_{room}"]
    for view, im in images.items():
        assert im.shape == (72, 96, 3) and im.std() > 5, view
    with pytest.raises(Exception, match="unknown view"):
        render_views(model, scene, ["room_attic"], 64, 48)


def test_generate_a_home_through_the_cli(cli, tmp_path: Path) -> None:
    """The real CLI generates a small home with its plan and room views."""
    run = tmp_path / "run"
    out = cli(
        "stage=generate",
        "profile=small",
        f"run_dir={run}",
        'generate.prompts=["a three-room apartment"]',
        "generate.max_objects=6",
        "generate.physics_critic=false",
        "render.views=[plan,rooms]",
        "render.width=96",
        "render.height=72",
    )
    assert out.returncode == 0, out.stderr
    (scene_dir,) = (run / "scenes").iterdir()
    scene = scene_from_json((scene_dir / "scene.json").read_text())
    validate(scene)
    assert [r.room_type for r in scene.rooms] == ["bedroom", "kitchen", "bathroom"]
    assert len({r.position.y for r in scene.rooms}) == 2  # kitchen south, the others north
    assert all(any(o.room_id == r.id for o in scene.objects) for r in scene.rooms)
    renders = sorted(p.name for p in (scene_dir / "renders").iterdir())
    assert renders == ["plan.png", "room_bathroom.png", "room_bedroom.png", "room_kitchen.png"]


def test_open_plan_joins_the_day_rooms() -> None:
    """ "open-plan" (or a loft) makes the home's day rooms zones of one open space: two of them
    that share a wall meet through an opening as wide as that wall but for short stubs; the
    same home without the word keeps doors and a 1.6 m kitchen opening."""
    from factory.scenes.homes import OPEN_PLAN_ROOMS
    from factory.scenes.plan_layout import DOOR_MARGIN
    from factory.scenes.request import parse_request

    assert parse_request("an open-plan loft").open_plan
    assert not parse_request("a loft bed").open_plan  # one room: nothing to open
    assert not parse_request("a family home").open_plan

    def day_doors(request: str) -> list[tuple[Door, float]]:
        scene, _ = init_scene(request, seed=1)
        rooms = {r.id: r for r in scene.rooms}
        out = []
        for room in scene.rooms:
            walls = {w.id: w for w in room.walls}
            for door in room.doors:
                other = door.id.rpartition("_to_")[2]
                if other in rooms and {room.room_type, rooms[other].room_type} <= OPEN_PLAN_ROOMS:
                    w = walls[door.wall_id]
                    length = math.dist((w.start.x, w.start.y), (w.end.x, w.end.y))
                    out.append((door, length))
        return out

    request = "an apartment with a kitchen, a living room, a dining room and a bedroom"
    closed = day_doors(request)
    assert closed and all(d.width <= 1.6 + 1e-6 for d, _ in closed)
    opened = day_doors("an open-plan " + request.removeprefix("an "))
    assert len(opened) >= len(closed)
    shared = [d for d, _ in opened if d.door_type == "opening" and d.width > 1.6]
    assert shared, [(d.id, d.width) for d, _ in opened]
    for d in shared:
        assert d.width >= 2.0 - 2 * DOOR_MARGIN
