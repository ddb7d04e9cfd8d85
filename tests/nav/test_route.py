"""The mobile task's route check on hand-built two-room homes: a pass through the door, and
each failure with its reason (no route, no place support, too close, too small, no spawn
area)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

from factory.nav.errors import NavError
from factory.nav.goals import BasePose
from factory.nav.grid import OccupancyGrid
from factory.nav.route import (
    MIN_SUPPORT_SEPARATION,
    NO_PLACE_SUPPORT,
    NO_ROUTE,
    NO_SPAWN_AREA,
    PLACE_SUPPORT_TOO_CLOSE,
    PLACE_SUPPORT_TOO_SMALL,
    ROUTE_REASONS,
    check_route,
    free_poses,
    is_mobile_task,
    pose_labels,
    route_scene_check,
    se2_labels,
)
from factory.nav.task_poses import MOBILE_FOOTPRINT
from factory.schema import (
    Door,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Task,
    Vec3,
    Wall,
)

ROOM_L = 4.0
"""Length (y, m) of both rooms; the living room spans x 0..4, the study x 4..8."""
DOOR_Y = (1.6, 2.5)
"""The door in the shared wall x = 4: y from, y to (m)."""


def _room(rid: str, x0: float, width: float, length: float, door: bool, west: bool) -> Room:
    corners = [(x0, 0.0), (x0 + width, 0.0), (x0 + width, length), (x0, length)]
    names = ["south", "east", "north", "west"]
    walls = [
        Wall(id=f"{rid}_{n}", start=Vec3(*a, 0.0), end=Vec3(*b, 0.0), height=2.5)
        for n, a, b in zip(names, corners, corners[1:] + corners[:1], strict=True)
    ]
    doors = []
    if door:  # on the shared wall: the east wall runs +y, the west wall -y
        mid = (DOOR_Y[0] + DOOR_Y[1]) / 2 / length
        wall, t = (f"{rid}_west", 1.0 - mid) if west else (f"{rid}_east", mid)
        doors.append(
            Door(id=f"{rid}_door", wall_id=wall, position_on_wall=t, width=0.9, height=2.1)
        )
    return Room(
        id=rid,
        room_type="office" if west else "living_room",
        position=Vec3(x0, 0.0, 0.0),
        dimensions=Size3(width, length, 2.7),
        walls=walls,
        doors=doors,
    )


def _box(
    oid: str,
    room: str,
    xy: tuple[float, float],
    size: tuple[float, float, float],
    role: str | None = None,
    mass: float = 20.0,
    static: bool = False,
) -> SceneObject:
    return SceneObject(
        id=oid,
        room_id=room,
        category=oid.rstrip("0123456789_"),
        position=Vec3(*xy, 0.0),
        dimensions=Size3(*size),
        physics=Physics(mass=mass, static=static),
        task_role=role,
    )


def home(
    door: bool = True,
    desk: tuple[float, float] | None = (6.5, 2.0),
    desk_size: tuple[float, float, float] = (1.2, 0.6, 0.75),
    stool_in_door: bool = False,
    length: float = ROOM_L,
) -> Scene:
    """A living room (x 0..4) with a coffee table and a can on it, and a study (x 4..8) with
    the desk the can goes to, joined by a 0.9 m door (or a closed wall)."""
    rooms = [
        _room("living", 0.0, 4.0, length, door, west=False),
        _room("study", 4.0, 4.0, length, door, west=True),
    ]
    table = (1.5, length / 2)
    objects = [
        _box("coffee_table", "living", table, (1.0, 0.6, 0.45)),
        SceneObject(
            id="can",
            room_id="living",
            category="can",
            position=Vec3(table[0], table[1] - 0.1, 0.45),
            dimensions=Size3(0.066, 0.066, 0.12),
            placement=Placement(kind="on_top", support_id="coffee_table"),
            physics=Physics(mass=0.3),
            task_role="pick",
        ),
    ]
    if desk is not None:
        room = "study" if desk[0] > 4.0 else "living"
        objects.append(_box("desk", room, desk, desk_size, role="place_support", mass=30.0))
    if stool_in_door:
        y = (DOOR_Y[0] + DOOR_Y[1]) / 2
        objects.append(_box("stool", "living", (3.7, y), (0.45, 0.45, 0.5), mass=4.0))
    return Scene(
        id="home",
        rooms=rooms,
        objects=objects,
        source="example",
        task=Task(kind="mobile_pick_place", instruction="move the can from the table to the desk"),
    )


def test_route_through_the_door_passes() -> None:
    verdict = check_route(home())
    assert verdict.ok, verdict
    assert verdict.separation is not None and verdict.separation >= 4.0
    assert verdict.pick_poses > 0 and verdict.place_poses > 0
    assert verdict.spawn_area is not None and verdict.spawn_area > 5.0
    assert verdict.as_dict()["passed"] is True


def test_the_route_keeps_the_poses_it_verified() -> None:
    """The verdict carries its poses: every verified pick pose shares an SE(2) region with a
    verified place pose; spawns are free poses from which the lattice reaches a pick pose; a
    closed route verifies none and has nowhere to spawn."""
    verdict = check_route(home())
    route = verdict.route
    assert route is not None and route.ok
    picks, places = route.route_picks(), route.route_places()
    assert (verdict.route_pick_poses, verdict.route_place_poses) == (len(picks), len(places))
    assert picks and places and len(picks) <= verdict.pick_poses
    for p in picks:
        assert route.pick_index(p) >= 0 and route.route_places(p)
        assert route.carry.free(route.grid, p.as_array())
    assert "route" not in verdict.as_dict()  # the report keeps counts, not poses
    rng = np.random.default_rng(0)
    for _ in range(10):
        spawn = route.random_spawn(rng)
        assert route.footprint.free(route.grid, spawn.as_array())
        assert route.picks_from(spawn)
    closed = check_route(home(door=False)).route
    assert closed is not None and closed.reason == NO_ROUTE and not closed.route_picks()
    with pytest.raises(NavError):
        closed.random_spawn(rng)


def test_closed_wall_fails_with_no_route() -> None:
    """The desk's study has no door: both supports are reachable, but not from each other."""
    verdict = check_route(home(door=False))
    assert verdict.reason == NO_ROUTE, verdict
    assert verdict.pick_poses > 0 and verdict.place_poses > 0
    assert "desk" in verdict.detail and "corridor" in verdict.detail


def test_blocked_door_names_what_to_take_out() -> None:
    verdict = check_route(home(stool_in_door=True), suggest_clear=True)
    assert verdict.reason == NO_ROUTE and verdict.clear == ("stool",), verdict


def test_missing_place_support() -> None:
    scene = home(desk=None)
    assert is_mobile_task(scene)  # the task says so, though nothing is the place support
    verdict = check_route(scene)
    assert verdict.reason == NO_PLACE_SUPPORT and "place support" in verdict.detail


def test_place_support_too_close() -> None:
    verdict = check_route(home(desk=(2.6, ROOM_L / 2)))
    assert verdict.reason == PLACE_SUPPORT_TOO_CLOSE, verdict
    assert verdict.separation is not None and verdict.separation < MIN_SUPPORT_SEPARATION
    assert "1.5 m" in verdict.detail


def test_place_support_too_small() -> None:
    """A pedestal 15 cm across cannot hold the can (6.6 cm across) with 4 cm to each edge."""
    verdict = check_route(home(desk_size=(0.15, 0.15, 0.75)))
    assert verdict.reason == PLACE_SUPPORT_TOO_SMALL, verdict
    assert "larger support" in verdict.detail


def test_no_spawn_area() -> None:
    """Rooms 0.7 m long: the base (0.58 m wide with its margin) fits nowhere."""
    verdict = check_route(home(length=0.7, desk=(6.5, 0.35)))
    assert verdict.reason == NO_SPAWN_AREA and verdict.spawn_area == 0.0, verdict


def test_scene_check_applies_to_mobile_tasks_only() -> None:
    scene = home()
    out = route_scene_check(scene, _compiled(scene))
    assert out is not None and out["reason"] == "" and out["passed"]
    plain = home()
    plain.task = Task(kind="pick_place", instruction="")
    for o in plain.objects:
        o.task_role = None
    assert not is_mobile_task(plain) and route_scene_check(plain, _compiled(plain)) is None
    assert len(set(ROUTE_REASONS)) == len(ROUTE_REASONS)


def _compiled(scene: Scene) -> mujoco.MjModel:
    from factory.sim.compile import compile_scene

    return compile_scene(scene, None).model


def test_robot_numbers_are_the_mobile_robots() -> None:
    """:mod:`factory.nav.task_poses` keeps the robot's footprint and arm position as numbers
    (nav does not import the robot): they stay equal to the robot's."""
    require_robot_models()
    from factory.nav.task_poses import ARM_X, CARRY_X, MOBILE_FOOTPRINT
    from factory.robots.mobile_panda import ARM_MOUNT, BASE_FOOTPRINT
    from factory.tasks.mobile_pick_place.scene import CARRY_TOOL

    assert MOBILE_FOOTPRINT == BASE_FOOTPRINT
    assert (ARM_MOUNT[0], CARRY_TOOL[0]) == (ARM_X, CARRY_X)


def _l_corridor(width: float) -> OccupancyGrid:
    """A 5 x 5 m grid, walls everywhere but two rooms joined by an L-shaped corridor
    ``width`` (m) wide: east from the first room, then north to the second."""
    res = 0.05
    occupied = np.ones((100, 100), bool)

    def clear(x0: float, y0: float, x1: float, y1: float) -> None:
        occupied[round(y0 / res) : round(y1 / res), round(x0 / res) : round(x1 / res)] = False

    clear(0.2, 0.2, 1.8, 1.8)
    clear(3.0, 3.0, 4.8, 4.8)
    clear(1.8, 0.6, 3.9 + width / 2, 0.6 + width)
    clear(3.9 - width / 2, 0.6, 3.9 + width / 2, 3.0)
    return OccupancyGrid(res, (0.0, 0.0), occupied)


@pytest.mark.parametrize(("width", "turns"), [(0.7, False), (0.8, True)])
def test_the_base_must_turn_the_corner(width: float, turns: bool) -> None:
    """In an L-shaped corridor 0.7 m wide the footprint's discs pass (the inscribed grid
    connects the rooms) but the 0.78 x 0.58 m base cannot turn the corner; at 0.8 m it can.
    OMPL's SE(2) planner agrees (no path in 2 x 5 s at 0.7 m, a path at 0.75 and 0.8 m)."""
    grid = _l_corridor(width)
    a, b = BasePose(1.0, 1.0, 0.0), BasePose(3.9, 3.9, 1.57)
    inscribed = MOBILE_FOOTPRINT.inscribed_grid(grid)
    assert inscribed.component(a.xy) == inscribed.component(b.xy) != 0
    labels = se2_labels(free_poses(grid, MOBILE_FOOTPRINT))
    assert bool(pose_labels(labels, grid, [a]) & pose_labels(labels, grid, [b])) == turns
