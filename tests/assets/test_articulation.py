"""Articulated shapes (issue 35, S2): joint transforms and link poses, the swept box, the
catalogue's joint physics, handles, and an articulated category built into an asset."""

from __future__ import annotations

import math

import numpy as np
import pytest

from factory.assets.articulation import (
    JOINT_DEFAULTS,
    JointSpec,
    applied,
    link_transform,
    parse_physics,
    pose_of,
    swept_box,
)
from factory.assets.catalog import CatalogError
from factory.assets.geometry import Shape, box
from factory.assets.procedural import AssetError
from factory.schema.asset import Articulation, JointMeta, LinkMeta, SweptBox

WOOD = (0.6, 0.4, 0.2, 1.0)


def _joint(name: str, kind: str, link: str, anchor, axis, rng, parent: str = "") -> JointMeta:
    role = "door" if kind == "hinge" else "drawer"
    return JointMeta(name, kind, role, link, list(anchor), list(axis), list(rng))  # type: ignore[arg-type]


def _art() -> Articulation:
    """A drawer sliding out along -y, carrying a small door hinged about z at x = 0.1."""
    return Articulation(
        links=[LinkMeta("drawer"), LinkMeta("flap", parent="drawer")],
        joints=[
            _joint("drawer", "slide", "drawer", (0, -0.2, 0.5), (0, -1, 0), (0, 0.4)),
            _joint("flap", "hinge", "flap", (0.1, -0.25, 0.5), (0, 0, 1), (0, 2)),
        ],
        swept=SweptBox([0, 0, 0], [0, 0, 0]),
    )


def test_slide_and_hinge_transforms() -> None:
    slide = _joint("s", "slide", "s", (1, 2, 3), (0, -1, 0), (0, 0.5))
    tf = link_transform(slide, 0.3)
    assert np.allclose(tf[:3, :3], np.eye(3)) and np.allclose(tf[:3, 3], (0, -0.3, 0))
    hinge = _joint("h", "hinge", "h", (0.5, 0, 0), (0, 0, 1), (0, 2))
    tf = link_transform(hinge, math.pi / 2)
    # the anchor stays; a point 1 m along +x from it swings to +y
    assert np.allclose(tf @ [0.5, 0, 0, 1], [0.5, 0, 0, 1])
    assert np.allclose(tf @ [1.5, 0, 0.7, 1], [0.5, 1, 0.7, 1])
    assert np.allclose(link_transform(hinge, 0.0), np.eye(4))


def test_link_poses_compose_through_parents() -> None:
    art = _art()
    states = {"drawer": 0.3, "flap": math.pi / 2}
    assert np.allclose(pose_of(art, states, ""), np.eye(4))
    assert np.allclose(pose_of(art, states, "drawer")[:3, 3], (0, -0.3, 0))
    flap = pose_of(art, states, "flap")
    # the flap's hinge rides out with the drawer, then turns the flap about it
    hinge_closed = np.array([0.1, -0.25, 0.5, 1.0])
    assert np.allclose(flap @ hinge_closed, [0.1, -0.55, 0.5, 1])
    assert np.allclose(flap @ [0.2, -0.25, 0.5, 1], [0.1, -0.45, 0.5, 1])
    assert np.allclose(pose_of(art, {}, "flap"), np.eye(4))
    with pytest.raises(KeyError):
        pose_of(art, states, "lid")


def test_swept_box_covers_the_limits() -> None:
    s = Shape([box((0.6, 0.5, 0.8), (0, 0, 0.4), "oak", WOOD, "carcass")])
    door = box((0.5, 0.02, 0.6), (0, -0.26, 0.4), "oak", WOOD, "door")
    door.link = "door"
    drawer = box((0.5, 0.4, 0.1), (0, 0.0, 0.75), "oak", WOOD, "drawer")
    drawer.link = "drawer"
    s.parts += [door, drawer]
    s.joints = [
        JointSpec("door", "hinge", "door", "door", (-0.25, -0.26, 0.4), (0, 0, -1), (0, 2.0)),
        JointSpec("drawer", "slide", "drawer", "drawer", (0, -0.2, 0.75), (0, -1, 0), (0, 0.3)),
    ]
    sw = swept_box(s)
    lo, hi = np.array(sw.lo), np.array(sw.hi)
    for name, link in (("door", "door"), ("drawer", "drawer")):
        j = next(x for x in s.joints if x.name == name)
        for q in j.range:
            tf = link_transform(j, q)
            part = next(p for p in s.parts if p.link == link)
            pts = part.visual.vertices @ tf[:3, :3].T + tf[:3, 3]
            assert (pts >= lo - 1e-9).all() and (pts <= hi + 1e-9).all()
    assert lo[1] < -0.25 - 0.3 + 0.01  # the open drawer reaches out
    assert lo[1] < -0.26 - 0.45  # the door swings out almost its width


def test_joint_spec_is_validated() -> None:
    with pytest.raises(AssetError, match="kind 'twist' is not one of"):
        JointSpec("j", "twist", "door", "l", (0, 0, 0), (0, 0, 1), (0, 1))
    with pytest.raises(AssetError, match="unit vector"):
        JointSpec("j", "hinge", "door", "l", (0, 0, 0), (0, 0, 2), (0, 1))
    with pytest.raises(AssetError, match="lo <= 0 <= hi"):
        JointSpec("j", "hinge", "door", "l", (0, 0, 0), (0, 0, 1), (0.2, 1))


def test_physics_defaults_and_parse_errors_name_the_field() -> None:
    phys = parse_physics("cab", {"drawer": {"range": [0, 0.5], "damping": 2.0}})
    assert set(phys) == set(JOINT_DEFAULTS)
    assert phys["drawer"].range == (0.0, 0.5) and phys["drawer"].damping == 2.0
    assert phys["drawer"].frictionloss == JOINT_DEFAULTS["drawer"]["friction"]
    assert phys["lid"].hold
    door = JointSpec("d", "hinge", "door", "d", (0, 0, 0), (0, 0, 1), (0, 3))
    assert np.allclose(applied(door, phys["door"]).range, (0, math.radians(110)))
    drawer = JointSpec("s", "slide", "drawer", "s", (0, 0, 0), (0, -1, 0), (0, 0.4))
    assert np.allclose(applied(drawer, phys["drawer"]).range, (0, 0.2))
    cases = [
        ({"hatch": {}}, "articulation.hatch.*valid roles: door, drawer"),
        ({"door": {"range": [10, 90]}}, "articulation.door.range"),
        ({"door": {"friction": -1}}, "articulation.door.friction"),
        ({"door": {"spring": 3}}, "articulation.door.spring"),
        ({"lid": {"hold": "yes"}}, "articulation.lid.hold"),
        ({"door": {"stiff": 1}}, "articulation.door.stiff.*valid keys: range"),
        ([1, 2], "field 'articulation'"),
    ]
    for raw, match in cases:
        with pytest.raises(CatalogError, match=match):
            parse_physics("cab", raw)


@pytest.mark.parametrize("style", ["bar", "knob", "pull", "edge"])
def test_handle_pieces_are_convex_and_the_meta_validates(style: str) -> None:
    from factory.assets.geometry import MAX_HULL_VERTICES
    from factory.assets.handles import handle
    from factory.schema.asset import AssetMeta

    parts, meta = handle(style, "h", (0.1, -0.3, 0.5), (1, 0, 0), (0, -1, 0), 0.12, 0.04, "door")
    pieces = [c for p in parts for c in p.collision]
    assert all(p.link == "door" and p.handle == "h" for p in parts)
    for c in pieces:
        assert c.is_convex and c.volume > 0 and len(c.vertices) <= MAX_HULL_VERTICES
    if pieces:  # in front of the face (y <= -0.3), within its depth and length
        lo, hi = np.min([c.bounds[0] for c in pieces], 0), np.max([c.bounds[1] for c in pieces], 0)
        assert hi[1] <= -0.3 + 1e-9 and lo[1] >= -0.34 - 1e-9
        assert hi[0] - lo[0] <= 0.12 + 1e-9
    meta.collision = list(range(len(pieces)))
    link = LinkMeta("door", collision=list(range(len(pieces))), handles=[meta])
    joint = _joint("door", "hinge", "door", (0.3, -0.3, 0), (0, 0, 1), (0, 2))
    AssetMeta(
        "a",
        "procedural",
        "visual.obj",
        [1, 1, 1],
        collision=[f"c{k}.obj" for k in range(len(pieces))],
        articulation=Articulation([link], [joint], SweptBox([0, 0, 0], [1, 1, 1])),
    )
    if style == "bar":
        assert meta.clearance >= 0.025
    with pytest.raises(AssetError, match="is not one of"):
        handle("hook", "h", (0, 0, 0), (1, 0, 0), (0, -1, 0), 0.1, 0.03)


def test_articulated_category_asset_validates_and_switch_off_changes_nothing(tmp_path) -> None:
    from factory.assets import AssetLibrary, AssetSpec
    from factory.assets.cache import cached

    on = AssetLibrary(tmp_path / "on", texture_size=64, articulated=True)
    off = AssetLibrary(tmp_path / "off", texture_size=64)
    meta = on.get(AssetSpec("base_cabinet", seed=1))
    art = meta.articulation
    assert art is not None and meta.request["rig"] == "joints"
    assert [x.name for x in art.links] == ["drawer", "door"]
    assert {j.name: j.kind for j in art.joints} == {"drawer": "slide", "door": "hinge"}
    assert all(h.collision for link in art.links for h in link.handles)
    assert {s["name"]: s.get("link", "") for s in meta.supports}["drawer_floor"] == "drawer"
    assert cached(tmp_path / "on", meta.asset_id) == meta  # written and read back, validated
    door = art.joint("door")
    opened = pose_of(art, {"door": door.range[1]}, "door")
    handle = np.array([*art.link("door").handles[0].center, 1.0])
    assert (opened @ handle)[1] < handle[1] - 0.2  # +q swings the door out to the front
    assert art.swept.lo[1] < -meta.extents[1] / 2 - 0.3
    fused = off.get(AssetSpec("base_cabinet", seed=1))
    assert fused.articulation is None and fused.request["rig"] == "fused"
    assert fused.asset_id != meta.asset_id and len(fused.collision) == len(meta.collision)
    # a rigid category: the same id and meta with the switch on or off (no rig key)
    a = on.get(AssetSpec("nightstand", seed=1))
    b = off.get(AssetSpec("nightstand", seed=1))
    assert a.asset_id == b.asset_id and "rig" not in a.request and a.articulation is None
    assert a.supports == b.supports and a.visual_parts == b.visual_parts


def test_rest_intervals_of_gravity_free_joints_with_and_without_springs() -> None:
    """A door on a vertical hinge rests anywhere in its range; with a closing spring, only
    where the spring's pull is within the joint's friction; a spring that pulls past a limit
    holds the link there; a lid (horizontal hinge) is not known yet."""
    from factory.assets.articulation import JointSpec
    from factory.assets.library import _rest

    door = JointSpec("door", "hinge", "door", "door", (0, 0, 0), (0, 0, 1), (0.0, 1.9))
    assert _rest(door) == [[0.0, 1.9]]
    assert _rest(door, stiffness=2.0, springref=0.0, friction=0.4) == [[0.0, 0.2]]
    assert _rest(door, stiffness=1.0, springref=-0.5, friction=0.2) == [[0.0, 0.0]]
    lid = JointSpec("lid", "hinge", "lid", "lid", (0, 0, 0), (1, 0, 0), (0.0, 1.5))
    assert _rest(lid) == []
