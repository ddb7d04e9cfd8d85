"""LeRobot export of mobile pick-and-place episodes, and the refusal to mix them with fixed ones."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

pytest.importorskip("lerobot")

from factory.dataset.mobile_features import (
    MOBILE_ACTION_NAMES,
    MOBILE_STATE_NAMES,
    MOBILE_SUBTASKS,
    one_meta_layout,
)
from factory.demos.episodes import EpisodeStore
from factory.errors import MixedLayoutError
from factory.store import Shard

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
    pose in the state, 11 action columns, sub-task labels and done flags; the card names them."""
    for mod in ("robosuite", "ruckig", "ompl", "mink"):
        pytest.importorskip(mod)
    from huggingface_hub import DatasetCard
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset.lerobot_export import unpack_depth_mm
    from factory.demos.mobile_pick_place import SUBTASKS
    from factory.schema import scene_to_json

    assert tuple(MOBILE_SUBTASKS) == tuple(SUBTASKS)  # the export's copy of the names
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
    assert meta["state_names"] == MOBILE_STATE_NAMES and meta["action_names"] == MOBILE_ACTION_NAMES
    info = json.loads((merged / "meta" / "info.json").read_text())
    assert info["robot_type"] == "franka_panda_omron"
    feats = info["features"]
    assert "observation.environment_state" not in feats
    assert feats["observation.state"]["names"] == MOBILE_STATE_NAMES
    assert feats["action"]["names"] == MOBILE_ACTION_NAMES
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
    # the sub-tasks in order, each with one done flag on its last frame
    assert (np.diff(subtask) >= 0).all() and sorted(set(subtask)) == list(range(len(SUBTASKS)))
    ends = np.flatnonzero(done)
    assert [subtask[e] for e in ends] == list(range(len(SUBTASKS))) and ends[-1] == n - 1
    assert all(subtask[e + 1] == subtask[e] + 1 for e in ends[:-1])

    card = DatasetCard.load(merged / "README.md")
    assert "mobile-manipulation" in card.data.tags
    for name in SUBTASKS:
        assert f"`{name}`" in card.text
    assert "0 = `navigate_to_pick`" in card.text and "`subtask_done`" in card.text
    assert "`base_x`, `base_y`, `base_yaw`" in card.text and "`fisheye_back`" in card.text
    assert "`observation.environment_state`:**" not in card.text


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
