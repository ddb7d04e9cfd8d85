"""Textured real meshes from an installed package (robosuite): imported with licence and
provenance, compiled and rendered textured on the CPU renderer, chosen for "a coke can"
deterministically per seed, procedural when the package or the flag is off, and grasped by
the demos' planner."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from factory.assets import CATEGORIES, AssetLibrary
from factory.assets import packaged as packaged_mod
from factory.assets.geometry import MAX_HULL_VERTICES
from factory.assets.packaged import ROBOSUITE, choose, import_robosuite, robosuite_source
from factory.assets.realmesh import read_obj_uv
from factory.schema import (
    ASSET_SCHEMA_VERSION,
    AssetRef,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
    load_asset_meta,
)
from factory.sim.compile import CompileOptions, compile_scene

if robosuite_source() is None:
    pytest.skip("robosuite is not installed", allow_module_level=True)

TEXTS = {
    "coke_can": "a coke can",
    "soda_can": "a diet soda",
    "bottle": "a water bottle",
    "milk": "milk",
    "cereal": "a box of cereal",
    "bread": "a slice of bread",
    "lemon": "a lemon",
}


@pytest.fixture(scope="module")
def assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run's assets folder holding the six objects (and both cans) as assets."""
    return tmp_path_factory.mktemp("real") / "assets"


@pytest.fixture(scope="module")
def metas(assets: Path) -> dict[str, object]:
    lib = AssetLibrary(assets)
    return {name: lib.from_text(text, seed=0)[0] for name, text in TEXTS.items()}


def _scene(metas: dict[str, object]) -> Scene:
    room = Room(
        id="room",
        room_type="test",
        position=Vec3(0, 0, 0),
        dimensions=Size3(0.4 * len(metas) + 0.4, 1.0, 1.5),
        floor_material="concrete",
    )
    objs = []
    for i, (name, meta) in enumerate(metas.items()):
        objs.append(
            SceneObject(
                id=name,
                room_id="room",
                category=meta.category,  # type: ignore[attr-defined]
                position=Vec3(0.4 + 0.4 * i, 0.5, 0.0),
                dimensions=Size3(*meta.extents),  # type: ignore[attr-defined]
                placement=Placement(kind="floor", support_id="room"),
                asset=AssetRef(backend="mesh_library", asset_id=meta.asset_id),  # type: ignore[attr-defined]
                physics=Physics(mass=meta.mass, static=False),  # type: ignore[attr-defined]
            )
        )
    return Scene(id="real", rooms=[room], objects=objs, seed=0)


def _side_views(model: mujoco.MjModel, scene: Scene) -> list[np.ndarray]:
    """A 64 px side view of each object filling the middle of the image, in uniform light."""
    model.light_diffuse[:] = 0.0
    model.light_specular[:] = 0.0
    model.vis.headlight.ambient[:] = 1.0
    model.vis.headlight.diffuse[:] = 0.0
    model.vis.headlight.specular[:] = 0.0
    model.vis.map.znear = 0.001  # of the model's extent: the camera is a few cm away
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.elevation, cam.azimuth = -5.0, 90.0
    out = []
    with mujoco.Renderer(model, 64, 64) as r:
        for o in scene.objects:
            h = o.dimensions.height
            cam.lookat[:] = [o.position.x, o.position.y, h / 2]
            cam.distance = 1.2 * h  # the object's middle fills the centre crop
            r.update_scene(data, camera=cam)
            out.append(r.render()[24:40, 28:36].astype(np.float32))
    return out


def test_every_object_has_licence_provenance_and_hulls(assets: Path, metas: dict) -> None:
    assert {o.name for o in ROBOSUITE} == set(TEXTS)
    for name, meta in metas.items():
        folder = assets / meta.asset_id
        assert meta.backend == "mesh_library" and meta.license == "MIT", name
        saved = json.loads((folder / "meta.json").read_text())
        assert saved["schema_version"] == ASSET_SCHEMA_VERSION
        prov = meta.provenance
        assert prov["package"] == "robosuite" and prov["version"] and prov["library_entry"] == name
        assert prov["copyright"].startswith("Copyright (c)")
        assert len(prov["sources"]) == 3
        for src in prov["sources"].values():
            assert len(src["sha256"]) == 64 and Path(src["path"]).is_file()
        assert "MIT License" in (folder / "LICENSE.txt").read_text()
        # collision: convex hulls of <= 64 vertices, inside the category's mass range
        assert meta.collision
        for c in meta.collision:
            hull = trimesh.load(folder / c, force="mesh")
            assert hull.is_convex and len(hull.vertices) <= MAX_HULL_VERTICES, (name, c)
            # inside the object's box: nothing below its bottom presses into its support
            vis = trimesh.load(folder / "visual.obj", force="mesh")
            assert (hull.vertices >= vis.bounds[0] - 1e-6).all(), (name, c)
            assert (hull.vertices <= vis.bounds[1] + 1e-6).all(), (name, c)
        lo, hi = CATEGORIES[meta.category].mass
        assert lo <= meta.mass <= hi, (name, meta.mass)
        # the visual part carries its texture and UVs (as shipped; they span the image)
        (part,) = meta.visual_parts
        assert (folder / part["texture"]).is_file() and part["tinted"] is False
        uv = read_obj_uv(folder / part["file"]).uv
        assert np.isfinite(uv).all() and np.ptp(uv, axis=(0, 1)).min() > 0.3, name
    assert np.allclose(metas["coke_can"].extents, (0.05, 0.05, 0.08), atol=1e-4)
    meta = json.loads(next((assets / "packaged").glob("robosuite-*/metadata.json")).read_text())
    assert meta["schema_version"] == 1 and meta["license"] == "MIT"


def test_every_object_compiles_and_renders_textured(assets: Path, metas: dict) -> None:
    """Through the real path (import, asset, compile, CPU renderer): each object's visual mesh
    has texture coordinates and a textured material, and its side view varies far more than
    with textures off."""
    scene = _scene(metas)
    textured = compile_scene(scene, assets).model
    flat = compile_scene(scene, assets, CompileOptions(textures=False)).model
    for name in metas:
        geom = textured.geom(f"{name}/visual_0")
        assert textured.mesh_texcoordnum[geom.dataid[0]] > 0
        assert textured.mat_texid[geom.matid[0], mujoco.mjtTextureRole.mjTEXROLE_RGB] >= 0
    for name, im_t, im_f in zip(
        metas, _side_views(textured, scene), _side_views(flat, scene), strict=True
    ):
        s_t = float(im_t.reshape(-1, 3).std(axis=0).max())
        s_f = float(im_f.reshape(-1, 3).std(axis=0).max())
        mean = float(im_t.mean())
        msg = f"{name}: textured std {s_t:.2f}, flat {s_f:.2f} (mean {mean:.0f})"
        assert s_t > 0.01 * mean and s_t > 2.0 * s_f + 0.3, msg
    # the coke can is red (its label), the milk carton white, the lemon yellow
    views = dict(zip(metas, _side_views(textured, scene), strict=True))
    r, g, b = views["coke_can"].reshape(-1, 3).mean(0)
    assert r > 1.5 * g and r > 1.5 * b
    r, g, b = views["lemon"].reshape(-1, 3).mean(0)
    assert r > 1.5 * b and g > 1.5 * b


def test_coke_can_resolves_to_the_textured_can(tmp_path: Path, assets: Path) -> None:
    lib = AssetLibrary(assets)
    for seed in range(4):
        meta, res = lib.from_text("a coke can", seed=seed)
        assert res.spec.category == "can" and meta.provenance["library_entry"] == "coke_can"
    picks = {lib.from_text("a soda can", seed=s)[0].provenance["library_entry"] for s in range(4)}
    assert picks == {"coke_can", "soda_can"}  # the seed picks among equally good entries
    for text in ("milk", "cereal", "bread", "a lemon", "a bottle"):
        assert lib.from_text(text, seed=3)[0].backend == "mesh_library", text
    # deterministic per seed: same request and seed, same asset
    assert lib.from_text("a can", seed=5)[0].asset_id == lib.from_text("a can", seed=5)[0].asset_id
    # what the real mesh cannot show stays procedural
    for text in ("a red can", "a rusty can", "a tin can", "a wine bottle", "a loaf of bread"):
        assert lib.from_text(text, seed=0)[0].backend == "procedural", text
    # size words scale the real mesh
    small, _ = lib.from_text("a small coke can", seed=0)
    assert small.backend == "mesh_library"
    assert np.allclose(small.extents, np.array([0.05, 0.05, 0.08]) * 0.78, atol=1e-4)
    # the flag turns them off; without the package the procedural asset stands in
    off = AssetLibrary(tmp_path / "off", real_meshes=False)
    assert off.from_text("a coke can")[0].backend == "procedural"


def test_without_the_package_procedural_stands_in(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(packaged_mod, "robosuite_source", lambda: None)
    lib = AssetLibrary(tmp_path / "assets")
    meta, _ = lib.from_text("a coke can")
    assert meta.backend == "procedural" and not (tmp_path / "assets" / "packaged").exists()


def test_import_is_deterministic_and_read_by_the_mesh_library_backend(
    tmp_path: Path, assets: Path
) -> None:
    first = next((assets / "packaged").glob("robosuite-*"))
    again = import_robosuite(tmp_path / "again")
    assert again.folder.name == first.name
    for f in sorted(p.relative_to(first) for p in first.rglob("*") if p.is_file()):
        assert (first / f).read_bytes() == (again.folder / f).read_bytes(), f
    lib = AssetLibrary(tmp_path / "a", "mesh_library", again.folder, fallback=False)
    can, _ = lib.from_text("a coke can")
    assert can.backend == "mesh_library" and can.visual_parts[0]["tinted"] is False
    assert load_asset_meta(tmp_path / "a" / can.asset_id).license == "MIT"
    shutil.rmtree(tmp_path / "again")


def test_choose_is_pure_and_seeded(assets: Path) -> None:
    from factory.assets import resolve

    lib = packaged_mod.packaged_library(assets)
    assert lib is not None
    names = [choose(lib.entries, resolve("a can", seed=s).spec)["name"] for s in range(6)]  # type: ignore[index]
    assert names == [choose(lib.entries, resolve("a can", seed=s).spec)["name"] for s in range(6)]  # type: ignore[index]
    assert choose(lib.entries, resolve("a blue cereal box").spec) is None


def test_demo_picks_up_the_coke_can(tmp_path: Path) -> None:
    """The demos' planner grasps the real can (its collision hull) and the executor lifts it
    into the bowl: a successful episode."""
    pytest.importorskip("ompl")
    from factory.demos.execute.cpu import RecordConfig, execute
    from factory.scenes.tools import ToolSession
    from factory.tasks.pick_place.plan import EpisodePlan, EpisodePlanner, setup_scene

    assets = tmp_path / "assets"
    session = ToolSession(AssetLibrary(assets), physics=False)
    assert session.init_scene("a kitchen", seed=3)["ok"]
    table = session.place_objects("dining table", placement="floor", rule="center")
    tid = table["placed"][0]
    for text, role in (("bowl", "place_target"), ("coke can", "pick")):
        res = session.place_objects(text, placement="on_top", target=tid, task_role=role)
        assert res["ok"], res
    scene = session.scene
    scene.task = None
    can = next(o for o in scene.objects if o.task_role == "pick")
    assert can.asset is not None and can.asset.backend == "mesh_library"
    setup = setup_scene(scene, assets)
    planner = EpisodePlanner(setup)
    plan = next(
        (p for s in range(6) if isinstance(p := planner.plan_episode(s), EpisodePlan)), None
    )
    assert plan is not None, "one of six seeds must plan a grasp of the can"
    (rec,) = execute(setup, [plan], RecordConfig(render=False))
    assert rec.outcome is not None and rec.outcome.success, rec.outcome
