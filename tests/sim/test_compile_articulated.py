"""The MJCF compiler's articulated objects: link bodies with hinge and slide joints at the
scene's joint states (``factory.sim.compile``)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from factory.errors import CompileError
from factory.sim.compile import compile_scene


@pytest.fixture(scope="module")
def cabinet_scene(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path, str]:
    """A kitchen with one articulated base cabinet (a drawer over a hinged door)."""
    from factory.assets import AssetLibrary
    from factory.scenes.tools import ToolSession

    assets = tmp_path_factory.mktemp("art") / "assets"
    session = ToolSession(AssetLibrary(assets, texture_size=64, articulated=True), physics=False)
    assert session.init_scene("a kitchen", seed=3)["ok"]
    res = session.place_objects("base cabinet", placement="floor", rule="against_wall")
    assert res["ok"], res
    return session.scene, assets, res["placed"][0]


def _with(scene: Any, oid: str, **changes: Any) -> Any:
    scene = copy.deepcopy(scene)
    obj = next(o for o in scene.objects if o.id == oid)
    for k, v in changes.items():
        if k == "static":
            obj.physics.static = v
        else:
            setattr(obj, k, v)
    return scene


def test_links_get_joints_at_the_scene_state_and_the_objects_mass(cabinet_scene) -> None:
    scene, assets, oid = cabinet_scene
    opened = _with(scene, oid, joint_states={"door": 1.2, "drawer": 0.2})
    model = compile_scene(opened, assets).model
    door, drawer = model.joint(f"{oid}/door"), model.joint(f"{oid}/drawer")
    assert door.type[0] == mujoco.mjtJoint.mjJNT_HINGE
    assert drawer.type[0] == mujoco.mjtJoint.mjJNT_SLIDE
    assert model.qpos0[door.qposadr[0]] == pytest.approx(1.2)
    assert model.qpos0[drawer.qposadr[0]] == pytest.approx(0.2)
    assert door.range[0] == 0 and door.range[1] == pytest.approx(np.deg2rad(110))
    assert door.damping[0] > 0 and drawer.frictionloss[0] > 0
    obj = next(o for o in opened.objects if o.id == oid)
    root = model.body(oid).id
    assert model.body_subtreemass[root] == pytest.approx(obj.physics.mass, rel=1e-6)
    for link in ("door", "drawer"):
        assert model.body(f"{oid}/{link}").mass[0] > 0.5
        assert model.body(f"{oid}/{link}").parentid[0] == root


def test_closed_links_sit_where_the_rigid_pieces_sit(cabinet_scene) -> None:
    """Joint position 0 is closed whatever the scene's state: an opened cabinet's model moved
    to 0 puts every piece where the closed model has it."""
    scene, assets, oid = cabinet_scene
    closed = compile_scene(scene, assets).model
    opened = compile_scene(_with(scene, oid, joint_states={"door": 0.9}), assets).model
    dc, do = mujoco.MjData(closed), mujoco.MjData(opened)
    mujoco.mj_forward(closed, dc)
    mujoco.mj_forward(opened, do)
    geoms = [closed.geom(i).name for i in range(closed.ngeom)]
    door_geoms = [
        g
        for g in geoms
        if g.startswith(oid) and opened.geom(g).bodyid[0] == opened.body(f"{oid}/door").id
    ]
    assert door_geoms
    moved = max(np.abs(do.geom(g).xpos - dc.geom(g).xpos).max() for g in door_geoms)
    assert moved > 0.05  # opened
    do.qpos[opened.joint(f"{oid}/door").qposadr[0]] = 0.0
    mujoco.mj_forward(opened, do)
    for g in (g for g in geoms if g.startswith(oid)):
        np.testing.assert_allclose(do.geom(g).xpos, dc.geom(g).xpos, atol=1e-9)


def test_a_fixed_cabinet_stays_closed_and_stays_open(cabinet_scene) -> None:
    """Fixed to the floor, 2 s of simulation: closed parts stay closed, a door left ajar and a
    drawer left out stay where they are (joint friction)."""
    scene, assets, oid = cabinet_scene
    for states in ({}, {"door": 0.6, "drawer": 0.15}):
        model = compile_scene(_with(scene, oid, static=True, joint_states=states), assets).model
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        for _ in range(int(2.0 / model.opt.timestep)):
            mujoco.mj_step(model, data)
        for name in ("door", "drawer"):
            q = float(data.joint(f"{oid}/{name}").qpos[0])
            assert q == pytest.approx(states.get(name, 0.0), abs=2e-3), (states, name, q)


def test_a_state_outside_the_range_is_refused(cabinet_scene) -> None:
    scene, assets, oid = cabinet_scene
    with pytest.raises(CompileError, match=r"joint_states\['drawer'\] = 2 is outside"):
        compile_scene(_with(scene, oid, joint_states={"drawer": 2.0}), assets)


def test_built_in_furniture_is_placed_fixed(cabinet_scene) -> None:
    """``fixed: true`` in the catalogue (base_cabinet): the placed object is static, so the
    compiled cabinet has no free joint; a rigid floor category stays free."""
    from factory.assets import CATEGORIES

    scene, assets, oid = cabinet_scene
    obj = next(o for o in scene.objects if o.id == oid)
    assert CATEGORIES["base_cabinet"].fixed and obj.is_static
    model = compile_scene(scene, assets).model
    names = [model.joint(j).name for j in range(model.njnt)]
    assert f"{oid}/free" not in names and f"{oid}/door" in names
    assert not CATEGORIES["chair"].fixed


def test_the_stability_check_judges_links(cabinet_scene) -> None:
    """The strict protocol judges each link as an object named by its body: a closed cabinet
    and an ajar one hold (the metrics list its links); a door that a spring swings shut turns
    more than 5° and is unstable."""
    from factory.sim.metrics import measure_scene
    from factory.sim.stability import StabilityProtocol, check_stability

    scene, assets, oid = cabinet_scene
    strict = StabilityProtocol(resettle=False)
    ajar = _with(scene, oid, joint_states={"door": 0.6, "drawer": 0.1})
    model = compile_scene(ajar, assets).model
    result = check_stability(model, protocol=strict)
    links = [f"{oid}/drawer", f"{oid}/door"]
    assert set(links) <= set(result.object_ids) and bool(result.stable[0])
    door = model.joint(f"{oid}/door")
    model.jnt_stiffness[door.id] = 40.0  # springref 0: pulls the door shut
    model.dof_frictionloss[door.dofadr[0]] = 0.0
    shut = check_stability(model, protocol=strict)
    j = shut.object_ids.index(f"{oid}/door")
    assert not shut.stable_object[0, j] and shut.rotation_deg[0, j] > 5.0
    assert shut.stable_object[0, shut.object_ids.index(f"{oid}/drawer")]
    metrics = measure_scene(ajar, assets, trimesh_test=False)
    entry = metrics["per_object"][oid]
    assert set(entry["links"]) == set(links) and entry["stable"]
    assert metrics["dynamic_objects"] == len([o for o in ajar.objects if not o.is_static])
