"""Scene schema: exact round trips, conventions, and a clear error for each bad input."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from factory.schema import (
    SCHEMA_VERSION,
    Euler,
    SchemaError,
    SchemaVersionError,
    UnsafePathError,
    load_scene,
    scene_from_dict,
    scene_from_json,
    scene_to_json,
    to_dict,
)
from factory.schema.migrate import MIGRATIONS, upgrade


@pytest.fixture
def scene_dict(example_scene_path: Path) -> dict[str, Any]:
    return json.loads(example_scene_path.read_text())


def test_json_round_trip_is_exact(example_scene_path: Path) -> None:
    text = example_scene_path.read_text()
    scene = scene_from_json(text)
    assert scene_to_json(scene) == text
    again = scene_from_json(scene_to_json(scene))
    assert again == scene
    assert to_dict(again) == json.loads(text)


def test_round_trip_keeps_extras_and_odd_floats(scene_dict: dict[str, Any]) -> None:
    scene_dict["objects"][0]["position"]["x"] = 0.1 + 0.2
    scene_dict["objects"][0]["extras"] = {"note": [1, {"a": None}]}
    scene = scene_from_dict(scene_dict)
    assert json.loads(scene_to_json(scene)) == scene_dict
    assert scene.objects[0].position.x == 0.1 + 0.2


@pytest.mark.parametrize("angles", [(0, 0, 90), (30, -20, 145), (90, 45, -60), (-170, 10, 5)])
def test_euler_convention_is_rz_ry_rx(angles: tuple[float, float, float]) -> None:
    w, x, y, z = Euler(*angles).quat_wxyz()
    rx, ry, rz = (Rotation.from_euler(a, v, degrees=True) for a, v in zip("xyz", angles))
    expected = (rz * ry * rx).as_quat()  # x, y, z, w; Rz @ Ry @ Rx
    got = np.array([x, y, z, w])
    assert np.allclose(got, expected) or np.allclose(got, -expected)


def test_load_scene_names_the_file(tmp_path: Path) -> None:
    p = tmp_path / "scene.json"
    p.write_text('{"schema_version": 1, "id": "x", "rooms": [')
    with pytest.raises(SchemaError, match=r"scene\.json.*truncated or corrupt"):
        load_scene(p)
    with pytest.raises(SchemaError, match="does not exist"):
        load_scene(tmp_path / "missing.json")


def _set(d: dict[str, Any], path: str, value: Any) -> None:
    keys = path.split(".")
    for k in keys[:-1]:
        d = d[int(k)] if isinstance(d, list) else d[k]  # type: ignore[assignment]
    last = keys[-1]
    if isinstance(d, list):
        d[int(last)] = value
    else:
        d[last] = value


BAD = [
    ("schema_version", 3, SchemaVersionError, "schema_version is 3, this factory reads 2"),
    ("schema_version", 0, SchemaVersionError, "schema_version is 0"),
    ("objects.0.joint_states", {"a/b": 0.1}, UnsafePathError, "joint_states key 'a/b' contains"),
    ("objects.0.joint_states", {"free": 0.0}, SchemaError, r"key 'free' is reserved"),
    ("objects.0.joint_states", {"door_0": "ajar"}, SchemaError, r"\['door_0'\] must be a number"),
    ("objects.0.joint_states", {"door_0": True}, SchemaError, "must be a number"),
    ("objects.0.joint_states", {"door_0": float("inf")}, SchemaError, "must be finite"),
    ("objects.0.joint_states", [0.1], SchemaError, "expected an object"),
    ("objects.0.task_joint", "door_0", SchemaError, r"task_joint 'door_0' is not a key.*\[\]"),
    ("rooms.0.dimensions.width", 0.0, SchemaError, r"dimensions\.width must be > 0"),
    ("rooms.0.dimensions.length", -3.0, SchemaError, r"dimensions\.length must be > 0"),
    ("objects.0.dimensions.height", 0, SchemaError, r"dimensions\.height must be > 0"),
    ("objects.1.dimensions.width", -0.5, SchemaError, r"dimensions\.width must be > 0"),
    ("rooms.0.walls.0.thickness", 0.0, SchemaError, "thickness must be > 0"),
    ("rooms.0.doors.0.width", -1.0, SchemaError, "width must be > 0"),
    ("objects.0.physics.mass", 0.0, SchemaError, r"physics\.mass must be > 0"),
    ("objects.0.position.x", 40.0, SchemaError, "outside every room"),
    ("objects.8.placement.support_id", "no_such_table", SchemaError, "'no_such_table' does not"),
    ("objects.7.placement.support_id", "no_wall", SchemaError, "is not a wall id"),
    ("objects.0.room_id", "attic", SchemaError, "room_id 'attic' does not exist"),
    ("objects.0.id", "../x", UnsafePathError, "contains a path"),
    ("objects.0.id", "a/b", UnsafePathError, "contains a path"),
    ("id", "../../etc", UnsafePathError, "contains a path"),
    ("rooms.0.id", "", SchemaError, "non-empty"),
    ("objects.0.position.y", float("nan"), SchemaError, "must be finite"),
    ("objects.0.dimensions", {"width": 1, "length": 1}, SchemaError, "missing required key"),
    ("objects.0.colour", "red", SchemaError, r"unknown key\(s\) \['colour'\]"),
    ("rooms.0.doors.0.wall_id", "nowhere", SchemaError, "is not a wall of this room"),
    ("rooms.0.windows.0.position_on_wall", 1.5, SchemaError, r"must be in \[0, 1\]"),
    ("objects.0.placement.kind", "ceiling", SchemaError, "is not one of"),
    ("source", "dream", SchemaError, "source 'dream'"),
    ("rooms", [], SchemaError, "has no rooms"),
]


@pytest.mark.parametrize(("path", "value", "exc", "match"), BAD, ids=[b[0] for b in BAD])
def test_bad_scene_is_refused(
    scene_dict: dict[str, Any], path: str, value: Any, exc: type, match: str
) -> None:
    bad = copy.deepcopy(scene_dict)
    _set(bad, path, value)
    with pytest.raises(exc, match=match):
        scene_from_dict(bad)


def _as_version_1(scene_dict: dict[str, Any]) -> dict[str, Any]:
    old = copy.deepcopy(scene_dict)
    old["schema_version"] = 1
    for o in old["objects"]:
        del o["joint_states"], o["task_joint"]
    return old


def test_version_1_scene_reads_and_writes_current(
    scene_dict: dict[str, Any], example_scene_path: Path
) -> None:
    assert SCHEMA_VERSION == 2
    old = _as_version_1(scene_dict)
    before = copy.deepcopy(old)
    scene = scene_from_dict(old)
    assert old == before  # the upgrade copies
    assert scene.schema_version == 2 and all(o.joint_states == {} for o in scene.objects)
    assert scene_to_json(scene) == example_scene_path.read_text()


def test_every_migration_reaches_the_current_version() -> None:
    for version in MIGRATIONS:
        assert upgrade({"schema_version": version})["schema_version"] == SCHEMA_VERSION
    assert upgrade({"schema_version": 3}) == {"schema_version": 3}
    assert upgrade([1]) == [1]


def test_committed_scenes_load() -> None:
    """Every scene file under factory/data/ (the mobile task's example is still version 1)."""
    data = Path(__file__).resolve().parents[2] / "factory" / "data"
    paths = sorted(data.rglob("scene.json"))
    assert len(paths) >= 2
    for path in paths:
        assert load_scene(path).schema_version == SCHEMA_VERSION


def test_joint_states_round_trip(scene_dict: dict[str, Any]) -> None:
    obj = scene_dict["objects"][0]
    obj["joint_states"] = {"drawer_0": 0.25, "door_0": 1.2, "lid": 0}
    obj["task_joint"] = "drawer_0"
    scene = scene_from_dict(scene_dict)
    assert scene.objects[0].joint_states["door_0"] == 1.2
    assert scene.objects[0].task_joint == "drawer_0"
    assert json.loads(scene_to_json(scene)) == scene_dict


def test_missing_schema_version(scene_dict: dict[str, Any]) -> None:
    del scene_dict["schema_version"]
    with pytest.raises(SchemaVersionError, match=f"reads {SCHEMA_VERSION}"):
        scene_from_dict(scene_dict)


def test_duplicate_object_ids(scene_dict: dict[str, Any]) -> None:
    scene_dict["objects"][1]["id"] = scene_dict["objects"][0]["id"]
    with pytest.raises(SchemaError, match="duplicate object id"):
        scene_from_dict(scene_dict)


def test_support_cycle(scene_dict: dict[str, Any]) -> None:
    mug = next(o for o in scene_dict["objects"] if o["id"] == "mug")
    bowl = next(o for o in scene_dict["objects"] if o["id"] == "bowl")
    mug["placement"] = {**mug["placement"], "kind": "on_top", "support_id": "bowl"}
    bowl["placement"] = {**bowl["placement"], "kind": "on_top", "support_id": "mug"}
    with pytest.raises(SchemaError, match="cycle"):
        scene_from_dict(scene_dict)


def test_wall_length_is_geometry(scene_dict: dict[str, Any]) -> None:
    scene = scene_from_dict(scene_dict)
    wall = scene.rooms[0].walls[0]
    assert math.isclose(wall.length, 4.0)


def test_ingest_keeps_an_older_runs_scene(tmp_path: Path, scene_dict: dict[str, Any]) -> None:
    """A run's version-1 scene.json is the same scene: ingest skips it and leaves its bytes
    (the later stages' stamps hash them); a changed scene still needs force."""
    from factory.errors import StoreError
    from factory.scenes.ingest import SceneInput, ingest_one
    from factory.store import RunStore

    store = RunStore(tmp_path / "run")
    old_text = json.dumps(_as_version_1(scene_dict), indent=2) + "\n"
    stored = store.scene_json(scene_dict["id"])
    stored.parent.mkdir(parents=True)
    stored.write_text(old_text)
    source = tmp_path / "scene.json"
    source.write_text(json.dumps(scene_dict))
    assert ingest_one(store, SceneInput("scene", source)) == "skipped"
    assert stored.read_text() == old_text
    scene_dict["description"] = "changed"
    source.write_text(json.dumps(scene_dict))
    with pytest.raises(StoreError, match="force=true"):
        ingest_one(store, SceneInput("scene", source))
