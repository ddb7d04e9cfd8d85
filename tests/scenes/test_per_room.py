"""Per-room generation of a home: the same scene whether the rooms run here or in workers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from factory.assets import AssetLibrary
from factory.scenes.brain import AgentConfig, generate_scene
from factory.scenes.brain_steps import BrainState
from factory.scenes.per_room import RoomWork, merge_rooms
from factory.schema import Placement, Room, Scene, SceneObject, Size3, Vec3, scene_to_json, validate


def test_rooms_in_workers_give_the_same_home(tmp_path: Path) -> None:
    request = "a student apartment with one bedroom"
    cfg = {"max_objects": 14, "extra_fill": 1}
    here, report = generate_scene(
        request, AssetLibrary(tmp_path / "a"), seed=4, config=AgentConfig(workers=1, **cfg)
    )
    there, report2 = generate_scene(
        request, AssetLibrary(tmp_path / "b"), seed=4, config=AgentConfig(workers=2, **cfg)
    )
    validate(here)
    assert report["workers"] == 1 and report2["workers"] == 2
    assert scene_to_json(here) == scene_to_json(there)
    per_room = {r.id: sum(o.room_id == r.id for o in here.objects) for r in here.rooms}
    assert len(per_room) >= 3 and all(n >= 5 for n in per_room.values()), per_room
    assert any(o.placement.kind == "on_top" for o in here.objects)  # the critic judged some
    rooms = {c.get("room") for c in report["trace"]}
    assert set(range(len(here.rooms))) <= rooms


def _obj(oid: str, room: str, support: str | None = None) -> SceneObject:
    kind = "on_top" if support else "floor"
    return SceneObject(
        id=oid,
        room_id=room,
        category=oid.rsplit("_", 1)[0],
        position=Vec3(0.0, 0.0, 0.0),
        dimensions=Size3(0.1, 0.1, 0.1),
        placement=Placement(kind, support_id=support),
    )


def _work(k: int, objects: list[SceneObject], keyed: dict[str, list[str]]) -> RoomWork:
    room = Room(id=f"r{k}", room_type="bedroom", position=Vec3(0, 0, 0), dimensions=Size3(3, 3, 3))
    state = BrainState(np.random.default_rng(k), "", 10, keyed=keyed)
    return RoomWork(k, Scene(id="s", rooms=[room], objects=objects), {}, state, state.rng)


def test_merge_renames_new_ids_taken_elsewhere() -> None:
    # before the phase: r0 holds table_0, r1 holds table_1; each room then added its own
    # table_1 / table_0 and a mug on it
    w0 = _work(
        0, [_obj("table_0", "r0"), _obj("table_1", "r0"), _obj("mug_0", "r0", "table_1")], {}
    )
    w1 = _work(
        1,
        [_obj("table_1", "r1"), _obj("table_0", "r1"), _obj("mug_0", "r1", "table_0")],
        {"r1:table": ["table_1", "table_0"]},
    )
    objs = merge_rooms([w0, w1], [{"table_0"}, {"table_1"}])
    ids = [o.id for o in objs]
    assert len(set(ids)) == len(ids)
    assert ids[:3] == ["table_0", "table_2", "mug_0"]  # r0's new table_1 was r1's already
    assert objs[2].placement.support_id == "table_2"
    r1 = {o.id: o for o in objs[3:]}
    assert set(r1) == {"table_1", "table_3", "mug_1"}
    assert r1["mug_1"].placement.support_id == "table_3"
    assert w1.brain.keyed == {"r1:table": ["table_1", "table_3"]}
