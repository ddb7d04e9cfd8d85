"""Compiler: model.xml that plain MuJoCo loads, bodies named by id, masses, statics, meshes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from factory.scenes.sage_assets import import_sage_mesh
from factory.schema import load_scene
from factory.schema.sage import read_package, sage_to_scene
from factory.sim.compile import CompileOptions, compile_scene, model_xml
from factory.store import RunStore

SIMULATE = """
import sys, mujoco, numpy as np
m = mujoco.MjModel.from_xml_path(sys.argv[1])
d = mujoco.MjData(m)
q0 = d.qpos.copy()
steps = int(round(2.0 / m.opt.timestep))
for _ in range(steps):
    mujoco.mj_step(m, d)
assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all(), "NaN"
names = [m.body(i).name for i in range(1, m.nbody)]
print(d.time, float(np.abs(d.qpos - q0).max()), ",".join(names))
"""


def _simulate_in_subprocess(xml: Path) -> tuple[float, float, list[str]]:
    out = subprocess.run(
        [sys.executable, "-c", SIMULATE, str(xml)], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    t, moved, names = out.stdout.split()
    return float(t), float(moved), names.split(",")


def test_example_compiles_loads_and_simulates(tmp_path: Path, example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    compiled = compile_scene(scene)
    assert sorted(compiled.boxed) == sorted(o.id for o in scene.objects)
    xml = tmp_path / "model.xml"
    xml.write_text(model_xml(compiled, tmp_path))
    t, moved, names = _simulate_in_subprocess(xml)
    assert t == pytest.approx(2.0, abs=1e-6)
    assert names == [o.id for o in scene.objects]
    assert moved < 0.05  # a resting scene stays at rest
    model = compiled.model
    for obj in scene.objects:
        body = model.body(obj.id)
        if obj.is_static:
            assert body.jntnum[0] == 0
        else:
            assert body.jntnum[0] == 1
            assert model.body_mass[body.id] == pytest.approx(obj.physics.mass, rel=1e-9)
            gid = model.body_geomadr[body.id]
            assert model.geom_friction[gid][0] == pytest.approx(obj.physics.friction)


def test_object_pose_is_bottom_centre(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    model = compile_scene(scene).model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    for obj in scene.objects:
        gid = model.body_geomadr[model.body(obj.id).id]
        bottom = data.geom_xpos[gid][2] - obj.dimensions.height / 2
        assert bottom == pytest.approx(obj.position.z, abs=1e-9)
        assert data.xpos[model.body(obj.id).id][:2] == pytest.approx(
            [obj.position.x, obj.position.y]
        )


def test_ceiling_option(example_scene_path: Path) -> None:
    scene = load_scene(example_scene_path)
    with_ceiling = compile_scene(scene, options=CompileOptions(ceiling=True)).model
    without = compile_scene(scene).model
    assert with_ceiling.ngeom == without.ngeom + len(scene.rooms)


def test_sage_package_with_meshes(tmp_path: Path, sage_package: Path) -> None:
    store = RunStore(tmp_path / "run")
    pkg = read_package(sage_package)
    scene = sage_to_scene(pkg.layout)
    for obj in scene.objects:
        if obj.asset and obj.asset.source_id in pkg.meshes:
            sid = obj.asset.source_id
            obj.asset.asset_id = import_sage_mesh(store, pkg.meshes[sid], pkg.textures[sid], "x")
    compiled = compile_scene(scene, store.assets_dir)
    assert sorted(set(o.id for o in scene.objects) - set(compiled.boxed)) == [
        "bed_0",
        "cup_0",
        "sofa_0",
    ]
    model = compiled.model
    gid = model.body_geomadr[model.body("bed_0").id]
    assert model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_MESH
    assert model.ntex >= 3
    assert model.body_mass[model.body("bed_0").id] == pytest.approx(60.0)
    scene_dir = store.scene_dir(scene.id)
    scene_dir.mkdir(parents=True)
    xml = scene_dir / "model.xml"
    xml.write_text(model_xml(compiled, scene_dir))
    assert "../../assets" in xml.read_text()
    _, _, names = _simulate_in_subprocess(xml)
    assert "bed_0" in names and "tv_0" in names
    # the mesh's texture coordinates survive
    mid = model.geom_dataid[gid]
    assert model.mesh_texcoordnum[mid] == 4


def test_same_mesh_imported_twice_is_one_asset(tmp_path: Path, sage_package: Path) -> None:
    store = RunStore(tmp_path)
    pkg = read_package(sage_package)
    a = import_sage_mesh(store, pkg.meshes["bed_0_mesh"], pkg.textures["bed_0_mesh"], "x")
    b = import_sage_mesh(store, pkg.meshes["bed_0_mesh"], pkg.textures["bed_0_mesh"], "x")
    assert a == b and a.startswith("sage-")
    assert [p.name for p in store.assets_dir.iterdir()] == [a]
    assert np.allclose(  # extents come from the mesh
        __import__("json").loads((store.asset_dir(a) / "meta.json").read_text())["extents"],
        [1.6, 2.0, 0.55],
        atol=1e-6,
    )
