"""LeRobot export and shard merge: round trip, errors, and a diffusion-policy training batch."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from factory.config import CompileConfig
from factory.demos.execute.cpu import STATE_SPEC
from factory.demos.record.episodes import EpisodeStore
from factory.scenes.build import compile_one
from factory.schema.episode import EpisodeInfo, RobotBase
from factory.store import RunStore, Shard

EXAMPLE_SCENE = (
    Path(__file__).resolve().parents[2] / "factory/data/examples/kitchen_pick_place/scene.json"
)
H = W = 32
CAMS = ["left", "wrist"]


def _episode(eid: str, scene_id: str, n: int, seed: int) -> tuple[EpisodeInfo, dict]:
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    yy, xx = np.mgrid[0:H, 0:W]
    rgb = {}
    for k, cam in enumerate(CAMS):
        # smooth images with a moving square: what a video codec keeps well
        frames = np.zeros((n, H, W, 3), np.uint8)
        for f in range(n):
            frames[f, ..., 0] = (4 * xx + 2 * f) % 256
            frames[f, ..., 1] = (4 * yy + 40 * k) % 256
            frames[f, ..., 2] = 128
            x0 = (f + 3 * k) % (W - 8)
            frames[f, 8:16, x0 : x0 + 8] = 255
        rgb[cam] = frames
    info = EpisodeInfo(
        episode_id=eid,
        scene_id=scene_id,
        task="pick_place",
        instruction="pick up the mug and put it in the bowl",
        seed=seed,
        success=True,
        failure_reason="",
        pick_id="mug",
        target_id="bowl",
        support_id="table",
        robot=RobotBase(1.0, 2.0, 0.75, 0.5),
        fps=20.0,
        timestep=0.002,
        n_frames=n,
        cameras=CAMS,
        image_size=[H, W],
        depth_format="uint16_mm",
        state_spec=int(STATE_SPEC),
        # the left camera's calibration: position (m) and rotation rows, base frame
        camera_poses={"left": [0.45, 0.01 * seed, 0.6, *np.eye(3).ravel().tolist()]},
        camera_fovy={"left": 50.0},
    )
    arrays = {
        "time": t / 20.0,
        "state": rng.normal(size=(n, 30)),
        "joint_pos": rng.normal(size=(n, 7)).astype(np.float32),
        "gripper": rng.uniform(0, 0.08, size=(n, 1)).astype(np.float32),
        "ee_pose": rng.normal(size=(n, 7)).astype(np.float32),
        "action": rng.normal(size=(n, 8)).astype(np.float32),
        "env_state": rng.normal(size=(n, 14)).astype(np.float32),
    }
    for cam in CAMS:
        arrays[f"rgb/{cam}"] = rgb[cam]
        arrays[f"depth/{cam}"] = rng.integers(300, 4000, size=(n, H, W)).astype(np.uint16)
    return info, arrays


def _run(tmp_path: Path, shards: int = 2, per_shard: int = 2, finished: bool = True) -> RunStore:
    store = RunStore(tmp_path / "run")
    scene_id = "kitchen_pick_place"
    (store.scenes_dir / scene_id).mkdir(parents=True)
    shutil.copyfile(EXAMPLE_SCENE, store.scene_json(scene_id))
    store.assets_dir.mkdir(parents=True, exist_ok=True)
    compile_one(store, scene_id, CompileConfig())  # scenes/<id>/model.xml, as the stages leave it
    for k in range(shards):
        ep = EpisodeStore(store.episodes_shard(Shard(k, shards)))
        for j in range(per_shard):
            info, arrays = _episode(f"{scene_id}-ep{k}{j}", scene_id, 24 + 3 * j, 10 * k + j)
            ep.write(info, arrays)
        status = "done" if finished or k == 0 else "running"
        store.record_stage("demos", Shard(k, shards), status, {})
    return store


def test_export_merge_round_trip(cli, tmp_path: Path) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset.lerobot_export import unpack_depth_mm

    store = _run(tmp_path)
    # each shard written by two processes: the round trip below checks the joined parts too
    out = cli("stage=dataset", f"run_dir={store.root}", "dataset.workers=2")
    assert out.returncode == 0, out.stderr[-3000:]
    merged = store.root / "dataset" / "merged"
    meta = json.loads((merged / "meta" / "factory.json").read_text())
    assert [e["episode_id"] for e in meta["episodes"]] == [
        "kitchen_pick_place-ep00",
        "kitchen_pick_place-ep01",
        "kitchen_pick_place-ep10",
        "kitchen_pick_place-ep11",
    ]
    assert meta["scenes"] == ["kitchen_pick_place"] and meta["factory_version"]
    from huggingface_hub import DatasetCard

    card = DatasetCard.load(merged / "README.md")
    assert {"LeRobot", "factory", "mujoco"} <= set(card.data.tags)
    assert f"by factory {meta['factory_version']}" in card.text
    assert (
        "4 (" in card.text
        and "`kitchen_pick_place`" in card.text
        and "Seeds:** 0 to 11" in card.text
    )
    assert '`pick_place`; instruction(s): "pick up the mug and put it in the bowl"' in card.text
    assert "mm = 256 * R + G" in card.text and '"total_episodes": 4' in card.text
    assert "**`observation.camera_poses`:** the calibration of the cameras placed" in card.text
    ds = LeRobotDataset("factory/demos", root=merged, video_backend="pyav")
    assert ds.num_episodes == 4 and ds.fps == 20
    index = 0
    worst_rgb = 0.0
    for e in meta["episodes"]:
        shard = int(e["episode_id"][-2])
        group = EpisodeStore(store.episodes_shard(Shard(shard, 2))).arrays(e["episode_id"])
        for f in range(e["n_frames"]):
            item = ds[index]
            index += 1
            state = np.concatenate([group["joint_pos"][f], group["gripper"][f]])
            assert np.array_equal(item["observation.state"].numpy(), state)
            assert np.array_equal(item["action"].numpy(), group["action"][f])
            env_state = item["observation.environment_state"].numpy()
            assert np.array_equal(env_state, group["env_state"][f])
            calib = item["observation.camera_poses"].numpy()  # the left camera's, 13 values
            seed = int(e["seed"])
            assert np.allclose(calib, [0.45, 0.01 * seed, 0.6, *np.eye(3).ravel(), 50.0])
            for cam in CAMS:
                depth = unpack_depth_mm(item[f"observation.depth.{cam}"])
                assert np.array_equal(depth, group[f"depth/{cam}"][f])  # exact millimetres
                img = (item[f"observation.images.{cam}"].numpy().transpose(1, 2, 0) * 255).round()
                err = np.abs(img - group[f"rgb/{cam}"][f].astype(float)).mean()
                worst_rgb = max(worst_rgb, err)
            assert item["task"] == "pick up the mug and put it in the bowl"
    assert worst_rgb < 6.0, worst_rgb  # video codec tolerance (mean abs error, 0-255)
    # extras: scene, robot placement and exact MuJoCo states per episode
    extra = merged / "extras" / "kitchen_pick_place-ep10"
    assert json.loads((extra / "scene.json").read_text())["id"] == "kitchen_pick_place"
    assert json.loads((extra / "robot.json").read_text())["base"]["yaw"] == 0.5
    import mujoco

    assert mujoco.MjModel.from_xml_path(str(extra / "model.xml")).nbody > 10  # loads as is
    states = np.load(extra / "states.npz")["state"]
    group = EpisodeStore(store.episodes_shard(Shard(1, 2))).arrays("kitchen_pick_place-ep10")
    assert np.array_equal(states, group["state"][:])
    # re-running redoes nothing but the merge
    again = cli("stage=dataset", f"run_dir={store.root}", "dataset.workers=2")
    assert again.returncode == 0
    result = json.loads((store.root / "manifest.json").read_text())["stages"]["dataset"]
    assert result["shards"]["0-of-1"]["result"]["exported"] == 0


def test_unfinished_or_missing_shard(cli, tmp_path: Path) -> None:
    store = _run(tmp_path, finished=False)
    out = cli("stage=dataset", f"run_dir={store.root}")
    assert out.returncode == 2 and "shard(s) {1: 'running'} of 2 have not finished" in out.stderr
    assert not (store.root / "dataset" / "merged").exists()
    store.record_stage("demos", Shard(1, 2), "done", {})
    shutil.rmtree(store.episodes_shard(Shard(1, 2)))
    out = cli("stage=dataset", f"run_dir={store.root}")
    assert out.returncode == 2 and "shard-1.zarr is missing" in out.stderr
    assert not (store.root / "dataset" / "merged").exists()


def test_per_shard_export_then_merge(cli, tmp_path: Path) -> None:
    """An array task exports only its shard; the merge exports just what is missing."""
    store = _run(tmp_path)
    run = f"run_dir={store.root}"
    # two processes write the shard's two episodes, joined into one dataset
    out = cli("stage=dataset", run, "shard.index=1", "shard.count=2", "dataset.workers=2")
    assert out.returncode == 0, out.stderr[-3000:]
    assert "2 process(es)" in out.stderr
    shards = store.root / "dataset" / "shards"
    assert [p.name for p in shards.iterdir()] == ["shard-1"]  # no parts left behind
    meta = json.loads((shards / "shard-1" / "meta" / "factory.json").read_text())
    assert meta["parts"] == 2 and meta["digest"]
    assert [e["episode_id"] for e in meta["episodes"]] == [
        "kitchen_pick_place-ep10",
        "kitchen_pick_place-ep11",
    ]
    assert [e["episode_index"] for e in meta["episodes"]] == [0, 1]
    assert not (store.root / "dataset" / "merged").exists()
    out = cli("stage=dataset", run, "shard.index=0", "shard.count=3")
    assert out.returncode == 2 and "stage=demos ran as 2 shard(s)" in out.stderr
    out = cli("stage=dataset", run, "dataset.crf=99")
    assert out.returncode == 2 and "dataset.crf must be in 0..63" in out.stderr
    out = cli("stage=dataset", run, "dataset.preset=quick")
    assert out.returncode == 2 and "dataset.preset must be one of ultrafast" in out.stderr
    out = cli("stage=dataset", run, "dataset.workers=0")
    assert out.returncode == 2 and "dataset.workers must be >= 1" in out.stderr
    out = cli("stage=dataset", run)
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads((store.root / "manifest.json").read_text())["stages"]["dataset"]
    summary = result["shards"]["0-of-1"]["result"]
    assert summary["exported"] == 1 and summary["shards"] == 2 and summary["episodes"] == 4
    assert summary["export_frames"] == 24 + 27  # shard 0's two episodes
    assert summary["export_seconds"] > 0 and summary["merge_seconds"] > 0
    # another codec setting re-exports both shards
    out = cli("stage=dataset", run, "dataset.crf=30")
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads((store.root / "manifest.json").read_text())["stages"]["dataset"]
    assert result["shards"]["0-of-1"]["result"]["exported"] == 2


def _small_disk_or_skip(mnt: Path) -> list[str]:
    """The command prefix that runs a shell in a private mount namespace (user namespaces: no
    root needed); skips where the kernel does not allow them."""
    import subprocess

    prefix = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c"]
    probe = f"mount -t tmpfs -o size=64k tmpfs {mnt}"
    if shutil.which("unshare") is None or subprocess.run([*prefix, probe]).returncode != 0:
        pytest.skip("no private mount namespace here to make a small file system")
    return prefix


def test_disk_full_then_resume(tmp_path: Path) -> None:
    """A real full disk (a 0.9 MB tmpfs: room for one of the two shards) stops the export with
    a clear error; the finished shard stays, nothing half-written does, and a re-run with room
    exports only the missing shard and merges."""
    import subprocess
    import sys

    store = _run(tmp_path)
    out = tmp_path / "small"
    out.mkdir()
    prefix = _small_disk_or_skip(out)
    cmd = f"{sys.executable} -m factory stage=dataset run_dir={store.root} dataset.out={out}"
    script = f"""
        mount -t tmpfs -o size=900k tmpfs {out} || exit 90
        {cmd} 2> {tmp_path}/first.err; echo "first=$?"
        ls -A {out} {out}/shards
        mount -o remount,size=8m {out} || exit 91
        {cmd} 2> {tmp_path}/second.err; echo "second=$?"
        ls -A {out} {out}/shards
        cat {out}/merged/meta/factory.json
    """
    run = subprocess.run([*prefix, script], capture_output=True, text=True, timeout=600)
    first_err = (tmp_path / "first.err").read_text()
    assert "first=2" in run.stdout, first_err[-3000:]
    assert "No space left on device" in first_err and "free space there" in first_err
    assert "Traceback" not in first_err
    listings = run.stdout.split("second=")
    assert "shard-0" in listings[0] and "shard-1" not in listings[0] and ".tmp" not in listings[0]
    assert "merged" not in listings[0]
    assert listings[1].startswith("0"), (tmp_path / "second.err").read_text()[-3000:]
    assert "exporting shard 1-of-2" in (tmp_path / "second.err").read_text()
    assert "exporting shard 0-of-2" not in (tmp_path / "second.err").read_text()
    merged = json.loads(listings[1][listings[1].index("{") :])
    assert len(merged["episodes"]) == 4 and ".tmp" not in listings[1]


def test_killed_writer_then_rerun(cli, tmp_path: Path) -> None:
    """SIGKILL in the middle of an export leaves only a hidden temporary folder; the re-run
    removes it and publishes the whole dataset."""
    import os
    import signal
    import subprocess
    import sys
    import time

    store = _run(tmp_path, shards=1, per_shard=6)
    shards = store.root / "dataset" / "shards"
    proc = subprocess.Popen(
        [sys.executable, "-m", "factory", "stage=dataset", f"run_dir={store.root}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while not list(shards.glob(".tmp-shard-0-*/meta")) and time.monotonic() < deadline:
        assert proc.poll() is None, "the export ended before it could be killed"
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert list(shards.glob(".tmp-shard-0-*")) and not (shards / "shard-0").exists()
    assert not (store.root / "dataset" / "merged").exists()
    manifest = json.loads((store.root / "manifest.json").read_text())
    assert manifest["stages"]["dataset"]["shards"]["0-of-1"]["status"] == "running"
    rerun = cli("stage=dataset", f"run_dir={store.root}")
    assert rerun.returncode == 0, rerun.stderr[-3000:]
    assert "left by an interrupted export" in rerun.stderr
    assert [p.name for p in shards.iterdir()] == ["shard-0"]
    merged = json.loads((store.root / "dataset/merged/meta/factory.json").read_text())
    assert len(merged["episodes"]) == 6


def test_duplicate_episode_and_bad_shape(tmp_path: Path) -> None:
    from factory.dataset.lerobot_export import export_store, merge_datasets
    from factory.errors import StoreError

    store = _run(tmp_path, shards=1, per_shard=1)
    ep = EpisodeStore(store.episodes_shard(Shard(0, 1)))
    a = export_store(ep, tmp_path / "a", "x/a", store.root)
    assert a["episodes"][0]["episode_id"] == "kitchen_pick_place-ep00"
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    with pytest.raises(StoreError, match="in two shards"):
        merge_datasets([tmp_path / "a", tmp_path / "b"], tmp_path / "m", "x/m")
    assert not (tmp_path / "m").exists()
    # an episode whose arrays have the wrong shape
    bad = EpisodeStore(tmp_path / "bad.zarr")
    info, arrays = _episode("s-ep0", "kitchen_pick_place", 10, 0)
    arrays["action"] = np.zeros((10, 6), np.float32)
    bad.write(info, arrays)
    with pytest.raises(StoreError, match="'action' has shape"):
        export_store(bad, tmp_path / "c", "x/c", store.root)
    assert not (tmp_path / "c").exists() and not list(tmp_path.glob(".tmp-c-*"))


def test_diffusion_policy_trains_on_export(tmp_path: Path) -> None:
    import torch
    from lerobot.configs.types import FeatureType
    from lerobot.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata
    from lerobot.datasets.utils import dataset_to_policy_features
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy
    from lerobot.policies.diffusion.processor_diffusion import make_diffusion_pre_post_processors

    from factory.dataset.lerobot_export import export_store

    store = _run(tmp_path, shards=1, per_shard=2)
    root = tmp_path / "ds"
    export_store(EpisodeStore(store.episodes_shard(Shard(0, 1))), root, "x/ds", store.root)
    meta = LeRobotDatasetMetadata("x/ds", root=root)
    feats = dataset_to_policy_features(meta.features)
    inputs = {
        k: f
        for k, f in feats.items()
        if k == "observation.state" or k.startswith("observation.images.")
    }
    assert all(f.type is FeatureType.VISUAL for k, f in inputs.items() if "images" in k)
    outputs = {k: f for k, f in feats.items() if f.type is FeatureType.ACTION}
    cfg = DiffusionConfig(
        input_features=inputs,
        output_features=outputs,
        n_obs_steps=2,
        horizon=8,
        n_action_steps=4,
        down_dims=(32, 64),
        crop_shape=None,
        num_train_timesteps=10,
        device="cpu",
        pretrained_backbone_weights=None,
    )
    policy = DiffusionPolicy(cfg)
    pre, _ = make_diffusion_pre_post_processors(cfg, dataset_stats=meta.stats)
    obs = [i / meta.fps for i in cfg.observation_delta_indices]
    delta = {k: obs for k in inputs} | {"action": [i / meta.fps for i in cfg.action_delta_indices]}
    ds = LeRobotDataset("x/ds", root=root, delta_timestamps=delta, video_backend="pyav")
    batch = next(iter(torch.utils.data.DataLoader(ds, batch_size=4, shuffle=True)))
    assert batch["observation.images.left"].shape == (4, 2, 3, H, W)
    assert batch["action"].shape == (4, 8, 8)
    optim = torch.optim.Adam(policy.parameters(), lr=1e-4)
    loss, _ = policy.forward(pre(batch))
    loss.backward()
    optim.step()
    assert torch.isfinite(loss)


def test_environment_state_of_stores_recorded_before_it(tmp_path: Path) -> None:
    """Stores without ``env_state`` get it from the MuJoCo states (free-body qpos in scene
    order, without cleared objects); an episode whose states cannot hold it is refused."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset.lerobot_export import export_store
    from factory.errors import StoreError
    from factory.schema import load_scene

    store = _run(tmp_path, shards=1, per_shard=0)
    scene = load_scene(EXAMPLE_SCENE)
    movable = [o.id for o in scene.objects if not o.is_static]
    pick, target = "mug", "bowl"
    assert pick in movable and target in movable
    n = 6
    info, arrays = _episode("kitchen_pick_place-ep00", "kitchen_pick_place", n, 0)
    info = replace(info, pick_id=pick, target_id=target, cleared=[movable[0]])
    del arrays["env_state"]
    kept = [o for o in movable if o != movable[0]]
    state = np.zeros((n, 1 + 7 * len(kept) + 9))
    expect = np.zeros((n, 14))
    for j, oid in enumerate((pick, target)):
        adr = 1 + 7 * kept.index(oid)
        pos = np.arange(3) + 10 * j + np.arange(n)[:, None]
        quat = np.array([2.0, 0.0, 0.0, 2.0])  # not normalized in qpos: exported unit-length
        state[:, adr : adr + 3] = pos
        state[:, adr + 3 : adr + 7] = quat
        expect[:, 7 * j : 7 * j + 3] = pos
        expect[:, 7 * j + 3 : 7 * j + 7] = quat / np.linalg.norm(quat)
    arrays["state"] = state
    ep = EpisodeStore(store.episodes_shard(Shard(0, 1)))
    ep.write(info, arrays)
    export_store(ep, tmp_path / "out", "x/out", store.root)
    ds = LeRobotDataset("x/out", root=tmp_path / "out", video_backend="pyav")
    got = np.stack([ds[f]["observation.environment_state"].numpy() for f in range(n)])
    assert np.allclose(got, expect, atol=1e-6)
    # a pick object the states cannot hold (a static one) is refused with the fix
    bad = EpisodeStore(tmp_path / "bad.zarr")
    static = next(o.id for o in scene.objects if o.is_static)
    bad.write(replace(info, pick_id=static), arrays)
    with pytest.raises(StoreError, match="re-record it"):
        export_store(bad, tmp_path / "c", "x/c", store.root)
