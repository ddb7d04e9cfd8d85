"""Augmentation: every level keeps task objects, roles and relations, and stays physical;
the stage is deterministic, sharded without gaps, resumable, and explains failures."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from factory.assets import AssetLibrary
from factory.augment.check import PhysicsCheck
from factory.augment.levels import AugmentError, category, configuration, layout
from factory.augment.stage import check_physics
from factory.scenes.brain import AgentConfig, generate_scene
from factory.schema import scene_to_json, validate

TASK = "a kitchen where the robot picks up the mug and puts it in the bowl"


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory):
    assets = tmp_path_factory.mktemp("run") / "assets"
    lib = AssetLibrary(assets)
    scene, _ = generate_scene(TASK, lib, seed=2, config=AgentConfig(max_objects=30))
    return scene, lib


def _check(lib: AssetLibrary) -> PhysicsCheck:
    return PhysicsCheck(lib.assets_dir, backend="cpu")


def _task(scene) -> dict:
    return {o.task_role: o for o in scene.objects if o.task_role}


def test_configuration_level(base) -> None:
    scene, lib = base
    v = configuration(scene, lib, 11, _check(lib)).scene
    validate(v)
    before, after = _task(scene), _task(v)
    assert set(after) == {"pick", "place_target"}
    for role, obj in after.items():
        old = before[role]
        assert (obj.id, obj.category, obj.asset.asset_id, obj.placement.support_id) == (
            old.id,
            old.category,
            old.asset.asset_id,
            old.placement.support_id,
        )
    assert any(
        (after[r].position.x, after[r].position.y) != (before[r].position.x, before[r].position.y)
        for r in after
    )
    assert check_physics(v, lib.assets_dir) is None
    assert scene_to_json(scene) != scene_to_json(v)


def test_category_level(base) -> None:
    scene, lib = base
    v = category(scene, lib, 12, _check(lib)).scene
    validate(v)
    before, after = _task(scene), _task(v)
    for role, obj in after.items():
        assert obj.category == before[role].category and obj.id == before[role].id
        assert obj.placement.support_id == before[role].placement.support_id
        assert obj.asset.asset_id != before[role].asset.asset_id  # a new instance
    assert check_physics(v, lib.assets_dir) is None


def test_layout_level(base) -> None:
    scene, lib = base
    v = layout(scene, lib, 13, _check(lib)).scene
    validate(v)
    before, after = _task(scene), _task(v)
    for role, obj in after.items():
        old = before[role]
        assert obj.id == old.id and obj.asset.asset_id == old.asset.asset_id
        assert obj.placement.support_id == old.placement.support_id  # same relation
        sup_old, sup_new = (
            scene.object(old.placement.support_id),
            v.object(obj.placement.support_id),
        )
        assert sup_new.asset.asset_id == sup_old.asset.asset_id
    kept = {o.id for o in after.values()} | {o.placement.support_id for o in after.values()}
    others_old = {o.asset.asset_id for o in scene.objects if o.id not in kept}
    others_new = {o.asset.asset_id for o in v.objects if o.id not in kept}
    assert others_new != others_old  # the background was regenerated
    assert v.rooms[0].dimensions != scene.rooms[0].dimensions
    assert check_physics(v, lib.assets_dir) is None


def test_configuration_needs_task_objects(base) -> None:
    scene, lib = base
    plain = copy.deepcopy(scene)
    for o in plain.objects:
        o.task_role = None
    with pytest.raises(AugmentError, match="no task-relevant objects"):
        configuration(plain, lib, 1, None)


def _run_with_parent(cli, run: Path, base) -> None:
    scene, lib = base
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    import shutil

    shutil.copytree(lib.assets_dir, run / "assets")


def test_stage_deterministic_sharded_resumable(cli, tmp_path: Path, base) -> None:
    args = [
        "stage=augment",
        "augment.levels=[category,configuration]",
        "augment.variants_per_scene=3",
        "augment.render=false",
    ]
    runs = []
    for name in ("a", "b"):
        run = tmp_path / name
        _run_with_parent(cli, run, base)
        runs.append(run)
    out = cli(*args, f"run_dir={runs[0]}")
    assert out.returncode == 0, out.stderr
    for k in range(2):  # the same work split over two shards
        env = {"SLURM_ARRAY_TASK_ID": str(k), "SLURM_ARRAY_TASK_COUNT": "2"}
        assert cli(*args, f"run_dir={runs[1]}", env=env).returncode == 0
    names = sorted(p.name for p in (runs[0] / "scenes").iterdir())
    assert names == sorted(p.name for p in (runs[1] / "scenes").iterdir())
    variants = [n for n in names if "__" in n]
    assert variants, names
    for n in variants:
        a = (runs[0] / "scenes" / n / "scene.json").read_text()
        assert a == (runs[1] / "scenes" / n / "scene.json").read_text()
        data = json.loads(a)
        assert data["source"].startswith("augment:")
        report = json.loads((runs[0] / "scenes" / n / "report.json").read_text())["augment"]
        assert report["seed"] == data["seed"] and report["levels"] == ["category", "configuration"]
    again = cli(*args, f"run_dir={runs[0]}")  # nothing left to do
    assert again.returncode == 0, again.stderr
    manifest = json.loads((runs[0] / "manifest.json").read_text())
    assert manifest["stages"]["augment"]["shards"]["0-of-1"]["result"]["done"] == 0


def test_stage_bad_input(cli, tmp_path: Path, base) -> None:
    run = tmp_path / "run"
    _run_with_parent(cli, run, base)
    out = cli("stage=augment", f"run_dir={run}", "augment.variants_per_scene=0")
    assert out.returncode == 2 and "variants_per_scene" in out.stderr
    out = cli("stage=augment", f"run_dir={run}", "augment.levels=[style]")
    assert out.returncode == 2 and "augment.levels" in out.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    out = cli("stage=augment", f"run_dir={empty}")
    assert out.returncode == 2 and "no scenes to augment" in out.stderr
