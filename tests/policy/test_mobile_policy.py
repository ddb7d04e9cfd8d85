"""``stage=train`` on mobile pick-and-place datasets: the features map to the policy inputs
(base pose in the state, the sub-task one-hot, the base target in the action), a training
step runs and its samples equal lerobot's own; ``stage=eval`` rolls a mobile policy out in the
closed-loop mobile env (``factory.tasks.mobile_pick_place.env``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

pytest.importorskip("lerobot")
require_robot_models()

from factory.config import FactoryConfig, TrainConfig
from factory.context import StageContext
from factory.errors import PolicyError
from factory.store import RunStore, Shard
from factory.tasks.mobile_pick_place.dataset import ACTION_NAMES as MOBILE_ACTION_NAMES
from factory.tasks.mobile_pick_place.dataset import DONE_KEY, SUBTASK_KEY
from factory.tasks.mobile_pick_place.dataset import STATE_NAMES as MOBILE_STATE_NAMES
from factory.tasks.mobile_pick_place.dataset import meta as mobile_meta

TINY = {
    "diffusion": {
        "horizon": 8,
        "n_action_steps": 4,
        "down_dims": [16, 32],
        "diffusion_step_embed_dim": 16,
        "num_inference_steps": 3,
    }
}
FRAMES = 40
HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
"""A Panda arm posture inside its joint limits (rad)."""


def _episode(k: int) -> dict[str, np.ndarray]:
    """One episode's columns: the arm sweeps about a posture, the base drives 1 m and turns,
    the sub-tasks follow in order (a quarter of the frames each)."""
    t = np.linspace(0.0, 1.0, FRAMES)[:, None]
    arm = HOME + 0.2 * np.sin(2 * np.pi * t + k) * np.ones(7)
    grip = np.where(t < 0.5, 0.08, 0.02)
    base = np.concatenate([1.0 + t + 0.1 * k, 2.0 - 0.5 * t, 0.3 * t * (k + 1)], axis=1)
    state = np.concatenate([arm, grip, base], axis=1).astype(np.float32)
    action = np.concatenate([state[1:], state[-1:]]).astype(np.float32)
    ee = np.tile(np.array([0.5, 0.0, 0.6, 1.0, 0.0, 0.0, 0.0], np.float32), (FRAMES, 1))
    subtask = np.minimum((np.arange(FRAMES) * 4) // FRAMES, 3)
    done = np.r_[subtask[1:] != subtask[:-1], True]
    return {"state": state, "action": action, "ee": ee, "subtask": subtask, "done": done}


@pytest.fixture(scope="module")
def mobile_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A merged mobile dataset of 2 episodes x 40 frames, written by lerobot with the
    features of ``factory.tasks.mobile_pick_place.dataset`` (no cameras) and a mobile
    ``meta/factory.json``."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.dataset.features import scalar_buffer

    root = tmp_path_factory.mktemp("mobile") / "merged"
    feats: dict[str, Any] = {
        "observation.state": {"dtype": "float32", "shape": (11,), "names": MOBILE_STATE_NAMES},
        "observation.ee_pose": {"dtype": "float32", "shape": (7,), "names": None},
        "action": {"dtype": "float32", "shape": (11,), "names": MOBILE_ACTION_NAMES},
        SUBTASK_KEY: {"dtype": "int64", "shape": (1,), "names": None},
        DONE_KEY: {"dtype": "bool", "shape": (1,), "names": None},
    }
    ds = LeRobotDataset.create(
        repo_id="factory/demos", fps=10, features=feats, root=root, use_videos=False
    )
    for k in range(2):
        ep = _episode(k)
        for f in range(FRAMES):
            ds.add_frame(
                {
                    "observation.state": ep["state"][f],
                    "observation.ee_pose": ep["ee"][f],
                    "action": ep["action"][f],
                    SUBTASK_KEY: np.array([ep["subtask"][f]], np.int64),
                    DONE_KEY: np.array([ep["done"][f]], bool),
                    "task": "move the can to the desk",
                }
            )
        scalar_buffer(ds.episode_buffer, feats)
        ds.save_episode()
    ds.finalize()
    meta = {
        "schema_version": 3,
        "scenes": ["room_a"],
        "episodes": [
            {"episode_index": k, "scene_id": "room_a", "n_frames": FRAMES} for k in range(2)
        ],
        **mobile_meta(),
    }
    (root / "meta" / "factory.json").write_text(json.dumps(meta))
    return root


def _features(root: Path) -> dict[str, Any]:
    return dict(json.loads((root / "meta" / "info.json").read_text())["features"])


def test_mobile_features_map_to_policy_inputs(mobile_dataset: Path) -> None:
    """State: joints, gripper, tool pose (base frame) + base x, y, cos yaw, sin yaw (21); the
    sub-task as a one-hot (4); actions: tool pose + gripper + base target (13) or the 11 joint
    targets."""
    import torch

    from factory.policy.inputs import (
        MOBILE_CAMERAS,
        convert_observation,
        input_spec,
        model_actions,
        robot_features,
    )

    feats = _features(mobile_dataset)
    spec = input_spec("state", feats, "tool")
    assert spec.mobile and spec.cameras == () and spec.action_dim == 13
    assert spec.raw_features() == {
        "observation.state": [11],
        "observation.ee_pose": [7],
        SUBTASK_KEY: [1],
    }
    assert spec.model_features() == {
        "observation.state": [21],
        "observation.environment_state": [4],
    }
    assert input_spec("state", feats, "joint").action_dim == 11

    ep = _episode(0)
    obs = {
        "observation.state": ep["state"][:5],
        "observation.ee_pose": ep["ee"][:5],
        SUBTASK_KEY: np.array([0, 1, 2, 3, 3]),
    }
    model = convert_observation(spec, obs)
    state = model["observation.state"].numpy()
    assert state.shape == (5, 21)
    assert np.allclose(state[:, :17], robot_features(ep["state"][:5, :8]))
    assert np.array_equal(state[:, 17:19], ep["state"][:5, 8:10])  # base x, y as recorded
    yaw = ep["state"][:5, 10]
    assert np.allclose(state[:, 19:], np.stack([np.cos(yaw), np.sin(yaw)], 1), atol=1e-6)
    assert torch.equal(model["observation.environment_state"], torch.eye(4)[[0, 1, 2, 3, 3]])
    act = model_actions(ep["action"][:5], "tool")
    assert act.shape == (5, 13) and np.array_equal(act[:, 10:], ep["action"][:5, 8:])
    assert np.array_equal(model_actions(ep["action"][:5], "joint"), ep["action"][:5])
    with pytest.raises(PolicyError, match="sub-task indices"):
        convert_observation(spec, {**obs, SUBTASK_KEY: np.array([0, 1, 2, 3, 4])})

    # image inputs: the five cameras in order, one size for all of them
    cams = {
        f"observation.images.{c}": {"dtype": "video", "shape": [32, 32, 3]} for c in MOBILE_CAMERAS
    }
    rgb = input_spec("rgb", {**feats, **cams}, "tool")
    assert rgb.cameras == MOBILE_CAMERAS and rgb.image_size == (32, 32)
    assert rgb.model_features()["observation.images.fisheye_back"] == [3, 32, 32]
    assert rgb.model_features()["observation.state"] == [21]
    odd = {**cams, "observation.images.left": {"dtype": "video", "shape": [24, 32, 3]}}
    with pytest.raises(PolicyError, match=r"demos\.width equal to demos\.height"):
        input_spec("rgb", {**feats, **odd}, "tool")
    with pytest.raises(PolicyError, match=r"lacks observation\.depth\.left"):
        input_spec("rgbd", {**feats, **cams}, "tool")
    short = {**feats, "action": {"dtype": "float32", "shape": [8]}}
    with pytest.raises(PolicyError, match="action has 8 columns"):
        input_spec("state", short, "tool")


def test_mobile_policy_trains_and_its_samples_equal_lerobots_own(
    mobile_dataset: Path, tmp_path: Path
) -> None:
    """stage=train on the mobile dataset writes a lerobot checkpoint whose model reads the
    mobile features; the fast samples equal ``LeRobotDataset.__getitem__``'s, converted."""
    import torch

    from factory.policy.checkpoint import load_policy
    from factory.policy.inputs import convert_sample, input_spec
    from factory.policy.train import open_dataset, policy_config

    spec = input_spec("state", _features(mobile_dataset), "tool")
    cfg = policy_config(TrainConfig(options=TINY), spec, "cpu")
    base, trainset = open_dataset(mobile_dataset, spec, cfg, augment=False)
    for idx in [0, 9, FRAMES - 1, FRAMES, 2 * FRAMES - 1]:
        fast, slow = trainset[idx], convert_sample(spec, base[idx])
        assert set(fast) == set(slow), idx
        for k, v in slow.items():
            assert fast[k].shape == v.shape, (idx, k)
            assert torch.allclose(fast[k].float(), v.float(), atol=1e-5), (idx, k)
    assert fast["observation.environment_state"].shape == (2, 4)  # n_obs_steps x sub-tasks
    assert fast["action"].shape == (8, 13)

    run = tmp_path / "run"
    result = _train(run, mobile_dataset, "mobile", steps=3, batch_size=4, log_every=1)
    assert result["steps"] == 3 and np.isfinite(result["loss"])
    model_dir = Path(result["checkpoint"]) / "pretrained_model"
    config = json.loads((model_dir / "config.json").read_text())
    assert config["input_features"]["observation.state"]["shape"] == [21]
    assert config["input_features"]["observation.environment_state"]["shape"] == [4]
    assert config["output_features"]["action"]["shape"] == [13]
    loaded = load_policy(str(model_dir), run, "cpu")
    assert loaded.spec.mobile and SUBTASK_KEY in loaded.info.features


def test_mobile_base_action_is_relative_and_round_trips(mobile_dataset: Path) -> None:
    """A training sample's base action is the recorded world target relative to the base pose
    of the sample's current frame (in its base frame); turned back the way ``LoadedPolicy.act``
    does at execution (``base_absolute`` from the observed pose), it is the recorded target,
    which the env applies as is. The heading enters the state as cos/sin: a pose at yaw and at
    yaw + 2 pi (the unwrapped yaw of demos that turned the other way) looks the same, and so
    do their relative actions."""
    from factory.policy.inputs import (
        base_absolute,
        base_relative,
        input_spec,
        mobile_robot_features,
    )
    from factory.policy.train import open_dataset, policy_config

    spec = input_spec("state", _features(mobile_dataset), "tool")
    cfg = policy_config(TrainConfig(options=TINY), spec, "cpu")
    _, trainset = open_dataset(mobile_dataset, spec, cfg, augment=False)
    ep = _episode(1)  # the dataset's second episode
    for f in [0, 5, 20, FRAMES - 3]:
        sample = trainset[FRAMES + f]
        rel = sample["action"].numpy()[:, 10:]  # (horizon, 3)
        window = np.clip(f - 1 + np.arange(rel.shape[0]), 0, FRAMES - 1)  # frames f-1 ...
        want = base_relative(ep["action"][window, 8:], ep["state"][f, 8:])
        assert np.allclose(rel, want, atol=1e-5), f
        now = np.repeat(ep["state"][f : f + 1, 8:], len(rel), 0)
        back = base_absolute(rel, now)
        assert np.allclose(back, ep["action"][window, 8:], atol=1e-5), f
    assert np.abs(rel[:, :2]).max() < 0.2  # a window's motion, not the room's coordinates

    state = ep["state"][:3].copy()
    turned = state.copy()
    turned[:, 10] -= 2 * np.pi
    assert np.allclose(mobile_robot_features(state), mobile_robot_features(turned), atol=1e-5)
    target = ep["action"][:3, None, 8:]
    shifted = target.copy()
    shifted[..., 2] -= 2 * np.pi
    assert np.allclose(
        base_relative(target, state[:, 8:]), base_relative(shifted, turned[:, 8:]), atol=1e-5
    )


def test_overfit_mobile_policy_acts_as_recorded(mobile_dataset: Path, tmp_path: Path) -> None:
    """A small state policy overfit on the two episodes, fed a training episode's recorded
    observations one frame at a time through ``LoadedPolicy.act`` (the env's path: model
    output -> joint and world base targets), predicts actions close to the recorded ones: the
    training's conversions (tool pose, base target relative to the chunk's first frame) and
    the execution's inverses agree, chunk after chunk."""
    from factory.policy.checkpoint import load_policy

    run = tmp_path / "run"
    options = {"diffusion": {**TINY["diffusion"], "down_dims": [32, 64]}}
    _train(run, mobile_dataset, "overfit", steps=400, batch_size=16, log_every=100, options=options)
    policy = load_policy("overfit", run, "cpu")
    ep = _episode(0)
    policy.reset()
    pred = np.stack(
        [
            policy.act(
                {
                    "observation.state": ep["state"][f : f + 1],
                    "observation.ee_pose": ep["ee"][f : f + 1],
                    SUBTASK_KEY: ep["subtask"][f : f + 1, None],
                }
            )[0]
            for f in range(FRAMES)
        ]
    )
    base_err = np.linalg.norm(pred[:, 8:10] - ep["action"][:, 8:10], axis=1)
    # the base drives 1 m over the episode (2.5 cm a frame); a wrong origin or frame is off
    # by the chunk's motion or the room's coordinates
    assert base_err.mean() < 0.03 and base_err.max() < 0.1, base_err
    assert np.abs(pred[:, 10] - ep["action"][:, 10]).mean() < 0.03
    assert np.abs(pred[:, :7] - ep["action"][:, :7]).mean() < 0.08  # arm joints (rad)


def _train(
    run: Path,
    dataset: Path,
    name: str,
    steps: int,
    batch_size: int,
    log_every: int,
    options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Trains policy ``name`` on ``dataset`` in a new run directory ``run`` (CPU, one thread,
    one checkpoint at the end; ``options`` default to the tiny model's) through ``stage=train``;
    its result."""
    from factory.policy.train_stage import run as train_stage

    run.mkdir()
    tc = TrainConfig(
        name=name,
        dataset=str(dataset),
        steps=steps,
        batch_size=batch_size,
        save_every=steps,
        log_every=log_every,
        threads=1,
        device="cpu",
        options=options or TINY,
    )
    ctx = StageContext(
        FactoryConfig(stage="train", run_dir=str(run), train=tc), RunStore(run), Shard(0, 1)
    )
    return train_stage(ctx)


def _ctx(run: Path, stage: str, **kw: Any) -> StageContext:
    return StageContext(
        FactoryConfig(stage=stage, run_dir=str(run), task="mobile_pick_place", **kw),
        RunStore(run),
        Shard(0, 1),
    )


def test_mobile_eval_stage_end_to_end(tmp_path: Path) -> None:
    """stage=demos -> dataset -> eval (replay) -> train (3 steps) -> eval (the policy) on the
    hand-built living room, in this process: the replay succeeds in the closed-loop mobile
    env, the tiny policy is rolled out and reported like a fixed-base one, with per-sub-task
    results and a video of the five cameras."""
    for mod in ("ruckig", "ompl", "mink"):
        pytest.importorskip(mod)
    import importlib.util

    from factory.config import DemosConfig, EvalConfig
    from factory.runner import run_stage
    from factory.schema import scene_to_json

    path = Path(__file__).resolve().parents[1] / "demos" / "test_mobile_pick_place.py"
    spec = importlib.util.spec_from_file_location("_mobile_helpers", path)
    assert spec is not None and spec.loader is not None
    helpers = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(helpers)
    scene = helpers._living_room()
    run = tmp_path / "run"
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    dc = DemosConfig(episodes_per_scene=1, fps=5.0, width=16, height=16, render=False, workers=1)
    assert run_stage("demos", _ctx(run, "demos", demos=dc))["episodes_stored"] == 1
    run_stage("dataset", _ctx(run, "dataset", demos=dc))

    ec = EvalConfig(policy="replay", videos=0)
    replay = run_stage("eval", _ctx(run, "eval", demos=dc, eval=ec))
    assert replay["success_rate"] == 1.0 and replay["episodes"] == 1, replay
    results = json.loads((run / "eval" / "replay" / "results.json").read_text())
    assert results["task"] == "mobile_pick_place"
    assert [v["completed"] for v in results["per_subtask"].values()] == [1, 1, 1, 1]

    tc = TrainConfig(
        name="tiny", steps=3, batch_size=4, save_every=3, threads=1, device="cpu", options=TINY
    )
    run_stage("train", _ctx(run, "train", demos=dc, train=tc))
    ec = EvalConfig(
        policy="tiny", scenes="train", episodes_per_scene=1, max_steps=6, videos=1, device="cpu"
    )
    out = run_stage("eval", _ctx(run, "eval", demos=dc, eval=ec))
    assert out["episodes"] == 1 and out["success_rate"] == 0.0
    results = json.loads((run / "eval" / "tiny" / "results.json").read_text())
    assert results["max_steps"] == 6 and set(results["per_subtask"]) == {
        "navigate_to_pick",
        "pick",
        "navigate_to_place",
        "place",
    }
    (reason,) = results["failures"]
    assert reason in ("nav_timeout", "base_collision", "collision"), results["failures"]
    (line,) = (run / "eval" / "tiny" / "episodes.jsonl").read_text().splitlines()
    record = json.loads(line)
    assert record["subtask"] == "navigate_to_pick" and record["subtasks_done"] == 0
    (video,) = (run / "eval" / "tiny" / "videos").glob("*.mp4")
    assert video.stat().st_size > 0


def _living_room_helpers() -> Any:
    """The living room of the demos' mobile tests (test folders are not packages)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "demos" / "test_mobile_pick_place.py"
    spec = importlib.util.spec_from_file_location("_mobile_helpers", path)
    assert spec is not None and spec.loader is not None
    helpers = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(helpers)
    return helpers


SEEN_DEMOS: dict[str, Any] = {
    "episodes_per_scene": 1,
    "fps": 5.0,
    "width": 32,
    "height": 32,  # the fisheye images are 32 square: one size for image policies
    "workers": 1,
}


@pytest.fixture(scope="module")
def seen_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run of the hand-built living room with one mobile demo recorded with the five cameras
    (RGB-D, 32 px) and exported: its dataset has ``observation.environment_state``."""
    for mod in ("ruckig", "ompl", "mink"):
        pytest.importorskip(mod)
    from factory.config import DemosConfig
    from factory.runner import run_stage
    from factory.schema import scene_to_json

    scene = _living_room_helpers()._living_room()
    run = tmp_path_factory.mktemp("mobile_seen") / "run"
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    dc = DemosConfig(**SEEN_DEMOS)
    assert run_stage("demos", _ctx(run, "demos", demos=dc))["episodes_stored"] == 1
    run_stage("dataset", _ctx(run, "dataset", demos=dc))
    return run


def test_mobile_object_values_are_in_the_arm_base_frame(seen_run: Path) -> None:
    """A mobile dataset's object poses become the fixed task's 24 model values in the frame
    of the arm's base (the Panda's link0, riding on the mobile base): at a few frames they
    equal the objects' positions in link0's frame of the recorded MuJoCo state; a state policy
    reads them before the sub-task one-hot (28), a dataset without them gives the one-hot
    alone and no auxiliary loss."""
    import mujoco

    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.payload import STATE_SPEC
    from factory.policy.inputs import ENV_DIM, env_features, input_spec
    from factory.policy.recipe import resolve_aux_state
    from factory.robots.mobile_panda import PREFIX
    from factory.tasks.mobile_pick_place import mobile_setup

    dataset = seen_run / "dataset" / "merged"
    feats = _features(dataset)
    spec = input_spec("state", feats)
    assert spec.mobile and spec.poses and spec.mobile_poses
    assert spec.raw_features()["observation.environment_state"] == [14]
    assert spec.model_features()["observation.environment_state"] == [ENV_DIM + 4]
    assert resolve_aux_state(None, "diffusion", "rgb", input_spec("rgb", feats).poses) == 1.0

    store = EpisodeStore(seen_run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    info, group = store.info(eid), store.arrays(eid)
    setup = mobile_setup(_living_room_helpers()._living_room())
    m = setup.model
    d = mujoco.MjData(m)
    link0 = m.body(f"{PREFIX}robot0_link0").id
    bodies = [m.body(info.pick_id).id, m.body(info.target_id).id]
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("factory/demos", root=dataset, video_backend="pyav")
    n = info.n_frames
    seen = []
    for f in sorted({0, n // 4, n // 2, 3 * n // 4, n - 1}):
        item = ds[f]
        state = item["observation.state"].numpy()[None]
        ee = item["observation.ee_pose"].numpy()[None]
        env = item["observation.environment_state"].numpy()[None]
        values = env_features(state, ee, env)[0]
        mujoco.mj_setState(m, d, np.asarray(group["state"][f], np.float64), STATE_SPEC)
        mujoco.mj_kinematics(m, d)
        rot = d.xmat[link0].reshape(3, 3)
        want = [rot.T @ (d.xpos[b] - d.xpos[link0]) for b in bodies]
        tool = rot.T @ (d.site_xpos[setup.robot.site] - d.xpos[link0])
        assert np.allclose(values[0:3], want[0], atol=2e-3), (f, values[0:3], want[0])
        assert np.allclose(values[9:12], want[1], atol=2e-3), (f, values[9:12], want[1])
        assert np.allclose(values[18:21], want[0] - tool, atol=2e-3)
        assert np.allclose(values[21:24], want[1] - tool, atol=2e-3)
        seen.append(want[1])
    # the desk stands still in the world but moves in the arm's frame as the base drives
    assert np.ptp(np.array(seen), axis=0).max() > 1.0

    old = {k: v for k, v in feats.items() if k != "observation.environment_state"}
    spec = input_spec("rgb", old)
    assert not spec.poses and not input_spec("state", old).mobile_poses
    assert resolve_aux_state(None, "diffusion", "rgb", spec.poses) == 0.0
    with pytest.raises(PolicyError, match="stage=dataset force=true"):
        input_spec("rgbd", old, perception=True)


def _train_seen(run: Path, name: str, **kw: Any) -> dict[str, Any]:
    """``stage=train`` of a tiny image policy (2 steps, batch 2, CPU) on ``seen_run``."""
    from factory.config import DemosConfig
    from factory.runner import run_stage

    tc = TrainConfig(
        name=name,
        steps=2,
        batch_size=2,
        save_every=2,
        log_every=1,
        threads=1,
        device="cpu",
        options={"diffusion": {**TINY["diffusion"], "spatial_softmax_num_keypoints": 4}},
        **kw,
    )
    return run_stage("train", _ctx(run, "train", demos=DemosConfig(**SEEN_DEMOS), train=tc))


def test_mobile_image_policy_trains_with_the_aux_state_loss(seen_run: Path) -> None:
    """``train.aux_state`` is on by default for a mobile image policy whose dataset records
    the object poses: two steps log a finite auxiliary loss."""
    out = _train_seen(seen_run, "aux", inputs="rgb")
    assert out["steps"] == 2
    log = seen_run / "policy" / "aux" / "train_log.jsonl"
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert lines and all(np.isfinite(r["aux_loss"]) for r in lines)


def test_mobile_perception_policy_trains_and_evaluates(
    seen_run: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``train.vision=perception`` on a mobile dataset: the network reads the five cameras
    (RGB-D; the wrist camera's pixels as points), the state policy reads the robot, the 24
    object values and the sub-task; ``stage=eval task=mobile_pick_place`` rolls it out with
    the network's predictions, the env never computing the objects' poses."""
    from factory.config import DemosConfig, EvalConfig
    from factory.policy.checkpoint import load_policy
    from factory.runner import run_stage
    from factory.tasks.mobile_pick_place import env as mobile_env

    out = _train_seen(seen_run, "seen", inputs="rgbd", vision="perception")
    assert out["steps"] == 2
    log = seen_run / "policy" / "seen" / "train_log.jsonl"
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert all(np.isfinite(r["perception_cm"]) for r in lines)
    policy = load_policy("seen", seen_run, device="cpu")
    assert policy.perception is not None and policy.perception.point_cameras == ["wrist"]
    assert len(policy.perception.cameras) == 5
    assert "observation.environment_state" not in policy.info.features
    assert policy.info.policy_features["observation.environment_state"] == [28]

    def no_poses(*args: Any) -> Any:
        raise AssertionError("the env computed the objects' poses for a perception policy")

    monkeypatch.setattr(mobile_env, "object_poses", no_poses)
    ec = EvalConfig(
        policy="seen", scenes="train", episodes_per_scene=1, max_steps=3, videos=0, device="cpu"
    )
    dc = DemosConfig(**SEEN_DEMOS)
    result = run_stage("eval", _ctx(seen_run, "eval", demos=dc, eval=ec))
    assert result["episodes"] == 1 and result["success_rate"] == 0.0


def test_mobile_and_fixed_do_not_mix() -> None:
    """An evaluation is mobile by its task, dataset or policy; a fixed-base policy on a mobile
    dataset (or the reverse) is refused in one line."""
    from factory.policy.eval_task import evaluated_task

    def task(*args: Any) -> str:
        return evaluated_task(*args).name

    mobile = {"layout": "mobile"}
    fixed = {"schema_version": 3}
    assert task("mobile_pick_place", None) == "mobile_pick_place"
    assert task("pick_place", mobile) == "mobile_pick_place"
    assert task("pick_place", mobile, {SUBTASK_KEY: [1]}) == "mobile_pick_place"
    assert task("pick_place", None, {SUBTASK_KEY: [1]}) == "mobile_pick_place"
    assert task("pick_place", fixed, {"observation.state": [8]}) == "pick_place"
    assert task("pick_place", None) == "pick_place"
    with pytest.raises(PolicyError, match="trained on a fixed-base dataset, but the evalu"):
        evaluated_task("pick_place", mobile, {"observation.state": [8]})
    with pytest.raises(PolicyError, match="trained on a mobile dataset, but the evaluation's "):
        evaluated_task("pick_place", fixed, {SUBTASK_KEY: [1]})
    with pytest.raises(
        PolicyError,
        match=r"^task=mobile_pick_place is the mobile task, but the policy is of the fixed-base "
        r"robot: evaluate it with task=pick_place, or train a policy on a mobile dataset$",
    ):
        evaluated_task("mobile_pick_place", None, {"observation.state": [8]})
    with pytest.raises(PolicyError, match="mobile task, but the dataset is of the fixed-base"):
        evaluated_task("mobile_pick_place", fixed, None)


def test_a_policy_s_task_is_its_dataset_s_layout() -> None:
    """A policy records its dataset's layout, which names its task even where two tasks' policies
    read the same features (``task=open`` and ``task=close``); a mismatch names both tasks."""
    from factory.policy.eval_task import evaluated_task

    feats = {"observation.state": [8], "observation.environment_state": [11]}
    opened = {"layout": "articulated_open"}
    assert evaluated_task("pick_place", None, feats, "articulated_open").name == "open"
    assert evaluated_task("open", opened, feats, "articulated_open").name == "open"
    assert evaluated_task("pick_place", opened, None).name == "open"
    with pytest.raises(PolicyError, match=r"^task=close was asked for, but the policy is of "):
        evaluated_task("close", None, feats, "articulated_open")
    with pytest.raises(PolicyError, match="trained on a task=close dataset, but the evaluation"):
        evaluated_task("open", opened, feats, "articulated_close")
