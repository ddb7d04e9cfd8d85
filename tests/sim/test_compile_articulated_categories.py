"""Every articulated category compiled on its own: each joint moves over its whole range
without its link running into the rest of the object, and, closed (and ajar), the object
holds under the strict stability protocol (fixed where the catalogue fixes it)."""

from __future__ import annotations

import copy
from typing import Any

import mujoco
import numpy as np
import pytest

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec
from factory.schema import AssetMeta
from factory.schema.scene import (
    AssetRef,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
)
from factory.sim.compile import compile_scene

ARTICULATED = sorted(n for n, c in CATEGORIES.items() if c.articulated)
OID = "obj_0"
PENETRATION = 1e-3
"""Deepest contact (m) allowed between an object's own pieces (fronts sit flush, 3 mm apart)."""


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> AssetLibrary:
    return AssetLibrary(
        tmp_path_factory.mktemp("artic") / "assets", texture_size=64, articulated=True
    )


def _scene(category: str, meta: AssetMeta) -> Scene:
    """One room with the object alone in it: on the floor (a wall category mounted at
    1.4 m), static where the catalogue fixes it."""
    cat = CATEGORIES[category]
    wall = cat.placement == "wall"
    obj = SceneObject(
        id=OID,
        room_id="room",
        category=category,
        position=Vec3(2.0, 2.0, 1.4 if wall else 0.0),
        dimensions=Size3(*(float(v) for v in meta.extents)),
        placement=Placement(kind="wall" if wall else "floor"),
        asset=AssetRef(backend=meta.backend, asset_id=meta.asset_id),
        physics=Physics(
            mass=float(meta.mass or 1.0), friction=float(meta.friction or 0.6), static=cat.fixed
        ),
    )
    room = Room("room", "kitchen", Vec3(0.0, 0.0, 0.0), Size3(4.0, 4.0, 2.7))
    return Scene(id="artic", rooms=[room], objects=[obj])


@pytest.fixture(scope="module")
def compiled(library: AssetLibrary) -> Any:
    cache: dict[str, tuple[AssetMeta, mujoco.MjModel]] = {}

    def get(category: str) -> tuple[AssetMeta, mujoco.MjModel]:
        if category not in cache:
            meta = library.get(AssetSpec(category, seed=0))
            model = compile_scene(_scene(category, meta), library.assets_dir).model
            cache[category] = (meta, model)
        return cache[category]

    return get


def _own_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[str, str, float]]:
    """Contacts between two of the object's pieces, deeper than :data:`PENETRATION`."""
    out = []
    for c in data.contact[: data.ncon]:
        a, b = model.geom(c.geom1).name, model.geom(c.geom2).name
        if a.startswith(f"{OID}/") and b.startswith(f"{OID}/") and c.dist < -PENETRATION:
            out.append((a, b, float(c.dist)))
    return out


@pytest.mark.parametrize("category", ARTICULATED)
def test_every_joint_moves_over_its_range_without_self_collision(compiled, category: str) -> None:
    """Each joint at 0, 50 % and 100 % of its range (the others closed), then every joint at
    50 % and 100 % together: no piece of a link cuts into another piece of the object
    (parent-child contacts are counted: MuJoCo's parent filter is off here); fully open,
    every link has moved away from its closed place."""
    meta, model = compiled(category)
    art = meta.articulation
    assert art is not None and art.joints
    model = copy.copy(model)  # the stability test shares the cached model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    data = mujoco.MjData(model)
    adr = {j.name: int(model.joint(f"{OID}/{j.name}").qposadr[0]) for j in art.joints}
    hi = {j.name: float(model.joint(f"{OID}/{j.name}").range[1]) for j in art.joints}
    states = [{name: f} for name in adr for f in (0.0, 0.5, 1.0)]
    states += [dict.fromkeys(adr, 0.5), dict.fromkeys(adr, 1.0)]
    closed: dict[str, np.ndarray] = {}
    for state in states:
        data.qpos[:] = model.qpos0
        for name, f in state.items():
            data.qpos[adr[name]] = f * hi[name]
        mujoco.mj_forward(model, data)
        assert not _own_contacts(model, data), (category, state, _own_contacts(model, data))
        if not closed:
            closed = {x.name: _link_geoms(model, data, x.name) for x in art.links}
    for x in art.links:  # the last state: all open
        moved = np.linalg.norm(_link_geoms(model, data, x.name) - closed[x.name], axis=1)
        assert moved.max() > 0.1, (category, x.name, moved.max())


def _link_geoms(model: mujoco.MjModel, data: mujoco.MjData, link: str) -> np.ndarray:
    """The world positions of the geoms of a link body."""
    body = model.body(f"{OID}/{link}").id
    return data.geom_xpos[model.geom_bodyid == body].copy()


@pytest.mark.parametrize("category", ARTICULATED)
def test_closed_and_ajar_hold_under_the_strict_protocol(compiled, category: str) -> None:
    """2 s under gravity from rest, as the critic runs it (no resettle): closed, every link
    stays closed; ajar (every joint at 40 % of its range) every link stays where it was; the
    object itself (free where it is not fixed) stays put."""
    from factory.sim.stability import StabilityProtocol, check_stability

    meta, model = compiled(category)
    assert meta.articulation is not None
    q0 = np.tile(model.qpos0, (2, 1))
    for j in meta.articulation.joints:
        joint = model.joint(f"{OID}/{j.name}")
        q0[1, joint.qposadr[0]] = 0.4 * joint.range[1]
    result = check_stability(model, q0, protocol=StabilityProtocol(resettle=False))
    links = {f"{OID}/{x.name}" for x in meta.articulation.links}
    assert links <= set(result.object_ids)
    cat = CATEGORIES[category]
    assert (OID in result.object_ids) == (not cat.fixed and cat.placement != "wall")
    assert not result.invalid.any(), result.reasons
    assert result.stable.all(), (result.object_ids, result.translation, result.rotation_deg)
