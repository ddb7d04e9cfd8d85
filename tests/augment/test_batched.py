"""Batched configuration variants: the vectorised geometry agrees with the one-pair code, a
batch returns the requested number of distinct variants that each pass the ordinary whole-scene
check, and the same seed gives the same variants."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from factory.assets import AssetLibrary
from factory.augment.check import PhysicsCheck, pose_rows, verify_whole_scene
from factory.augment.distinct import Distinctness
from factory.augment.levels import configurations
from factory.augment.local import local_scene
from factory.augment.rects import rects_overlap
from factory.augment.sampling import movers_of, sample
from factory.augment.stage import check_physics
from factory.config import FactoryConfig
from factory.scenes.brain import AgentConfig, generate_scene
from factory.scenes.footprint import Footprint, overlaps
from factory.scenes.placement import SceneState
from factory.schema import Euler, Vec3, scene_to_json
from factory.sim.compile import compile_scene
from factory.sim.validate import validate_scene

TASK = "a kitchen where the robot picks up the mug and puts it in the bowl"


@pytest.fixture(scope="module")
def kitchen(tmp_path_factory: pytest.TempPathFactory):
    lib = AssetLibrary(tmp_path_factory.mktemp("batched") / "assets")
    scene, _ = generate_scene(TASK, lib, seed=2, config=AgentConfig(max_objects=14))
    return scene, lib


def test_rects_overlap_matches_footprints() -> None:
    rng = np.random.default_rng(0)
    a = np.column_stack(
        [rng.uniform(-1, 1, (400, 2)), rng.uniform(0.05, 0.6, (400, 2)), rng.uniform(-4, 4, 400)]
    )
    b = np.column_stack(
        [rng.uniform(-1, 1, (400, 2)), rng.uniform(0.05, 0.6, (400, 2)), rng.uniform(-4, 4, 400)]
    )
    for margin in (0.0, 0.05):
        got = rects_overlap(a, b, margin)
        want = [
            overlaps(Footprint(*ra[:4], ra[4]), Footprint(*rb[:4], rb[4]), margin)
            for ra, rb in zip(a, b)
        ]
        assert got.tolist() == want
        assert 0 < got.sum() < len(a)  # both outcomes are exercised


def test_distinct_selection() -> None:
    d = Distinctness(min_distance=0.05, min_yaw_deg=20.0)
    base = np.zeros((1, 2, 4))
    near = base.copy()
    near[0, 0, :2] = 0.01  # 1.4 cm: not distinct
    turned = base.copy()
    turned[0, 1, 3] = 359.0 - 360.0 * 2  # -361 deg = -1 deg: not distinct
    far = base.copy()
    far[0, 1, 0] = 0.2
    yawed = base.copy()
    yawed[0, 0, 3] = 170.0
    cands = np.concatenate([near, turned, far, far, yawed])
    assert d.select(cands, base, 10).tolist() == [2, 4]
    assert d.select(cands, base, 1).tolist() == [2]


def test_samples_fit_and_are_footprint_free(kitchen) -> None:
    scene, lib = kitchen
    ids = [o.id for o in scene.objects if o.task_role]
    state = SceneState(scene, lib, 0)
    for o in scene.objects:
        state.metas[o.id], _ = state.meta_of(o)
    movers = movers_of(state, ids)
    s = sample(movers, 500, np.random.default_rng(1))
    assert s.free.sum() > 100
    for i in np.flatnonzero(s.free)[:60]:
        fps = []
        for j, m in enumerate(movers):
            x, y, z, yaw = s.pose[i, j]
            fp = Footprint(x, y, m.size[0] / 2, m.size[1] / 2, math.radians(yaw), z, z + m.size[2])
            surf = [f for f in m.surfaces if abs(f.z - z) < 1e-9]
            assert surf, "the pose is on a surface of the support"
            for k, rect in enumerate(m.obstacles):  # clear of what stays on the support
                z0, z1 = m.obstacle_z[k]
                assert not overlaps(fp, Footprint(*rect[:4], rect[4], z0, z1), 0.005)
            fps.append(fp)
        for a in range(len(fps)):
            for b in range(a + 1, len(fps)):
                assert not overlaps(fps[a], fps[b], 0.005)


def test_local_scene_keeps_support_chain(kitchen) -> None:
    scene, _ = kitchen
    ids = [o.id for o in scene.objects if o.task_role]
    local = local_scene(scene, ids)
    for oid in ids:
        assert oid in local.dynamic
        assert scene.object(oid).placement.support_id in local.dynamic
    for obj in scene.objects:  # what stands on a dynamic object is dynamic
        if obj.placement.kind == "on_top" and obj.placement.support_id in local.dynamic:
            assert obj.id in local.dynamic
    assert set(local.dynamic) | set(local.context) | set(local.absent) == {
        o.id for o in scene.objects
    }
    assert all(local.scene.object(o).is_static for o in local.context)
    assert all(not scene.object(o).physics.static for o in local.context)  # parent untouched


def test_rows_equal_the_variant_model(kitchen) -> None:
    """A row built for a configuration is the compiled variant's own qpos0, bit for bit."""
    scene, lib = kitchen
    ids = [o.id for o in scene.objects if o.task_role]
    batch = configurations(scene, lib, 5, 2, None)
    model = compile_scene(scene, lib.assets_dir).model
    rows = pose_rows(model, model.qpos0, batch.ids, batch.poses)
    for i in range(len(batch)):
        own = compile_scene(batch.variant(i).scene, lib.assets_dir).model
        assert np.array_equal(own.qpos0, rows[i])
    assert sorted(batch.ids) == sorted(ids)


def test_configurations_batch(kitchen) -> None:
    """CPU backend: the requested number of distinct variants, each passing the ordinary
    whole-scene check, deterministic for a seed."""
    scene, lib = kitchen
    before = scene_to_json(scene)
    check = PhysicsCheck(lib.assets_dir, backend="cpu")
    count = 6
    batch = configurations(scene, lib, 21, count, check)
    assert len(batch) == count
    assert scene_to_json(scene) == before  # the parent is not modified
    d = Distinctness()
    parent = np.array(
        [[[*scene.object(i).position.as_tuple(), scene.object(i).rotation.z] for i in batch.ids]]
    )
    for i in range(count):
        others = np.concatenate([parent, np.delete(batch.poses, i, axis=0)])
        assert d.differs(batch.poses[i], others).all()
    verdicts = verify_whole_scene(scene, batch.ids, batch.poses, check)
    cfg = FactoryConfig()
    cfg.validate.trimesh = False
    for i in range(count):
        v = batch.variant(i)
        assert v.params["level"] == "configuration"
        for oid in batch.ids:  # same object, asset and support; a new pose
            new, old = v.scene.object(oid), scene.object(oid)
            assert (new.asset.asset_id, new.placement.support_id) == (
                old.asset.asset_id,
                old.placement.support_id,
            )
        assert check_physics(v.scene, lib.assets_dir) is None
        _, report = validate_scene(v.scene, lib.assets_dir, cfg, "cpu")  # stage=validate's
        assert report["metrics"]["stability"]["unstable"] == []
        assert report["metrics"]["collision"]["colliding"] == []
        assert verdicts.ok[i]
    again = configurations(scene, lib, 21, count, check)
    assert np.array_equal(again.poses, batch.poses)
    assert scene_to_json(again.variant(3).scene) == scene_to_json(batch.variant(3).scene)
    other = configurations(scene, lib, 22, 2, check)
    assert not np.array_equal(other.poses, batch.poses[:2])


def test_whole_scene_verdicts_match_check_physics(kitchen) -> None:
    """The batched whole-scene check says what check_physics says, failures included."""
    scene, lib = kitchen
    check = PhysicsCheck(lib.assets_dir, backend="cpu")
    batch = configurations(scene, lib, 3, 2, None)
    poses = batch.poses.copy()
    poses[1, 0, 2] += 0.3  # dropped from 30 cm above its support: moves, fails
    poses = np.concatenate([poses, batch.poses[:1]])
    poses[2, 0, 2] -= 0.05  # 5 cm into its support: collides
    verdicts = verify_whole_scene(scene, batch.ids, poses, check)
    for i in range(len(poses)):
        v = copy.deepcopy(scene)
        for j, oid in enumerate(batch.ids):
            obj = v.object(oid)
            obj.position = Vec3(*(float(x) for x in poses[i, j, :3]))
            obj.rotation = Euler(0.0, 0.0, float(poses[i, j, 3]))
        ordinary = check_physics(v, lib.assets_dir)
        assert verdicts.ok[i] == (ordinary is None), (i, verdicts.reasons[i], ordinary)
    assert verdicts.ok.tolist()[1:] == [False, False]


def test_stage_configuration_batched(cli, tmp_path: Path, kitchen) -> None:
    """stage=augment with configuration alone: one batch per parent, the same variants for
    any shard layout, each passing the whole-scene check."""
    import shutil

    scene, lib = kitchen
    args = [
        "stage=augment",
        "augment.levels=[configuration]",
        "augment.variants_per_scene=3",
        "augment.render=false",
        "sim.backend=cpu",
    ]
    runs = []
    for name in ("one", "two"):
        run = tmp_path / name
        for sid in (scene.id, f"{scene.id}-b"):
            (run / "scenes" / sid).mkdir(parents=True)
            copy_ = copy.deepcopy(scene)
            copy_.id = sid
            (run / "scenes" / sid / "scene.json").write_text(scene_to_json(copy_))
        shutil.copytree(lib.assets_dir, run / "assets")
        runs.append(run)
    out = cli(*args, f"run_dir={runs[0]}")
    assert out.returncode == 0, out.stderr
    for k in range(2):
        env = {"SLURM_ARRAY_TASK_ID": str(k), "SLURM_ARRAY_TASK_COUNT": "2"}
        res = cli(*args, f"run_dir={runs[1]}", env=env)
        assert res.returncode == 0, res.stderr
    names = sorted(p.name for p in (runs[0] / "scenes").iterdir() if "__" in p.name)
    assert names == sorted(p.name for p in (runs[1] / "scenes").iterdir() if "__" in p.name)
    assert len(names) == 6, names
    for n in names:
        text = (runs[0] / "scenes" / n / "scene.json").read_text()
        assert text == (runs[1] / "scenes" / n / "scene.json").read_text()
        report = json.loads((runs[0] / "scenes" / n / "report.json").read_text())["augment"]
        assert report["levels"] == ["configuration"]
        assert report["applied"][0]["level"] == "configuration"
    manifest = json.loads((runs[0] / "manifest.json").read_text())
    assert manifest["stages"]["augment"]["shards"]["0-of-1"]["result"]["kept"] == 6
