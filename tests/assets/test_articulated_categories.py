"""Every articulated category's asset: graspable handles in front of the closed fronts,
interiors declared as supports with their link and the joint to open first, the cabinet
template's layout parameters, and one rigid body with the switch off."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import trimesh

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec
from factory.assets.catalog import CatalogError, build_template
from factory.robots.panda import GRIP_OPEN
from factory.schema import AssetMeta

ARTICULATED = sorted(n for n, c in CATEGORIES.items() if c.articulated)
NEW = (
    "wall_cabinet",
    "drawer_chest",
    "bedside_cabinet",
    "built_in_wardrobe",
    "upright_fridge",
    "microwave_oven",
    "file_drawer_cabinet",
    "two_door_sideboard",
    "glazed_bookcase",
    "front_loader_washer",
    "double_door_cupboard",
    "desk_pedestal",
)
FINGER = 0.02
"""Room (m) a Panda finger pad needs behind a grip (its pads are ~18 mm thick)."""


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """category -> (meta, closed collision hulls) of seed 0, articulated."""
    lib = AssetLibrary(
        tmp_path_factory.mktemp("artic") / "assets", texture_size=64, articulated=True
    )
    cache: dict[str, tuple[AssetMeta, list[trimesh.Trimesh]]] = {}

    def get(category: str) -> tuple[AssetMeta, list[trimesh.Trimesh]]:
        if category not in cache:
            meta = lib.get(AssetSpec(category, seed=0))
            folder = lib.assets_dir / meta.asset_id
            hulls = [trimesh.load(folder / f, force="mesh") for f in meta.collision]
            cache[category] = (meta, hulls)
        return cache[category]

    return get


def _inside(hull: trimesh.Trimesh, pts: np.ndarray, margin: float = 1e-4) -> np.ndarray:
    """Which points lie inside the convex ``hull`` deeper than ``margin``."""
    normals, origins = hull.face_normals, hull.triangles[:, 0, :]
    d = np.einsum("fk,pfk->pf", normals, pts[:, None, :] - origins[None])
    return (d < -margin).all(axis=1)


def test_the_new_categories_are_articulated() -> None:
    for name in NEW:
        assert CATEGORIES[name].articulated, name
    assert set(NEW) < set(ARTICULATED)


@pytest.mark.parametrize("category", ARTICULATED)
def test_handles_fit_the_gripper_and_stand_clear_of_the_closed_fronts(built, category: str) -> None:
    """Every link has a handle; the Panda's open fingers (``GRIP_OPEN``) close across its
    grip (a knob's cap too), a bar or pull leaves room for a finger behind its grip, and the
    grip stands proud of its own front: from the grip centre out along the handle's normal
    (15 cm, the approach) no collision piece of the closed object but the handle's own is in
    the way."""
    meta, hulls = built(category)
    art = meta.articulation
    assert art is not None
    for link in art.links:
        assert link.handles, (category, link.name)
        own = set(link.collision)
        for h in link.handles:
            assert h.collision and set(h.collision) <= own
            assert h.thickness < GRIP_OPEN - 0.01, (h.name, h.thickness)
            if h.style == "knob":
                assert h.length < GRIP_OPEN - 0.01, (h.name, h.length)
            if h.style in ("bar", "pull"):
                assert h.clearance >= FINGER, (h.name, h.clearance)
            c, n = np.asarray(h.center), np.asarray(h.normal)
            front = [k for k in link.collision if k not in h.collision]
            face = max(float((hulls[k].vertices @ n).max()) for k in front)
            if h.style == "edge":  # the grip is the front's own outermost edge
                assert c @ n >= face - 1e-6, (h.name, "not the front's edge")
            else:
                assert c @ n > face + 0.01, (h.name, "not proud of its front")
            ray = c + np.linspace(0.0, 0.15, 31)[:, None] * n
            for k, hull in enumerate(hulls):
                if k not in h.collision:
                    assert not _inside(hull, ray).any(), (h.name, "blocked by piece", k)
            assert 0.0 < c[2] < meta.extents[2] and c[1] < 0.0  # on the front, in reach


@pytest.mark.parametrize("category", ARTICULATED)
def test_interiors_are_supports_reached_through_their_joint(built, category: str) -> None:
    """Every support but the top is reached through one of the asset's joints and carried by
    the link it names (a drawer's floor rides with its drawer); above each, at 1 cm, its rect
    (inset 2 cm) is free of every closed collision piece, with at least 8 cm of clearance."""
    meta, hulls = built(category)
    art = meta.articulation
    assert art is not None
    joints = {j.name for j in art.joints}
    links = {x.name for x in art.links}
    inner = [s for s in meta.supports if s.get("access")]
    assert inner, category
    assert {s["name"] for s in meta.supports} - {s["name"] for s in inner} == {"case_top"}
    for s in inner:
        assert s["access"] in joints, s
        assert s.get("link", "") in links | {""}, s
        x0, y0, x1, y1 = s["rect"]
        assert x1 - x0 > 0.1 and y1 - y0 > 0.1, s
        assert s["clearance"] >= 0.08, s
        u, v = np.meshgrid(
            np.linspace(x0 + 0.02, x1 - 0.02, 5), np.linspace(y0 + 0.02, y1 - 0.02, 5)
        )
        pts = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, s["z"] + 0.01)])
        for k, hull in enumerate(hulls):
            assert not _inside(hull, pts).any(), (s["name"], k)
    for c in meta.containers:
        assert c.get("access") in joints, c


def test_layout_parameters_are_validated_with_the_field_named() -> None:
    cases = [
        ({"doors": 3}, "template.doors"),
        ({"drawers": 1.5}, "template.drawers"),
        ({"drawers": 0, "doors": 0}, "template.drawers"),
        ({"hinge": "top"}, "template.hinge"),
        ({"shelves": 2, "doors": 0}, "template.shelves"),
        ({"handles": "edge", "drawers": 3, "doors": 0}, "template.handles"),
        ({"handles": "edge", "doors": 2}, "template.handles"),
        ({"rail": "yes"}, "template.rail"),
        ({"glazed": "yes"}, "template.glazed"),
        ({"glazed": True, "doors": 0, "drawers": 2}, "template.shelves"),
    ]
    for params, match in cases:
        with pytest.raises(CatalogError, match=match):
            build_template("cab", {"kind": "cabinet", **params})
    with pytest.raises(CatalogError, match=r"template\.hinge"):
        build_template("fridge", {"kind": "hinged_fridge", "hinge": "middle"})
    with pytest.raises(CatalogError, match=r"template\.handles"):
        build_template("washer", {"kind": "hinged_washer", "handles": "lever"})


@pytest.mark.parametrize("category", ARTICULATED)
def test_switched_off_the_category_is_one_rigid_body(tmp_path, built, category: str) -> None:
    """Without ``assets.articulated``: no links, the same collision pieces, closed, and the
    interiors stay supports of the root (nothing to open first)."""
    meta, _ = built(category)
    off = AssetLibrary(tmp_path, texture_size=64).get(AssetSpec(category, seed=0))
    assert off.articulation is None and off.request["rig"] == "fused"
    assert len(off.collision) == len(meta.collision) and off.extents == meta.extents
    assert off.mass == pytest.approx(meta.mass)
    assert all("access" not in s and "link" not in s for s in off.supports)
    lo, hi = CATEGORIES[category].mass
    assert lo <= off.mass <= hi


def test_rigid_categories_are_built_articulated_as_their_moving_counterparts(
    tmp_path: Any,
) -> None:
    """``articulated_as``: with ``assets.articulated`` a request for a rigid category that has
    an articulated counterpart (a refrigerator) gets that category with its joints; without it,
    the rigid asset as before. Every counterpart is articulated and reads from its own name; a
    counterpart that is not articulated is refused naming the field and the choices."""
    from factory.assets.catalog import build_category, load_catalog

    pairs = {n: c.articulated_as for n, c in CATEGORIES.items() if c.articulated_as}
    assert {"refrigerator", "microwave", "kitchen_cabinet"} <= set(pairs)
    assert all(CATEGORIES[m].articulated for m in pairs.values())
    moving = AssetLibrary(tmp_path / "a", texture_size=64, articulated=True)
    rigid = AssetLibrary(tmp_path / "b", texture_size=64)
    for text, want in (("a refrigerator", "upright_fridge"), ("a microwave", "microwave_oven")):
        meta, res = moving.from_text(text)
        assert res.spec.category == want and meta.articulation is not None
        assert meta.articulation.joints
        meta, res = rigid.from_text(text)
        assert res.spec.category != want and meta.articulation is None
    entry = {"template": {"kind": "block"}, "dims": [1, 1, 1], "materials": ["oak", "oak"]}
    entry |= {"mass": [1, 2], "articulated_as": 3}
    with pytest.raises(CatalogError, match="articulated_as"):
        build_category("crate_x", entry)
    folder = tmp_path / "cat"
    folder.mkdir()
    (folder / "categories_00.yaml").write_text(
        "crate_x: {template: {kind: block}, dims: [1, 1, 1], materials: [oak, oak], "
        "mass: [1, 2], articulated_as: crate_x}\n"
    )
    with pytest.raises(CatalogError, match=r"articulated_as.*not an articulated category"):
        load_catalog(folder)
