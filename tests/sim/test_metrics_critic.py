"""Scene metrics (both collision tests) and the physics critic."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from factory.errors import ConfigError
from factory.schema import Scene, load_scene, scene_from_dict
from factory.sim.compile import compile_scene
from factory.sim.critic import physics_critic
from factory.sim.metrics import scene_metrics
from factory.sim.stability import StabilityProtocol, check_stability


def _broken(example_scene_path: Path) -> Scene:
    d = json.loads(example_scene_path.read_text())
    objs = {o["id"]: o for o in d["objects"]}
    objs["mug"]["position"]["z"] = 0.95  # hovering 20 cm above the table
    objs["plate"]["position"]["z"] = 0.87  # 3 cm inside the counter top
    objs["bottle"]["position"]["x"] = 3.22  # pushed into the fridge
    return scene_from_dict(d)


def test_clean_scene_metrics(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    model = compile_scene(scene).model
    m = scene_metrics(scene, model, check_stability(model))
    assert m["objects"] == len(scene.objects)
    assert m["collision"]["ratio"] == 0.0 and m["collision_trimesh"]["ratio"] == 0.0
    assert m["stability"]["ratio"] == 1.0
    assert m["per_room_type"] == {"kitchen": {"objects": 14, "colliding": 0, "stable": 14}}


def test_broken_scene_metrics_agree(example_scene_path: Path) -> None:
    scene = _broken(example_scene_path)
    model = compile_scene(scene).model
    result = check_stability(model, protocol=StabilityProtocol(penetration_tol=float("inf")))
    m = scene_metrics(scene, model, result)
    expected = ["bottle", "counter", "fridge", "plate"]
    assert m["collision"]["colliding"] == expected
    assert m["collision_trimesh"]["colliding"] == expected  # the paper's test agrees
    assert "mug" in m["stability"]["unstable"]


def test_critic_picks_first_good_candidate(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    out = physics_critic(
        scene,
        "mug",
        [[2.76, 2.5, 0.75, 0.0], [1.75, 2.75, 0.70, 0.0], [2.0, 2.6, 0.75, 45.0]],
        protocol=StabilityProtocol(resettle=False),
    )
    assert out["ok"] and out["candidate"] == 2
    assert out["settled_pose"][2] == pytest.approx(0.75, abs=2e-3)


def test_critic_explains_failure(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    out = physics_critic(
        scene,
        "mug",
        [[2.76, 2.5, 0.75, 0.0], [2.78, 2.9, 0.75, 10.0]],  # centre of mass past the edge
        protocol=StabilityProtocol(resettle=False),
    )
    assert not out["ok"]
    assert [f["object"] for f in out["failures"]] == ["mug", "mug"]
    assert all(f["kind"] in ("fell", "tipped") for f in out["failures"])
    assert "mug" in out["suggestion"]
    json.dumps(out)  # JSON-ready
    overlap = physics_critic(scene, "mug", [[1.75, 2.75, 0.70, 0.0]])
    assert overlap["failures"][0]["kind"] == "interpenetrating"
    assert overlap["failures"][0]["object"] == "table"
    with pytest.raises(ConfigError):
        physics_critic(scene, "mug", [[1, 2, 3]])


def test_critic_scope_and_chunks_keep_the_verdict(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    poses = [[2.76, 2.5, 0.75, 0.0], [1.75, 2.75, 0.70, 0.0], [2.0, 2.6, 0.75, 45.0]]
    protocol = StabilityProtocol(resettle=False)
    whole = physics_critic(scene, "mug", poses, protocol=protocol)
    for scope, chunk in (("scene", 1), ("local", None), ("local", 2)):
        out = physics_critic(scene, "mug", poses, protocol=protocol, scope=scope, chunk=chunk)
        assert out["ok"] and out["candidate"] == whole["candidate"] == 2
        assert out["settled_pose"] == pytest.approx(whole["settled_pose"], abs=1e-6)
    local = physics_critic(scene, "mug", poses, protocol=protocol, scope="local")
    assert local["simulated"]["dynamic"] < len(scene.objects)
    failed = physics_critic(scene, "mug", poses[:2], protocol=protocol, scope="local", chunk=1)
    assert [f["candidate"] for f in failed["failures"]] == [0, 1]
    with pytest.raises(ConfigError, match="scope"):
        physics_critic(scene, "mug", poses, scope="room")
