"""LeRobot export of mobile pick-and-place episodes, and the refusal to mix them with fixed ones."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

pytest.importorskip("lerobot")

from factory.dataset.layout import one_meta_layout
from factory.demos.record.episodes import EpisodeStore
from factory.errors import MixedLayoutError
from factory.store import Shard
from factory.tasks.mobile_pick_place.dataset import ACTION_NAMES, STATE_NAMES
from factory.tasks.pick_place.dataset import ENV_STATE_NAMES as FIXED_ENV_NAMES

CAMERAS = ["left", "right", "wrist", "fisheye_front", "fisheye_back"]
HERE = Path(__file__).resolve().parent


def _module(path: Path, name: str) -> ModuleType:
    """Another test module's helpers (test folders are not packages)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_mobile_episode_exports(cli, tmp_path: Path) -> None:
    """A recorded mobile episode -> stage=dataset -> LeRobotDataset with five cameras, the base
    pose in the state, 11 action columns, sub-task labels and done flags, and the objects' world
    poses as the fixed task's ``observation.environment_state`` (equal to the bodies' poses of
    the recorded MuJoCo states, and to what stores recorded before the ``env_state`` array
    export); the card names them."""
    require_robot_models()
    for mod in ("ruckig", "ompl", "mink"):
        pytest.importorskip(mod)
    from huggingface_hub import DatasetCard
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset.lerobot_export import unpack_depth_mm
    from factory.schema import scene_to_json
    from factory.tasks.mobile_pick_place import SUBTASKS

    helpers = _module(HERE.parent / "demos" / "test_mobile_pick_place.py", "_mobile_helpers")
    scene = helpers._living_room()
    run = tmp_path / "run"
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    out = cli(
        "stage=demos",
        f"run_dir={run}",
        "task=mobile_pick_place",
        "demos.episodes_per_scene=1",
        "demos.width=32",
        "demos.height=24",  # the fisheye images are 32 square: per-camera sizes
        "demos.fps=5",
        "demos.workers=1",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    out = cli("stage=dataset", f"run_dir={run}")
    assert out.returncode == 0, out.stderr[-3000:]

    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    group = store.arrays(eid)
    n = store.info(eid).n_frames
    merged = run / "dataset" / "merged"
    meta = json.loads((merged / "meta" / "factory.json").read_text())
    assert meta["layout"] == "mobile" and meta["subtasks"] == list(SUBTASKS)
    assert meta["state_names"] == STATE_NAMES and meta["action_names"] == ACTION_NAMES
    info = json.loads((merged / "meta" / "info.json").read_text())
    assert info["robot_type"] == "franka_panda_omron"
    feats = info["features"]
    assert feats["observation.environment_state"]["names"] == FIXED_ENV_NAMES
    assert feats["observation.state"]["names"] == STATE_NAMES
    assert feats["action"]["names"] == ACTION_NAMES
    assert feats["subtask_index"]["dtype"] == "int64" and feats["subtask_done"]["dtype"] == "bool"

    ds = LeRobotDataset("factory/demos", root=merged, video_backend="pyav")
    assert ds.num_episodes == 1 and ds.num_frames == n and ds.fps == 5
    assert sorted(k for k in ds.meta.camera_keys if ".images." in k) == sorted(
        f"observation.images.{c}" for c in CAMERAS
    )
    assert sorted(k for k in ds.meta.camera_keys if ".depth." in k) == sorted(
        f"observation.depth.{c}" for c in CAMERAS
    )
    subtask, done = [], []
    for f in range(n):
        item = ds[f]
        state, action = item["observation.state"].numpy(), item["action"].numpy()
        assert state.shape == (11,) and action.shape == (11,)
        expect = np.concatenate([group["joint_pos"][f], group["gripper"][f], group["base_pose"][f]])
        assert np.array_equal(state, expect)
        assert np.array_equal(action, group["action"][f])
        subtask.append(int(item["subtask_index"]))
        done.append(bool(item["subtask_done"]))
        for cam in CAMERAS:
            h, w = (32, 32) if cam.startswith("fisheye") else (24, 32)
            assert tuple(item[f"observation.images.{cam}"].shape) == (3, h, w)
        if f == n // 2:
            for cam in CAMERAS:  # depth survives exactly, fisheye included
                depth = unpack_depth_mm(item[f"observation.depth.{cam}"])
                assert np.array_equal(depth, group[f"depth/{cam}"][f]), cam
    assert subtask == group["subtask"][:].tolist() and done == group["subtask_done"][:].tolist()
    _check_object_poses(ds, store, eid, scene, run)
    # the sub-tasks in order, each with one done flag on its last frame
    assert (np.diff(subtask) >= 0).all() and sorted(set(subtask)) == list(range(len(SUBTASKS)))
    ends = np.flatnonzero(done)
    assert [subtask[e] for e in ends] == list(range(len(SUBTASKS))) and ends[-1] == n - 1
    assert all(subtask[e + 1] == subtask[e] + 1 for e in ends[:-1])

    from factory.dataset import episode_routes

    route = episode_routes(ds.root)[0]  # the route check's poses the episode drove to
    assert route == store.info(eid).route and len(route["pick_pose"]) == 3
    assert route["pick_index"] >= 0 and route["place_index"] >= 0 and not route["reason"]
    card = DatasetCard.load(merged / "README.md")
    assert "mobile-manipulation" in card.data.tags
    for name in SUBTASKS:
        assert f"`{name}`" in card.text
    assert "0 = `navigate_to_pick`" in card.text and "`subtask_done`" in card.text
    assert "`base_x`, `base_y`, `base_yaw`" in card.text and "`fisheye_back`" in card.text
    assert "`observation.environment_state`:** the pick object's position" in card.text


def _check_object_poses(ds: Any, store: EpisodeStore, eid: str, scene: Any, run: Path) -> None:
    """The exported environment state at a few frames is the pick object's and the place
    support's body poses in the scene's model set to the recorded MuJoCo state; the export of
    a store without the ``env_state`` array (recorded before it) reads the same from the
    states."""
    import mujoco

    from factory.demos.record.payload import STATE_SPEC
    from factory.tasks.mobile_pick_place import mobile_setup
    from factory.tasks.mobile_pick_place.dataset import columns

    info, group = store.info(eid), store.arrays(eid)
    setup = mobile_setup(scene)
    m = setup.model
    d = mujoco.MjData(m)
    bodies = [m.body(info.pick_id).id, m.body(info.target_id).id]
    assert info.target_id == setup.objects.place_support.id
    n = info.n_frames
    for f in sorted({0, n // 3, n // 2, n - 1}):
        mujoco.mj_setState(m, d, np.asarray(group["state"][f], np.float64), STATE_SPEC)
        mujoco.mj_kinematics(m, d)
        want = np.concatenate([np.r_[d.xpos[b], d.xquat[b]] for b in bodies])
        got = ds[f]["observation.environment_state"].numpy()
        assert np.allclose(got, want, atol=1e-5), (f, got, want)
    # the objects moved: the can from the table onto the desk
    first, last = (ds[f]["observation.environment_state"].numpy() for f in (0, n - 1))
    assert np.linalg.norm(first[:2] - last[:2]) > 1.0
    assert np.allclose(first[7:], last[7:], atol=1e-3)
    keys = ("state", "joint_pos", "gripper", "ee_pose", "action", "base_pose", "subtask")
    old = {k: group[k] for k in (*keys, "subtask_done")}  # no env_state
    scene_json = (run / "scenes" / scene.id / "scene.json").read_bytes()
    recorded = np.asarray(group["env_state"][:], np.float32)
    assert np.allclose(columns(info, old, scene_json)["observation.environment_state"], recorded)


def test_mixed_layouts_refused(tmp_path: Path) -> None:
    """Fixed-base and mobile episodes in one store, or shards of both, are refused with the
    fix; nothing is written."""
    from factory.dataset.lerobot_export import export_store

    fixed = _module(HERE / "test_dataset.py", "_fixed_helpers")
    store = fixed._run(tmp_path, shards=1, per_shard=1)
    ep = EpisodeStore(store.episodes_shard(Shard(0, 1)))
    info, arrays = fixed._episode("kitchen_pick_place-ep99", "kitchen_pick_place", 6, 1)
    n = info.n_frames
    del arrays["env_state"]
    arrays["action"] = np.zeros((n, 11), np.float32)
    arrays["base_pose"] = np.zeros((n, 3), np.float32)
    arrays["subtask"] = np.zeros(n, np.int8)
    arrays["subtask_done"] = np.zeros(n, bool)
    ep.write(replace(info, task="mobile_pick_place"), arrays)
    with pytest.raises(MixedLayoutError, match="in its own run_dir") as e:
        export_store(ep, tmp_path / "out", "x/out", store.root)
    assert "kitchen_pick_place-ep00" in str(e.value) and "kitchen_pick_place-ep99" in str(e.value)
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".tmp-out-*"))
    with pytest.raises(MixedLayoutError, match="cannot be merged"):
        one_meta_layout([{}, {"layout": "mobile"}], ["a", "b"])
    assert one_meta_layout([{}, {}], ["a", "b"]) == "fixed"


def _mobile_episode(fixed: ModuleType, eid: str, n: int, seed: int) -> tuple[Any, dict]:
    """A synthetic mobile episode (the fixed helper's images and arrays, the mobile columns)
    with a route like ``MobilePlanner.route_record``'s."""
    info, arrays = fixed._episode(eid, "kitchen_pick_place", n, seed)
    rng = np.random.default_rng(seed)
    arrays["action"] = rng.normal(size=(n, 11)).astype(np.float32)
    arrays["base_pose"] = rng.normal(size=(n, 3)).astype(np.float32)
    arrays["subtask"] = np.minimum(np.arange(n) * 4 // n, 3).astype(np.int8)
    arrays["subtask_done"] = np.r_[np.diff(arrays["subtask"]) != 0, True]
    route = {
        "pick_pose": [1.0 + seed, 1.5, 0.25 * seed],
        "place_pose": [3.25, 1.5 - seed, -1.5],
        "pick_index": seed,
        "place_index": 7,
        "reason": "",
        "pick_poses": 13,
        "place_poses": 167,
        "route_pick_poses": 12,
        "route_place_poses": 160,
        "resolution": 0.05,
        "headings": 32,
        "footprint_radius": 0.307,
        "carry_front": 0.4167,
    }
    return replace(info, task="mobile_pick_place", route=route), arrays


def test_mobile_route_exported_and_merged(tmp_path: Path) -> None:
    """Each mobile episode's route lands in its ``meta/factory.json`` entry, survives the shard
    merge re-indexed, reads back by the episode index of ``LeRobotDataset``'s frames, and is
    described on the card; a fixed dataset has none."""
    from huggingface_hub import DatasetCard
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset import episode_routes
    from factory.dataset.lerobot_export import export_store, merge_datasets
    from factory.errors import StoreError

    fixed = _module(HERE / "test_dataset.py", "_fixed_helpers")
    run = fixed._run(tmp_path, shards=1, per_shard=1)
    infos, shards = {}, []
    for k, (seed, n) in enumerate([(1, 8), (2, 6)]):  # one episode per shard
        store = EpisodeStore(tmp_path / f"mobile-{k}.zarr")
        info, arrays = _mobile_episode(fixed, f"kitchen_pick_place-ep{k}", n, seed)
        store.write(info, arrays)
        infos[info.episode_id] = (info, arrays)
        shard = tmp_path / "shards" / f"shard-{k}"
        export_store(store, shard, f"x/m-shard{k}", run.root)
        shards.append(shard)
    merged = tmp_path / "merged"
    merge_datasets(shards[::-1], merged, "x/m")  # shard 1 first: indices change in the merge

    ds = LeRobotDataset("x/m", root=merged, video_backend="pyav")
    routes = episode_routes(ds.root)
    meta = json.loads((merged / "meta" / "factory.json").read_text())
    assert sorted(routes) == [0, 1] == sorted(int(e) for e in ds.meta.episodes["episode_index"])
    for entry in meta["episodes"]:
        info, arrays = infos[entry["episode_id"]]
        route = routes[entry["episode_index"]]
        assert route == info.route
        # the index is the one of the dataset's frames: their base pose is this episode's
        start = int(ds.meta.episodes["dataset_from_index"][entry["episode_index"]])
        item = ds[start]
        assert int(item["episode_index"]) == entry["episode_index"]
        assert np.array_equal(item["observation.state"].numpy()[8:], arrays["base_pose"][0])
    assert routes[0]["pick_pose"] == [3.0, 1.5, 0.5]  # shard 1's episode (seed 2) came first
    card = DatasetCard.load(merged / "README.md")
    assert "**`route`**" in card.text and "`pick_pose` and `place_pose`" in card.text

    export_store(EpisodeStore(run.episodes_shard(Shard(0, 1))), tmp_path / "fixed", "x/f", run.root)
    with pytest.raises(StoreError, match="fixed-base episodes"):
        episode_routes(tmp_path / "fixed")
    old = json.loads((shards[0] / "meta" / "factory.json").read_text())
    del old["episodes"][0]["route"]
    (shards[0] / "meta" / "factory.json").write_text(json.dumps(old))
    with pytest.raises(StoreError, match="stage=dataset force=true"):
        episode_routes(shards[0])
