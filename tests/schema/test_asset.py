"""Asset meta schema: version-1 metas still read (and stay cached), an articulated version-2
meta round-trips, and each bad articulation is refused naming the field and the choices."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from factory.schema import (
    ASSET_SCHEMA_VERSION,
    AssetMeta,
    JointMeta,
    SchemaError,
    SchemaVersionError,
    SweptBox,
    UnsafePathError,
    to_dict,
)
from factory.schema.asset import (
    Articulation,
    LinkMeta,
    asset_meta_from_dict,
    asset_meta_to_json,
    load_asset_meta,
)

V1_META: dict[str, Any] = {
    "schema_version": 1,
    "asset_id": "proc-0123456789abcdef",
    "backend": "procedural",
    "visual": "visual.obj",
    "extents": [0.6, 0.6, 0.9],
    "collision": ["collision_0.obj"],
    "supports": [{"name": "top", "z": 0.9, "rect": [-0.3, -0.3, 0.3, 0.3]}],
}


def _drawer_meta() -> dict[str, Any]:
    """A version-2 cabinet: a root carcass (collision 0-1, visual 0) and one drawer link
    (collision 2-5, visual 1) on a slide joint, its bar handle being collision 5."""
    return {
        "asset_id": "proc-fedcba9876543210",
        "backend": "procedural",
        "visual": "visual.obj",
        "extents": [0.6, 0.6, 0.9],
        "collision": [f"collision_{k}.obj" for k in range(6)],
        "category": "kitchen_cabinet",
        "visual_parts": [{"file": "visual_0.obj"}, {"file": "visual_1.obj", "link": "drawer_0"}],
        "supports": [{"name": "bottom", "z": 0.62, "rect": [-0.25, -0.25, 0.25, 0.25]}],
        "containers": [
            {
                "name": "drawer",
                "lo": [-0.25, -0.25, 0.65],
                "hi": [0.25, 0.25, 0.85],
                "link": "drawer_0",
                "access": "drawer_0",
            }
        ],
        "mass": 30.0,
        "articulation": {
            "links": [
                {
                    "name": "drawer_0",
                    "parent": "",
                    "collision": [2, 3, 4, 5],
                    "visual": [1],
                    "handles": [
                        {
                            "name": "handle_0",
                            "style": "bar",
                            "center": [0.0, -0.33, 0.8],
                            "along": [1.0, 0.0, 0.0],
                            "normal": [0.0, -1.0, 0.0],
                            "length": 0.16,
                            "thickness": 0.012,
                            "clearance": 0.035,
                            "collision": [5],
                        }
                    ],
                }
            ],
            "joints": [
                {
                    "name": "drawer_0",
                    "kind": "slide",
                    "role": "drawer",
                    "link": "drawer_0",
                    "anchor": [0.0, -0.3, 0.7],
                    "axis": [0.0, -1.0, 0.0],
                    "range": [0.0, 0.44],
                    "damping": 4.0,
                    "frictionloss": 3.0,
                    "armature": 0.0,
                    "stiffness": 0.0,
                    "springref": 0.0,
                    "rest": [[0.0, 0.44]],
                }
            ],
            "swept": {"lo": [-0.3, -0.8, 0.0], "hi": [0.3, 0.3, 0.9]},
        },
        "schema_version": 2,
    }


def test_version_1_meta_reads_as_current_without_articulation() -> None:
    meta = asset_meta_from_dict(copy.deepcopy(V1_META))
    assert meta.articulation is None and meta.schema_version == ASSET_SCHEMA_VERSION == 2
    assert meta.supports == V1_META["supports"]
    assert json.loads(asset_meta_to_json(meta))["schema_version"] == 2


def test_old_cached_asset_is_kept(tmp_path: Path) -> None:
    """The cache rebuilds assets whose meta does not read: a version-1 asset must not be."""
    from factory.assets.cache import cached

    folder = tmp_path / V1_META["asset_id"]
    folder.mkdir()
    (folder / "meta.json").write_text(json.dumps(V1_META))
    for name in ("visual.obj", "collision_0.obj"):
        (folder / name).write_text("v 0 0 0\n")
    meta = cached(tmp_path, V1_META["asset_id"])
    assert meta is not None and meta.articulation is None
    assert json.loads((folder / "meta.json").read_text()) == V1_META  # left as it was


@pytest.mark.parametrize("version", [0, 3, None, True, "2"])
def test_unreadable_version(version: Any) -> None:
    data = {**V1_META, "schema_version": version}
    with pytest.raises(SchemaVersionError, match=r"this factory reads \[1, 2\]"):
        asset_meta_from_dict(data, "x/meta.json")


def test_version_1_has_no_articulation() -> None:
    data = {**V1_META, "articulation": None}
    with pytest.raises(SchemaError, match="version-1 meta has no 'articulation'"):
        asset_meta_from_dict(data)


def test_articulated_meta_round_trips(tmp_path: Path) -> None:
    data = _drawer_meta()
    meta = asset_meta_from_dict(copy.deepcopy(data))
    art = meta.articulation
    assert art is not None
    joint = art.joint("drawer_0")
    assert joint.kind == "slide" and joint.range == [0.0, 0.44] and joint.rest == [[0.0, 0.44]]
    assert art.link("drawer_0").handles[0].collision == [5]
    full = to_dict(meta)
    assert {k: full[k] for k in data} == data  # the rest are defaults
    assert asset_meta_from_dict(full) == meta
    (tmp_path / "meta.json").write_text(asset_meta_to_json(meta))
    assert load_asset_meta(tmp_path) == meta


def _edit(path: str, value: Any) -> dict[str, Any]:
    data = _drawer_meta()
    d: Any = data
    keys = path.split(".")
    for k in keys[:-1]:
        d = d[int(k)] if isinstance(d, list) else d[k]
    if isinstance(d, list):
        d[int(keys[-1])] = value
    else:
        d[keys[-1]] = value
    return data


A = "articulation"
LINK = f"{A}.links.0"
JOINT = f"{A}.joints.0"
HANDLE = f"{LINK}.handles.0"
BAD = [
    (f"{JOINT}.link", "drawer_9", SchemaError, r"link 'drawer_9' is not a link.*\['drawer_0'\]"),
    (f"{LINK}.parent", "carcass", SchemaError, r"parent 'carcass' is not the root.*\[''\]"),
    (f"{LINK}.name", "free", SchemaError, r"'free' is reserved \(reserved: \['free'\]\)"),
    (f"{LINK}.name", "a/b", UnsafePathError, "contains a path"),
    (f"{JOINT}.name", "free", SchemaError, "is reserved"),
    (f"{JOINT}.axis", [0.0, -0.9, 0.0], SchemaError, r"axis must be a unit vector.*norm 0\.9"),
    (f"{JOINT}.axis", [0.0, 1.0], SchemaError, r"axis must hold 3 numbers"),
    (f"{JOINT}.range", [0.1, 0.44], SchemaError, r"range must be \[lo, hi\] \(m\) with lo <= 0"),
    (f"{JOINT}.range", [0.0, 0.0], SchemaError, "lo < hi"),
    (f"{JOINT}.rest", [[0.0, 0.5]], SchemaError, r"rest\[0\] must be \[a, b\] \(m\)"),
    (f"{JOINT}.kind", "ball", SchemaError, r"'ball' is not one of \['hinge', 'slide'\]"),
    (f"{JOINT}.role", "hatch", SchemaError, r"'hatch' is not one of \['door', 'drawer'"),
    (f"{JOINT}.damping", -1.0, SchemaError, "damping must be >= 0"),
    (f"{LINK}.collision", [2, 3, 6], SchemaError, r"index 6 is out of range.*0\.\.5"),
    (f"{LINK}.visual", [2], SchemaError, r"visual: index 2 is out of range"),
    (f"{LINK}.collision", [2, 2, 5], SchemaError, "index 2 is already claimed by 'drawer_0'"),
    (f"{HANDLE}.collision", [1], SchemaError, r"collision indices \[1\] are not its link's"),
    (f"{HANDLE}.style", "rope", SchemaError, r"'rope' is not one of \['bar', 'knob'"),
    (f"{HANDLE}.normal", [1.0, 0.0, 0.0], SchemaError, "along and normal must be perpendicular"),
    (f"{HANDLE}.length", 0.0, SchemaError, r"length must be > 0"),
    (f"{A}.swept.hi", [0.3, -0.9, 0.9], SchemaError, r"swept: lo .* must be <= hi"),
    ("containers.0.access", "door_3", SchemaError, r"access 'door_3' is not one of \['', 'dra"),
    ("supports.0.link", "shelf", SchemaError, r"link 'shelf' is not one of \['', 'drawer_0'\]"),
    ("visual_parts.0.link", "lid", SchemaError, r"visual_parts\[0\]\.link 'lid'"),
    (f"{A}.joints", [], SchemaError, r"links \['drawer_0'\] have no joint"),
]


@pytest.mark.parametrize(("path", "value", "exc", "match"), BAD, ids=[b[0] for b in BAD])
def test_bad_articulation_is_refused(path: str, value: Any, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match) as info:
        asset_meta_from_dict(_edit(path, value), "assets/x/meta.json")
    assert str(info.value).startswith("assets/x/meta.json")


def test_duplicate_names_and_a_second_joint_per_link() -> None:
    data = _drawer_meta()
    links, joints = data[A]["links"], data[A]["joints"]
    links.append({**copy.deepcopy(links[0]), "collision": [], "visual": [], "handles": []})
    with pytest.raises(SchemaError, match="duplicate link name 'drawer_0'"):
        asset_meta_from_dict(copy.deepcopy(data))
    links[1]["name"] = "drawer_1"
    joints.append(copy.deepcopy(joints[0]))
    with pytest.raises(SchemaError, match="duplicate joint name 'drawer_0'"):
        asset_meta_from_dict(copy.deepcopy(data))
    joints[1]["name"] = "drawer_1"
    with pytest.raises(SchemaError, match="link 'drawer_0' already moves by joint 'drawer_0'"):
        asset_meta_from_dict(copy.deepcopy(data))
    joints[1]["link"] = "drawer_1"
    assert asset_meta_from_dict(data).articulation is not None


def test_meta_built_in_code_is_checked() -> None:
    joint = JointMeta(
        name="lid",
        kind="hinge",
        role="lid",
        link="lid",
        anchor=[0.0, 0.2, 0.4],
        axis=[-1.0, 0.0, 0.0],
        range=[0.0, 1.9],
    )
    art = Articulation(
        links=[LinkMeta(name="lid", collision=[1])],
        joints=[joint],
        swept=SweptBox(lo=[-0.3, -0.2, 0.0], hi=[0.3, 0.6, 0.9]),
    )
    meta = AssetMeta("a", "procedural", "visual.obj", [0.6, 0.4, 0.4], collision=["c0", "c1"])
    meta.articulation = art
    assert asset_meta_to_json(meta)  # checked on writing too
    with pytest.raises(SchemaError, match=r"index 1 is out of range \(the list has 1 entries"):
        AssetMeta("b", "procedural", "visual.obj", [1, 1, 1], collision=["c0"], articulation=art)
