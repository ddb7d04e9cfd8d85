"""Layout augmentation of a mobile-task scene keeps the route between the two supports, and
``stage=augment``'s route verdict rejects a variant whose route is blocked."""

from __future__ import annotations

import copy
import math
from pathlib import Path

from factory.assets import AssetLibrary
from factory.augment.levels import layout
from factory.augment.stage import check_route
from factory.nav.route import MIN_SUPPORT_SEPARATION, NO_ROUTE
from factory.scenes.brain import AgentConfig, generate_scene
from factory.schema import Physics, Scene, SceneObject, Size3, Vec3, validate

LIVING = "a living room where the robot moves the coke can from the coffee table to the desk"


def _partition(scene: Scene, a: SceneObject, b: SceneObject) -> SceneObject:
    """A static panel 1.2 m high across the whole room, halfway between ``a`` and ``b`` and
    square to the line between them: nothing passes from one side to the other."""
    ax, ay, bx, by = a.position.x, a.position.y, b.position.x, b.position.y
    room = scene.rooms[0]
    span = 2 * math.hypot(room.dimensions.width, room.dimensions.length)
    yaw = math.degrees(math.atan2(by - ay, bx - ax))  # the panel's x axis along a -> b
    wall = SceneObject(
        id="partition",
        room_id=room.id,
        category="partition",
        position=Vec3((ax + bx) / 2, (ay + by) / 2, 0.0),
        dimensions=Size3(0.06, span, 1.2),
        physics=Physics(mass=50.0, static=True),
    )
    wall.rotation.z = yaw
    return wall


def test_layout_variant_keeps_the_route_and_a_blocked_one_is_rejected(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path / "assets")
    parent, _ = generate_scene(LIVING, lib, seed=0, config=AgentConfig(physics_critic=False))
    assert check_route(parent, lib.assets_dir) is None
    v = layout(parent, lib, 5, None, physics=False).scene
    v.id = f"{parent.id}__L0"
    validate(v)
    roles = {o.task_role: o for o in v.objects if o.task_role}
    assert set(roles) == {"pick", "place_support"}  # the place support keeps its role
    source = v.object(str(roles["pick"].placement.support_id))
    place = roles["place_support"]
    assert place.asset == parent.object(place.id).asset  # the same desk, moved
    assert v.rooms[0].dimensions != parent.rooms[0].dimensions  # in a new room
    far = math.hypot(place.position.x - source.position.x, place.position.y - source.position.y)
    assert far >= MIN_SUPPORT_SEPARATION
    assert check_route(v, lib.assets_dir) is None  # kept: its route check passes
    blocked = copy.deepcopy(v)
    blocked.objects.append(_partition(blocked, source, place))
    assert check_route(blocked, lib.assets_dir) == NO_ROUTE  # dropped, counted as no_route
