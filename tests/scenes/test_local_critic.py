"""The local physics critic judges placements exactly as the whole-scene check does.

A generated living room (the physics critic on, so that the scene is at rest) and a fixed set
of candidate poses for the tallest objects on three different supports: resting, dropped,
dropped from high, sunk into the support, inside a neighbour, over the support's front edge,
tilted, and on the floor in front. Every candidate is judged by the whole-scene check and by
the local one, with the strict protocol and with resettling (the generation's), and the
verdicts must be equal.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from factory.assets import AssetLibrary
from factory.scenes.brain import AgentConfig, generate_scene
from factory.schema import Scene, SceneObject
from factory.sim.critic import candidate_verdicts, physics_critic
from factory.sim.local_critic import local_scene, neighbourhood
from factory.sim.stability import StabilityProtocol

KINDS = ("rest", "drop", "high", "sunk", "neighbour", "overhang", "tilted", "floor")


def _pose(obj: SceneObject, x: float, y: float, z: float, quat: np.ndarray | None = None):
    q = np.asarray(obj.rotation.quat_wxyz() if quat is None else quat, float)
    return [x, y, z, *q]


def _tilt(obj: SceneObject, yaw: float, deg: float) -> np.ndarray:
    """The object's orientation turned ``deg`` about the support's local x axis."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = obj.rotation.quat_wxyz()
    axis = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    r = Rotation.from_rotvec(math.radians(deg) * axis) * Rotation.from_quat([x, y, z, w])
    qx, qy, qz, qw = r.as_quat()
    return np.array([qw, qx, qy, qz])


def candidate_set(scene: Scene, n_objects: int = 3) -> list[tuple[str, list[str], np.ndarray]]:
    """``(object id, kinds, (8, 7) poses)`` for the tallest object on each of ``n_objects``
    supports of different categories (those with the most objects on them first)."""
    by_id = {o.id: o for o in scene.objects}
    on: dict[str, list[SceneObject]] = {}
    for o in scene.objects:
        sup = by_id.get(o.placement.support_id or "")
        if o.placement.kind == "on_top" and sup is not None and not sup.is_static:
            on.setdefault(sup.id, []).append(o)
    supports: list[str] = []
    ranked = sorted(on, key=lambda s: (-len(on[s]), s))
    for sid in ranked:
        if by_id[sid].category not in {by_id[x].category for x in supports}:
            supports.append(sid)
    supports += [sid for sid in ranked if sid not in supports]
    out = []
    for sid in supports[:n_objects]:
        s = by_id[sid]
        o = max(on[sid], key=lambda x: (x.dimensions.height, x.id))
        yaw = math.radians(s.rotation.z)
        c, sn = math.cos(yaw), math.sin(yaw)

        def world(lx: float, ly: float, s: SceneObject = s, c: float = c, sn: float = sn):
            return s.position.x + c * lx - sn * ly, s.position.y + sn * lx + c * ly

        dx, dy = o.position.x - s.position.x, o.position.y - s.position.y
        lx = c * dx + sn * dy  # the object's offset along the support's x
        p = o.position
        other = next((x for x in sorted(on[sid], key=lambda x: x.id) if x.id != o.id), None)
        neighbour = other if other is not None else s
        edge = world(lx, -(s.dimensions.length / 2 + 0.02))
        front = world(0.0, -(s.dimensions.length / 2 + max(o.dimensions.as_tuple()[:2]) + 0.15))
        poses = [
            _pose(o, p.x, p.y, p.z),
            _pose(o, p.x, p.y, p.z + 0.03),
            _pose(o, p.x, p.y, p.z + 0.4),
            _pose(o, p.x, p.y, p.z - 0.03),
            _pose(o, neighbour.position.x, neighbour.position.y, neighbour.position.z + 0.005),
            _pose(o, edge[0], edge[1], p.z + 0.002),
            _pose(o, p.x, p.y, p.z + 0.05, _tilt(o, yaw, 35.0)),
            _pose(o, front[0], front[1], 0.001),
        ]
        out.append((o.id, list(KINDS), np.array(poses)))
    return out


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scene, Path]:
    assets = tmp_path_factory.mktemp("local_critic") / "assets"
    scene, _ = generate_scene(
        "a living room", AssetLibrary(assets), seed=3, config=AgentConfig(max_objects=30)
    )
    return scene, assets


def _key(v: dict) -> tuple:
    return (v["ok"], v.get("kind"), v.get("object"), v.get("resettled"))


@pytest.mark.parametrize("resettle", [False, True], ids=["strict", "resettle"])
def test_local_verdicts_equal_whole_scene(room: tuple[Scene, Path], resettle: bool) -> None:
    scene, assets = room
    protocol = StabilityProtocol(resettle=resettle)
    cases = candidate_set(scene)
    assert len(cases) == 3
    seen: set[str] = set()
    for oid, kinds, poses in cases:
        whole = candidate_verdicts(scene, oid, poses, assets_root=assets, protocol=protocol)
        local = candidate_verdicts(
            scene, oid, poses, assets_root=assets, protocol=protocol, scope="local"
        )
        for kind, w, lo in zip(kinds, whole, local, strict=True):
            assert _key(w) == _key(lo), (oid, kind, w, lo)
            if w["ok"]:  # the same settled pose (islands are solved apart: mostly bit for bit;
                # a vase rolling after a tilted drop differs by 5e-5 m and 0.03 deg)
                assert np.allclose(w["settled_pose"], lo["settled_pose"], atol=1e-3), (oid, kind)
                seen.add("resettled" if w["resettled"] else "stable")
            else:
                seen.add(w["kind"])
    # the set covers every kind of verdict the generation meets
    expected = {"stable", "interpenetrating"} | ({"resettled"} if resettle else {"fell", "tipped"})
    assert expected <= seen, seen


def test_local_critic_simulates_less_and_agrees(room: tuple[Scene, Path]) -> None:
    scene, assets = room
    oid, _, poses = candidate_set(scene, 1)[0]
    hood = neighbourhood(scene, oid, poses)
    assert hood.dynamic[0] == oid and len(hood.dynamic) + len(hood.static) < len(scene.objects)
    flags = {o.id: o.physics.static for o in scene.objects}
    sub = local_scene(scene, hood)
    assert {o.id for o in sub.objects} == set(hood.dynamic) | set(hood.static)
    assert all(o.is_static for o in sub.objects if o.id in hood.static)
    assert flags == {o.id: o.physics.static for o in scene.objects}  # the scene is untouched
    args = {"assets_root": assets, "protocol": StabilityProtocol()}
    whole = physics_critic(scene, oid, poses[[3, 0, 1]], **args)
    local = physics_critic(scene, oid, poses[[3, 0, 1]], scope="local", chunk=1, **args)
    assert whole["ok"] and local["ok"] and whole["candidate"] == local["candidate"] == 1
    assert local["simulated"]["of"] == len(scene.objects)


@pytest.mark.slow
def test_generation_with_either_critic_builds_the_same_room(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path / "assets")
    scenes = {
        scope: generate_scene(
            "a living room", lib, seed=3, config=AgentConfig(max_objects=30, critic_scope=scope)
        )[0]
        for scope in ("scene", "local")
    }
    whole, local = scenes["scene"], scenes["local"]
    assert [(o.id, o.placement.support_id) for o in whole.objects] == [
        (o.id, o.placement.support_id) for o in local.objects
    ]
    for a, b in zip(whole.objects, local.objects, strict=True):
        assert np.allclose(a.position.as_tuple(), b.position.as_tuple(), atol=1e-3), a.id
