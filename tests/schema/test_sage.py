"""SAGE layout import/export: lossless, placement mapping, safe zips."""

from __future__ import annotations

import copy
import json
import os
import stat
import zipfile
from pathlib import Path
from typing import Any

import pytest

from factory.schema import SchemaError, UnsafePathError, scene_from_json, scene_to_json
from factory.schema.sage import extract_zip, read_package, sage_to_scene, scene_to_sage


def test_import_then_export_is_equal(sage_dict: dict[str, Any]) -> None:
    scene = sage_to_scene(copy.deepcopy(sage_dict))
    assert scene_to_sage(scene) == sage_dict
    # ... also after a trip through our own scene.json
    again = scene_from_json(scene_to_json(scene))
    assert scene_to_sage(again) == sage_dict
    # ... and as JSON text, key for key
    assert json.loads(json.dumps(scene_to_sage(again))) == json.loads(json.dumps(sage_dict))


def test_placement_mapping(sage_dict: dict[str, Any]) -> None:
    scene = sage_to_scene(sage_dict)
    by_id = {o.id: o for o in scene.objects}
    assert by_id["bed_0"].placement.kind == "floor" and by_id["bed_0"].placement.support_id is None
    assert by_id["nightstand_0"].placement.kind == "floor"
    assert by_id["nightstand_0"].placement.support_id == "bedroom"
    assert by_id["lamp_0"].placement.kind == "on_top"
    assert by_id["lamp_0"].placement.support_id == "nightstand_0"
    assert by_id["painting_0"].placement.kind == "wall" and by_id["painting_0"].is_static
    assert by_id["tv_0"].placement.kind == "wall" and by_id["tv_0"].is_static
    assert not by_id["cup_0"].is_static
    assert by_id["painting_0"].extras == {"sage": {"vlm_notes": {"style": "impressionist"}}}
    assert by_id["bed_0"].appearance.roughness == 0.8
    assert by_id["bed_0"].physics.mass == 60.0
    assert scene.source == "sage10k"
    assert scene.extras["sage"]["generator_version"] == "sage-1.0"


def test_missing_support_is_an_error(sage_dict: dict[str, Any]) -> None:
    sage_dict["rooms"][0]["objects"][2]["place_id"] = "ghost_table"
    with pytest.raises(SchemaError, match="'ghost_table' does not exist"):
        sage_to_scene(sage_dict)


def test_object_outside_rooms_is_an_error(sage_dict: dict[str, Any]) -> None:
    sage_dict["rooms"][1]["objects"][0]["position"]["x"] = 25.0
    with pytest.raises(SchemaError, match="outside every room"):
        sage_to_scene(sage_dict)


def test_malformed_layout_names_the_field(sage_dict: dict[str, Any]) -> None:
    del sage_dict["rooms"][0]["objects"][0]["dimensions"]
    with pytest.raises(SchemaError, match=r"'bed_0'.*missing 'dimensions'"):
        sage_to_scene(sage_dict)
    with pytest.raises(SchemaError, match="must be an object"):
        sage_to_scene([1, 2])


def test_read_package_finds_meshes(sage_package: Path) -> None:
    pkg = read_package(sage_package)
    assert set(pkg.meshes) == {"bed_0_mesh", "sofa_0_mesh", "cup_0_mesh"}
    assert set(pkg.textures) == set(pkg.meshes)


def test_unsafe_source_id_is_refused(tmp_path: Path, sage_dict: dict[str, Any]) -> None:
    sage_dict["rooms"][0]["objects"][0]["source_id"] = "../../etc/passwd"
    (tmp_path / "layout.json").write_text(json.dumps(sage_dict))
    with pytest.raises(UnsafePathError):
        read_package(tmp_path / "layout.json")


@pytest.mark.parametrize("member", ["../evil.txt", "/abs/evil.txt", "objects/../../evil.txt"])
def test_zip_with_unsafe_member_is_refused(tmp_path: Path, member: str) -> None:
    archive = tmp_path / "bad.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("layout.json", "{}")
        zf.writestr(member, "x")
    dest = tmp_path / "out"
    with pytest.raises(UnsafePathError, match="unsafe path"):
        extract_zip(archive, dest)
    assert not dest.exists()  # nothing was written
    assert not (tmp_path / "evil.txt").exists()


def test_zip_with_symlink_is_refused(tmp_path: Path) -> None:
    archive = tmp_path / "link.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        info = zipfile.ZipInfo("objects/link")
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(info, "/etc/passwd")
    with pytest.raises(UnsafePathError, match="symbolic link"):
        extract_zip(archive, tmp_path / "out")


def test_zip_round_trip(tmp_path: Path, sage_package: Path) -> None:
    archive = tmp_path / "pkg.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        for root, _, files in os.walk(sage_package):
            for f in files:
                p = Path(root) / f
                zf.write(p, p.relative_to(sage_package))
    out = extract_zip(archive, tmp_path / "x")
    assert read_package(out).meshes.keys() == read_package(sage_package).meshes.keys()


def test_not_a_zip(tmp_path: Path) -> None:
    p = tmp_path / "fake.zip"
    p.write_text("hello")
    with pytest.raises(SchemaError, match="not a readable zip"):
        extract_zip(p, tmp_path / "o")


def test_joint_states_go_to_a_side_file(tmp_path: Path, sage_dict: dict[str, Any]) -> None:
    """SAGE's layout has no joints: the export writes the layout unchanged and the joint
    states beside it, which ingest does not take for a scene."""
    from factory.scenes.ingest import discover
    from factory.scenes.sage_assets import export_sage

    scene = sage_to_scene(copy.deepcopy(sage_dict))
    layout = export_sage(scene, None, tmp_path / "plain")
    assert sorted(p.name for p in layout.parent.iterdir()) == [layout.name]
    stand = scene.object("nightstand_0")
    stand.joint_states = {"drawer_0": 0.12}
    stand.task_joint = "drawer_0"
    layout = export_sage(scene, None, tmp_path / "out")
    assert json.loads(layout.read_text()) == sage_dict
    side = json.loads(layout.with_name(f"{scene.id}.articulation.json").read_text())
    assert side == {
        "schema_version": 1,
        "objects": {"nightstand_0": {"asset_id": "", "joint_states": {"drawer_0": 0.12}}},
    }
    assert [(i.kind, i.path) for i in discover(tmp_path / "out")] == [("sage", layout)]
