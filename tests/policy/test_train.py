"""``stage=train``: lerobot policies trained on a real exported dataset, checkpoints in lerobot's
format, resuming, loading to act on env observations, and one-line errors on bad input."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

pytest.importorskip("lerobot")
if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()

from factory.config import FactoryConfig, TrainConfig
from factory.context import StageContext
from factory.errors import PolicyError
from factory.store import RunStore, Shard

REPO = Path(__file__).resolve().parents[2]
TINY: dict[str, Any] = {
    "diffusion": {
        "horizon": 8,
        "n_action_steps": 4,
        "down_dims": [16, 32],
        "diffusion_step_embed_dim": 16,
        "num_inference_steps": 3,
        "spatial_softmax_num_keypoints": 4,
    },
    "act": {
        "chunk_size": 8,
        "n_action_steps": 4,
        "dim_model": 32,
        "n_heads": 2,
        "dim_feedforward": 64,
        "n_encoder_layers": 1,
        "n_decoder_layers": 1,
        "n_vae_encoder_layers": 1,
        "latent_dim": 4,
    },
}


def _ctx(run: Path, dataset: Path, force: bool = False, **train: Any) -> StageContext:
    values: dict[str, Any] = {
        "name": "st",
        "dataset": str(dataset),
        "steps": 4,
        "batch_size": 4,
        "save_every": 2,
        "log_every": 2,
        "threads": 1,
        "options": TINY,
        **train,
    }
    cfg = FactoryConfig(stage="train", run_dir=str(run), force=force, train=TrainConfig(**values))
    run.mkdir(parents=True, exist_ok=True)
    return StageContext(cfg, RunStore(run), Shard(0, 1))


def _train(run: Path, dataset: Path, force: bool = False, **train: Any) -> dict[str, Any]:
    from factory.policy.train_stage import run as train_stage

    return train_stage(_ctx(run, dataset, force, **train))


def _hydra(value: Any) -> str:
    """A Hydra override value (YAML flow style) of a dict / list / scalar."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_hydra(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_hydra(v) for v in value) + "]"
    return str(value)


def _listing(root: Path) -> list[tuple[str, int]]:
    return sorted((str(p.relative_to(root)), p.stat().st_mtime_ns) for p in root.rglob("*"))


def _frames(dataset: Path, n: int, keys: list[str]) -> dict[str, np.ndarray]:
    """Env-style observations (n, ...) from the dataset's first frames: vectors from the
    parquet files, images (uint8) and depth (uint16 mm) decoded from the videos by the
    factory's own PyAV decoder (lerobot's ``pyav`` backend needs ``torchvision.io.
    VideoReader``, which newer torchvision lacks)."""
    import pyarrow.parquet as pq

    (path,) = sorted((dataset / "data").glob("*/*.parquet"))[:1]
    table = pq.read_table(path).to_pydict()
    obs: dict[str, np.ndarray] = {}
    visual = [k for k in keys if k.startswith(("observation.images.", "observation.depth."))]
    if visual:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        from factory.policy.video_frames import decode_videos

        ds = LeRobotDataset("factory/demos", root=dataset, video_backend="pyav")
        frames = decode_videos(ds, visual, workers=1)
        for k in visual:
            obs[k] = np.ascontiguousarray(frames[k][:n])
    for k in keys:
        if k not in obs:
            obs[k] = np.asarray(table[k][:n], np.float32)
    return obs


@pytest.fixture(scope="module")
def state_run(policy_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run dir with policy ``st`` (diffusion, state inputs) trained 4 steps on the shared
    small dataset, checkpoints at steps 2 and 4."""
    run = tmp_path_factory.mktemp("train") / "run"
    result = _train(run, policy_run / "dataset" / "merged")
    assert result["steps"] == 4 and result["resumed_from"] == 0
    return run


def test_checkpoints_are_lerobot_pretrained_models(state_run: Path, policy_run: Path) -> None:
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

    out = state_run / "policy" / "st"
    ckpts = out / "checkpoints"
    assert sorted(p.name for p in ckpts.iterdir()) == ["000002", "000004", "last"]
    assert (ckpts / "last").resolve() == (ckpts / "000004").resolve()
    model = ckpts / "000004" / "pretrained_model"
    for f in ("config.json", "model.safetensors", "train_config.json", "factory_policy.json"):
        assert (model / f).is_file(), f
    assert list(model.glob("policy_preprocessor*.json")) and list(model.glob("*normalizer*"))
    state = ckpts / "000004" / "training_state"
    assert json.loads((state / "training_step.json").read_text()) == {"step": 4}
    assert (state / "optimizer_state.safetensors").is_file()
    policy = DiffusionPolicy.from_pretrained(model)
    assert tuple(policy.config.input_features["observation.state"].shape) == (17,)
    assert tuple(policy.config.input_features["observation.environment_state"].shape) == (24,)
    assert tuple(policy.config.output_features["action"].shape) == (10,)  # train.action=tool
    info = json.loads((out / "train.json").read_text())
    assert info["schema_version"] == 1 and info["steps"] == 4
    assert info["policy_type"] == "diffusion" and info["inputs"] == "state"
    assert info["action"] == "tool"
    assert info["dataset"] == str((policy_run / "dataset" / "merged").resolve())
    assert info["scenes"] == ["kitchen_a"] and info["episodes"] == 3 and info["fps"] == 20
    assert info["features"] == {
        "observation.state": [8],
        "observation.ee_pose": [7],
        "observation.environment_state": [14],
    }
    log = [json.loads(line) for line in (out / "train_log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in log] == [2, 4]
    assert all(np.isfinite(r["loss"]) and r["lr"] > 0 and r["seconds"] > 0 for r in log)


def test_resume_continues_the_step_count(state_run: Path, policy_run: Path) -> None:
    dataset = policy_run / "dataset" / "merged"
    result = _train(state_run, dataset, steps=6)
    assert result["resumed_from"] == 4 and result["steps"] == 6
    out = state_run / "policy" / "st"
    log = [json.loads(line) for line in (out / "train_log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in log] == [2, 4, 6]
    assert log[2]["seconds"] > log[1]["seconds"]
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["000004", "000006", "last"]
    again = _train(state_run, dataset, steps=6)
    assert again.get("skipped") and again["steps"] == 6


def test_fast_low_dim_samples_equal_lerobots_own(policy_run: Path) -> None:
    """The state policy's samples (gathered from preloaded columns) are exactly what
    ``LeRobotDataset.__getitem__`` with the same delta timestamps gives, converted."""
    import torch

    from factory.policy.inputs import convert_sample, input_spec
    from factory.policy.train import open_dataset, policy_config

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec("state", feats)
    cfg = policy_config(TrainConfig(options=TINY), spec, "cpu")
    base, trainset = open_dataset(dataset, spec, cfg, augment=False)
    assert trainset.frames is not None and not base.meta.video_keys  # nothing decoded
    ends = base.meta.episodes["dataset_to_index"]
    for idx in [0, 1, int(ends[0]) - 2, int(ends[0]) - 1, int(ends[0]), len(base) - 1]:
        fast = trainset[idx]
        slow = convert_sample(spec, base[idx])
        assert set(fast) == set(slow), idx
        for k, v in slow.items():
            assert fast[k].shape == v.shape and fast[k].dtype == v.dtype, (idx, k)
            assert torch.allclose(fast[k].float(), v.float(), atol=1e-5), (idx, k)
    assert bool(trainset[len(base) - 1]["action_is_pad"][-1])


def test_state_diffusion_recipe_defaults(policy_run: Path) -> None:
    """Diffusion on state inputs predicts the clean chunk (sample) in 10 DDIM steps at lr 3e-4
    unless train.options / train.lr say otherwise; image inputs add their recipe (84 px
    images, no crop)."""
    from factory.policy.inputs import input_spec
    from factory.policy.train import STATE_DIFFUSION_LR, policy_config

    feats = json.loads((policy_run / "dataset" / "merged" / "meta" / "info.json").read_text())
    state = input_spec("state", feats["features"])
    cfg = policy_config(TrainConfig(options=TINY), state, "cpu")
    assert (cfg.prediction_type, cfg.noise_scheduler_type) == ("sample", "DDIM")
    assert cfg.num_inference_steps == TINY["diffusion"]["num_inference_steps"]  # options win
    eps = {"diffusion": {**TINY["diffusion"], "prediction_type": "epsilon"}}
    assert policy_config(TrainConfig(options=eps), state, "cpu").prediction_type == "epsilon"
    rgb = input_spec("rgb", feats["features"])
    image = policy_config(TrainConfig(inputs="rgb", options=TINY), rgb, "cpu")
    assert (image.prediction_type, image.resize_shape, image.crop_shape) == (
        "sample",
        (84, 84),
        None,
    )
    assert image.n_obs_steps == 1
    assert tuple(image.down_dims) == tuple(TINY["diffusion"]["down_dims"])  # options win
    assert STATE_DIFFUSION_LR == 3e-4


def test_video_cache_samples_equal_lerobots_own(policy_run: Path) -> None:
    """An RGB-D policy's samples read from the videos decoded into memory are what
    ``LeRobotDataset.__getitem__`` decodes per sample (same delta timestamps), converted:
    images within 1/255, depth exact."""
    import torch

    from factory.policy.inputs import input_spec
    from factory.policy.train import open_dataset, policy_config

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec("rgbd", feats)
    cfg = policy_config(TrainConfig(inputs="rgbd", options=TINY), spec, "cpu")
    base, cached = open_dataset(dataset, spec, cfg, augment=False, video_cache="memory")
    assert cached.frames is not None and cached.videos is not None
    assert set(cached.videos) == set(spec.visual_keys())
    assert cached.videos["observation.depth.left"].dtype == np.uint16
    _, plain = open_dataset(dataset, spec, cfg, augment=False, video_cache="off")
    assert plain.frames is None
    ends = base.meta.episodes["dataset_to_index"]
    for idx in [0, int(ends[0]) - 1, int(ends[0]), len(base) - 1]:
        fast = cached[idx]
        slow = plain[idx]  # convert_sample(spec, base[idx]), one-frame windows kept
        assert set(fast) == set(slow), idx
        for k, v in slow.items():
            assert fast[k].shape == v.shape and fast[k].dtype == v.dtype, (idx, k)
            tol = 1.0 / 255 + 1e-6 if k.startswith("observation.images.") else 1e-6
            assert torch.allclose(fast[k].float(), v.float(), atol=tol), (idx, k)


def test_videos_decoded_in_processes_equal_threads(
    policy_run: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A large dataset's video files are decoded in worker processes (here forced on the small
    one): the frames placed are those the threads place, depth packed to millimetres."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.policy import video_frames
    from factory.policy.inputs import input_spec

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    keys = input_spec("rgbd", feats).visual_keys()
    base = LeRobotDataset("factory/demos", root=dataset, video_backend="pyav")
    threads = video_frames.decode_videos(base, keys, workers=2)
    monkeypatch.setattr(video_frames, "PROCESS_MIN_FRAMES", 0)
    procs = video_frames.decode_videos(base, keys, workers=2)
    assert set(procs) == set(keys) and procs["observation.depth.left"].dtype == np.uint16
    for k in keys:
        assert np.array_equal(procs[k], threads[k]), k


def test_loaded_policy_acts_on_env_observations(state_run: Path, policy_run: Path) -> None:
    from factory.policy.checkpoint import check_features, load_policy

    policy = load_policy("st", state_run, device="cpu")
    assert policy.info.steps == 6 or policy.info.steps == 4
    obs = _frames(policy_run / "dataset" / "merged", 3, list(policy.info.features))
    policy.reset()
    for _ in range(3):
        actions = policy.act(obs)
        assert actions.shape == (3, 8) and actions.dtype == np.float32
        assert np.isfinite(actions).all()
    # by path: the pretrained_model folder alone
    again = load_policy(str(policy.path), None, device="cpu")
    assert again.info.name == "st"
    # an env without the environment state, or with other shapes: one-line errors
    with pytest.raises(PolicyError, match=r"observation\.environment_state"):
        check_features(policy.info, ["observation.state", "observation.ee_pose"])
    bad = dict(obs, **{"observation.environment_state": np.zeros((3, 13), np.float32)})
    fresh = load_policy("st", state_run, device="cpu")
    with pytest.raises(PolicyError, match="shape") as e:
        fresh.act(bad)
    assert "\n" not in str(e.value)


def test_rgbd_policy_trains_and_acts(policy_run: Path, tmp_path: Path) -> None:
    """RGB-D of both recorded cameras + the robot state: depth decoded from the packed video,
    images augmented, and the same conversion on the env's uint8 / uint16 observations."""
    from factory.policy.checkpoint import load_policy

    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name="rgbd", inputs="rgbd", steps=2, batch_size=2)
    assert result["steps"] == 2
    policy = load_policy("rgbd", tmp_path, device="cpu")
    assert policy.info.features["observation.depth.left"] == [32, 32]
    assert policy.info.features["observation.images.wrist"] == [32, 32, 3]
    # the image recipe: resized on the device, no crop (the loader shifts instead)
    assert policy.policy.config.resize_shape == (84, 84)
    assert policy.policy.config.crop_shape is None
    obs = _frames(dataset, 2, list(policy.info.features))
    assert obs["observation.depth.left"].dtype == np.uint16
    actions = policy.act(obs)
    assert actions.shape == (2, 8) and np.isfinite(actions).all()


def test_compiled_training_saves_the_plain_policy(
    policy_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``train.compile``: the encoder and U-Net are traced by ``torch.compile`` (here with the
    ``aot_eager`` backend: the same graphs, no code generation), the auxiliary loss's feature
    tap still sees the encoder, and the checkpoint is the plain lerobot policy, key for key."""
    from safetensors.torch import load_file

    from factory.policy import train as train_module
    from factory.policy.checkpoint import last_checkpoint

    monkeypatch.setattr(train_module, "COMPILE_BACKEND", "aot_eager")
    dataset = policy_run / "dataset" / "merged"
    for name, compiled in (("plain", False), ("compiled", True)):
        result = _train(
            tmp_path, dataset, name=name, inputs="rgbd", steps=2, batch_size=2, compile=compiled
        )
        assert result["steps"] == 2
    lines = (tmp_path / "policy" / "compiled" / "train_log.jsonl").read_text().splitlines()
    assert all(np.isfinite(json.loads(x)["aux_loss"]) for x in lines)
    keys = {}
    for name in ("plain", "compiled"):
        ckpt = last_checkpoint(tmp_path / "policy" / name)
        assert ckpt is not None
        keys[name] = sorted(load_file(str(ckpt / "pretrained_model" / "model.safetensors")))
    assert keys["compiled"] == keys["plain"]


def test_image_recipe_aux_loss_and_ema_resume(policy_run: Path, tmp_path: Path) -> None:
    """An image diffusion policy gets the auxiliary state loss and the weight average by
    default: the log holds the auxiliary loss, the checkpoint's ``pretrained_model`` holds the
    averaged weights (a plain lerobot policy) and ``training_state`` the raw weights and the
    head, from which a resumed training continues; lerobot's older crop recipe is one option
    away."""
    import torch
    from safetensors.torch import load_file

    from factory.policy.checkpoint import last_checkpoint
    from factory.policy.inputs import input_spec
    from factory.policy.train import EXTRAS, Trainer, policy_config

    dataset = policy_run / "dataset" / "merged"
    _train(tmp_path, dataset, name="rgb", inputs="rgb", steps=3, batch_size=2, save_every=3)
    out = tmp_path / "policy" / "rgb"
    lines = [json.loads(x) for x in (out / "train_log.jsonl").read_text().splitlines()]
    assert all(np.isfinite(r["aux_loss"]) for r in lines)
    ckpt = last_checkpoint(out)
    assert ckpt is not None
    extras = load_file(str(ckpt / "training_state" / EXTRAS))
    assert any(k.startswith("aux.") for k in extras) and int(extras["ema.updates"][0]) == 3
    averaged = load_file(str(ckpt / "pretrained_model" / "model.safetensors"))
    raw = [v for k, v in sorted(extras.items()) if k.startswith("raw.")]
    assert raw and len(averaged) >= len(raw)
    # resuming puts the raw weights back into the model and the average into the EMA
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec("rgb", feats, "tool")
    tc = _ctx(tmp_path, dataset, name="rgb", inputs="rgb", steps=6, batch_size=2).cfg.train
    trainer = Trainer(tc, spec, dataset, out, resume=ckpt)
    assert trainer.step == 3 and trainer.ema is not None and trainer.ema.updates == 3
    assert trainer.aux_head is not None
    for i, p in enumerate(trainer.params):
        assert torch.equal(p.detach(), extras[f"raw.{i}"])
    assert any(not torch.equal(s, p.detach()) for s, p in zip(trainer.ema.shadow, trainer.params))
    _train(tmp_path, dataset, name="rgb", inputs="rgb", steps=4, batch_size=2, save_every=3)
    # options bring back lerobot's crop recipe; train.aux_state=0 and train.ema=0 switch off
    cfg = policy_config(
        TrainConfig(
            inputs="rgb", options={"diffusion": {**TINY["diffusion"], "resize_shape": None}}
        ),
        spec,
        "cpu",
    )
    assert cfg.resize_shape is None and cfg.crop_shape == (28, 28)
    plain = _train(
        tmp_path, dataset, name="plain", inputs="rgb", steps=2, batch_size=2, aux_state=0.0, ema=0.0
    )
    assert plain["steps"] == 2
    ckpt = last_checkpoint(tmp_path / "policy" / "plain")
    assert ckpt is not None and not (ckpt / "training_state" / EXTRAS).exists()


def test_learning_curve_evaluates_checkpoints_while_training(
    policy_run: Path, tmp_path: Path
) -> None:
    """``train.eval_every_minutes``: checkpoints are evaluated in the held-out kitchen by
    ``stage=eval`` in a background process; each result joins ``train_log.jsonl`` as a curve
    point (the last step's too), and the run report draws it."""
    from factory.config import EvalConfig, ReportConfig
    from factory.policy.train_stage import run as train_stage
    from factory.report.collect import collect_run

    dataset = policy_run / "dataset" / "merged"
    shutil.copytree(policy_run / "scenes", tmp_path / "scenes")
    ctx = _ctx(tmp_path, dataset, name="curve", steps=6, eval_every_minutes=1e-4, eval_episodes=2)
    # two workers, one episode each: the evaluation's own worker pool starts in the child
    ctx.cfg.eval = EvalConfig(max_steps=5, workers=2, batch=1, nthread=1, device="cpu")
    ctx.cfg.report = ReportConfig()
    train_stage(ctx)
    out = tmp_path / "policy" / "curve"
    lines = [json.loads(x) for x in (out / "train_log.jsonl").read_text().splitlines()]
    points = [r for r in lines if "success" in r]
    assert points, lines
    assert points[-1]["step"] == 6 and points[-1]["episodes"] == 2
    assert all(0.0 <= p["success"] <= 1.0 and len(p["ci95"]) == 2 for p in points)
    for p in points:
        assert (out / "curve" / str(p["step"]) / "results.json").is_file()
    assert [r["step"] for r in lines if "loss" in r] == [2, 4, 6]
    data = collect_run(tmp_path)
    run = next(r for r in data.policies if r.name == "curve")
    assert [c.step for c in run.curve] == [p["step"] for p in points] and len(run.log) == 3
    from factory.report.media import MediaSink
    from factory.report.page import build_page

    html = build_page(data, ReportConfig(), MediaSink(tmp_path, embed=True)).html
    assert "learning curve of curve" in html and "training minutes" in html
    assert not (tmp_path / "eval").exists()  # the curve's evaluations stay in policy/<name>


def test_data_parallel_training_on_two_cpu_processes(policy_run: Path, tmp_path: Path) -> None:
    """``train.gpus=2`` (here two CPU processes over gloo, as on two GPUs over NCCL): rank 0
    logs and checkpoints every step count once, the policy it saves acts, and a bad count is a
    one-line error."""
    from factory.errors import ConfigError
    from factory.policy.checkpoint import load_policy

    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name="dp", steps=4, device="cpu", gpus=2)
    assert result["steps"] == 4 and result["finished"]
    out = tmp_path / "policy" / "dp"
    lines = [json.loads(x) for x in (out / "train_log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in lines] == [2, 4]  # one writer
    policy = load_policy("dp", tmp_path, device="cpu")
    actions = policy.act(_frames(dataset, 2, list(policy.info.features)))
    assert actions.shape == (2, 8) and np.isfinite(actions).all()
    with pytest.raises(ConfigError, match=r"train\.gpus"):
        _train(tmp_path, dataset, name="dp0", steps=2, gpus=0)


@pytest.mark.gpu
def test_image_recipe_on_cuda_compiled(policy_run: Path, tmp_path: Path) -> None:
    """On CUDA an RGB-D diffusion policy trains compiled by default (inductor), in bf16 with
    the device loader, and its checkpoint acts on the CPU like any lerobot policy."""
    from factory.policy.checkpoint import load_policy

    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name="cuda", inputs="rgbd", steps=3, device="cuda")
    assert result["steps"] == 3
    policy = load_policy("cuda", tmp_path, device="cpu")
    actions = policy.act(_frames(dataset, 2, list(policy.info.features)))
    assert actions.shape == (2, 8) and np.isfinite(actions).all()


@pytest.mark.gpu
def test_data_parallel_on_two_gpus(policy_run: Path, tmp_path: Path) -> None:
    """``train.gpus=2`` over NCCL on a machine with two GPUs."""
    import torch

    if torch.cuda.device_count() < 2:
        pytest.skip("needs two GPUs")
    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name="dp2", inputs="rgbd", steps=4, device="cuda", gpus=2)
    assert result["steps"] == 4 and result["finished"]


def test_act_policy_by_name(policy_run: Path, tmp_path: Path) -> None:
    from lerobot.policies.act.modeling_act import ACTPolicy

    from factory.policy.checkpoint import load_policy

    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name="act", policy="act", steps=2)
    assert result["steps"] == 2 and result["type"] == "act"
    policy = load_policy("act", tmp_path, device="cpu")
    assert isinstance(policy.policy, ACTPolicy)
    actions = policy.act(_frames(dataset, 2, list(policy.info.features)))
    assert actions.shape == (2, 8) and np.isfinite(actions).all()


@pytest.mark.parametrize("action", ["joint", "tool_rel"])
def test_other_action_kinds_train_and_act(policy_run: Path, tmp_path: Path, action: str) -> None:
    """``train.action=joint`` predicts the dataset's action as it is; ``tool_rel`` predicts
    tool positions relative to the tool at each chunk's start: its samples add back to the
    ``tool`` samples, its statistics are those of the relative windows, and acting adds each
    chunk's origin back (the queue of a chunk shares one origin)."""
    from factory.policy.checkpoint import chunk_starts, load_policy
    from factory.policy.inputs import input_spec
    from factory.policy.train import Trainer, model_stats

    dataset = policy_run / "dataset" / "merged"
    result = _train(tmp_path, dataset, name=action, action=action, steps=2)
    assert result["steps"] == 2
    policy = load_policy(action, tmp_path, device="cpu")
    assert policy.info.action == action
    dim = 8 if action == "joint" else 10
    assert tuple(policy.policy.config.output_features["action"].shape) == (dim,)
    obs = _frames(dataset, 2, list(policy.info.features))
    policy.reset()
    origins = []
    for step in range(5):  # n_action_steps 4: a new chunk at steps 0 and 4
        assert chunk_starts(policy.policy) == (step % 4 == 0)
        actions = policy.act(obs)
        assert actions.shape == (2, 8) and np.isfinite(actions).all()
        origins.append(getattr(policy, "_origin", None))
    if action == "joint":
        return
    assert origins[1] is origins[0] and origins[3] is origins[0]  # one chunk, one origin
    assert origins[4] is not origins[0]
    features = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    tc = TrainConfig(name="x", dataset=str(dataset), steps=1, batch_size=4, threads=1, options=TINY)
    absolute = Trainer(tc, input_spec("state", features, "tool"), dataset, tmp_path / "a")
    spec = input_spec("state", features, "tool_rel")
    relative = Trainer(tc, spec, dataset, tmp_path / "r")
    for i in (0, 5, len(relative.trainset) - 1):
        a, r = absolute.trainset[i], relative.trainset[i]
        now = r["observation.state"][-1, 8:11]
        assert torch_allclose(r["action"][:, :3] + now, a["action"][:, :3])
        assert torch_allclose(r["action"][:, 3:], a["action"][:, 3:])
    stats = model_stats(spec, dataset, relative.base, relative.trainset)
    span = stats["action"]["max"][:3] - stats["action"]["min"][:3]
    whole = model_stats(
        input_spec("state", features, "tool"), dataset, absolute.base, absolute.trainset
    )
    assert (span <= whole["action"]["max"][:3] - whole["action"]["min"][:3] + 1e-6).all()


def torch_allclose(a: Any, b: Any) -> bool:
    return bool(np.allclose(np.asarray(a), np.asarray(b), atol=1e-5))


def test_bad_inputs_are_one_line_errors_and_write_nothing(
    state_run: Path, policy_run: Path, tmp_path: Path
) -> None:
    dataset = policy_run / "dataset" / "merged"
    run = tmp_path / "run"
    # an unknown policy type: the available ones listed
    with pytest.raises(PolicyError) as e:
        _train(run, dataset, name="x", policy="difusion")
    assert "diffusion" in str(e.value) and "act" in str(e.value) and "\n" not in str(e.value)
    # an option the policy does not have
    with pytest.raises(PolicyError, match="down_dimz"):
        _train(run, dataset, name="x", options={"diffusion": {"down_dimz": [8]}})
    # a dataset without the environment state (exported before it existed)
    old = tmp_path / "old"
    (old / "meta").mkdir(parents=True)
    info = json.loads((dataset / "meta" / "info.json").read_text())
    del info["features"]["observation.environment_state"]
    (old / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(PolicyError, match="stage=dataset force=true"):
        _train(run, old, name="x")
    # no dataset at all
    with pytest.raises(PolicyError, match="stage=dataset"):
        _train(run, tmp_path / "none", name="x")
    assert not (run / "policy").exists()
    # policy/st holds checkpoints of another dataset: refused, nothing touched
    other = tmp_path / "other"
    shutil.copytree(dataset, other)
    before = _listing(state_run / "policy")
    with pytest.raises(PolicyError, match="dataset") as e:
        _train(state_run, other, steps=8)
    assert "force=true" in str(e.value) and "\n" not in str(e.value)
    assert _listing(state_run / "policy") == before


@pytest.mark.slow
def test_killed_training_resumes_from_its_last_checkpoint(policy_run: Path, tmp_path: Path) -> None:
    """A real SIGKILL of the command line mid-training, then a re-run that continues from the
    newest checkpoint instead of step 0."""
    run = tmp_path / "run"
    run.mkdir()
    args = [
        sys.executable,
        "-m",
        "factory",
        "stage=train",
        f"run_dir={run}",
        f"train.dataset={policy_run / 'dataset' / 'merged'}",
        "train.name=k",
        "train.steps=400",
        "train.batch_size=4",
        "train.save_every=5",
        "train.log_every=5",
        f"+train.options={_hydra(TINY)}",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    last = run / "policy" / "k" / "checkpoints" / "last"
    deadline = time.time() + 300
    while time.time() < deadline and proc.poll() is None:
        if last.exists() and int(last.resolve().name) >= 10:
            break
        time.sleep(0.2)
    assert proc.poll() is None, proc.stderr.read().decode()[-2000:] if proc.stderr else ""
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    saved = int(last.resolve().name)
    assert saved >= 10
    args[args.index("train.steps=400")] = f"train.steps={saved + 10}"
    out = subprocess.run(args, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    manifest = json.loads((run / "manifest.json").read_text())
    result = manifest["stages"]["train"]["shards"]["0-of-1"]["result"]
    assert result["resumed_from"] >= saved and result["steps"] == saved + 10
    log = [
        json.loads(x) for x in (run / "policy" / "k" / "train_log.jsonl").read_text().splitlines()
    ]
    steps = [r["step"] for r in log]
    assert steps == sorted(set(steps)) and steps[-1] == saved + 10


def test_train_scenes_picks_episodes_and_statistics(policy_run: Path, tmp_path: Path) -> None:
    """``train.scenes`` picks scenes of the dataset by count or id: the training record, the
    sampled frames and the statistics cover those scenes' episodes only."""
    from factory.errors import ConfigError
    from factory.policy.inputs import input_spec
    from factory.policy.train import Trainer, _low_dim, model_stats
    from factory.policy.train_stage import selected_scenes

    meta = {
        "scenes": ["b", "a", "c"],
        "episodes": [{"scene_id": s, "episode_index": i} for i, s in enumerate("abcab")],
    }
    assert selected_scenes(None, meta, tmp_path) is None
    assert selected_scenes(2, meta, tmp_path) == ["a", "b"]
    assert selected_scenes(["c", "a"], meta, tmp_path) == ["a", "c"]
    for bad, words in ((4, "has 3 scene(s)"), (["x"], "no scene(s) ['x']"), ("a", "a number")):
        with pytest.raises(ConfigError, match=re.escape(words)):
            selected_scenes(bad, meta, tmp_path)

    dataset = policy_run / "dataset" / "merged"
    info = json.loads((dataset / "meta" / "factory.json").read_text())
    first = info["episodes"][0]
    rows = _low_dim(dataset, ["action"], [first["episode_index"]])
    assert len(rows["action"]) == first["n_frames"]
    everything = _low_dim(dataset, ["action"])
    assert len(everything["action"]) == sum(e["n_frames"] for e in info["episodes"])

    tc = TrainConfig(
        name="sub", dataset=str(dataset), steps=1, batch_size=4, threads=1, options=TINY
    )
    features = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec("state", features)
    ep = int(first["episode_index"])
    trainer = Trainer(tc, spec, dataset, tmp_path / "sub", None, [ep])
    frames = trainer.trainset.frames
    assert frames is not None
    assert set(frames.episode[trainer.sampler().indices].tolist()) == {ep}
    stats = model_stats(spec, dataset, trainer.base, trainer.trainset, [ep])
    np.testing.assert_allclose(stats["action"]["max"], rows["action"].max(0), rtol=1e-6)
    np.testing.assert_allclose(stats["action"]["min"], rows["action"].min(0), rtol=1e-6)
    result = _train(tmp_path / "run", dataset, scenes=1, name="one")
    record = json.loads((tmp_path / "run" / "policy" / "one" / "train.json").read_text())
    assert result["steps"] == 4 and record["scenes"] == info["scenes"][:1]
    chosen = [e for e in info["episodes"] if e["scene_id"] in record["scenes"]]
    assert record["episodes"] == len(chosen)


def test_max_minutes_stops_with_a_checkpoint_and_a_rerun_goes_on(
    policy_run: Path, tmp_path: Path
) -> None:
    dataset = policy_run / "dataset" / "merged"
    run = tmp_path / "run"
    first = _train(run, dataset, name="late", max_minutes=1e-9)
    assert first["steps"] == 1 and first["finished"] is False
    ckpts = run / "policy" / "late" / "checkpoints"
    assert (ckpts / "last").resolve().name == "000001"
    log = [
        json.loads(x)
        for x in (run / "policy" / "late" / "train_log.jsonl").read_text().splitlines()
    ]
    assert [r["step"] for r in log] == [1]
    again = _train(run, dataset, name="late")
    assert again["steps"] == 4 and again["resumed_from"] == 1 and again["finished"] is True


def test_perception_policy_trains_resumes_and_acts_without_poses(
    policy_run: Path, tmp_path: Path
) -> None:
    """``train.vision=perception``: a perception network learns the object poses from the
    cameras while lerobot's state policy learns on the recorded poses; the checkpoint holds a
    plain lerobot state policy with the network beside it, a resumed training continues both,
    and the loaded policy acts on observations without ``observation.environment_state``
    (the network's prediction fills it)."""
    import torch

    from factory.errors import ConfigError
    from factory.policy import perception
    from factory.policy.checkpoint import last_checkpoint, load_policy
    from factory.policy.train import PERCEPTION_STATE

    dataset = policy_run / "dataset" / "merged"
    args = {"name": "seen", "inputs": "rgbd", "vision": "perception", "batch_size": 2}
    result = _train(tmp_path, dataset, steps=2, save_every=2, **args)
    assert result["steps"] == 2
    out = tmp_path / "policy" / "seen"
    lines = [json.loads(x) for x in (out / "train_log.jsonl").read_text().splitlines()]
    assert all(np.isfinite(r["perception_cm"]) and r["perception_cm"] > 0 for r in lines)
    ckpt = last_checkpoint(out)
    assert ckpt is not None
    model = ckpt / "pretrained_model"
    assert (model / perception.WEIGHTS).is_file() and (model / perception.SETTINGS).is_file()
    assert (ckpt / "training_state" / PERCEPTION_STATE).is_file()
    cfg = json.loads((model / "config.json").read_text())
    assert sorted(cfg["input_features"]) == [
        "observation.environment_state",
        "observation.state",
    ]
    first = perception.load(model, "cpu").state_dict()
    # resumed: two more steps move the network on from the saved weights
    result = _train(tmp_path, dataset, steps=4, save_every=2, **args)
    assert result["steps"] == 4 and result["resumed_from"] == 2
    ckpt = last_checkpoint(out)
    assert ckpt is not None
    moved = perception.load(ckpt / "pretrained_model", "cpu").state_dict()
    assert any(not torch.equal(first[k], moved[k]) for k in first)
    policy = load_policy("seen", tmp_path, device="cpu")
    assert policy.info.vision == "perception" and policy.perception is not None
    # RGB-D: the wrist camera's points (kinematics) and the left camera's (its calibration)
    assert policy.perception.point_cameras == ["left", "wrist"]
    assert policy.info.features["observation.camera_poses"] == [13]
    assert "observation.environment_state" not in policy.info.features
    obs = _frames(dataset, 2, list(policy.info.features))
    seen = {}
    policy.perception.register_forward_hook(lambda m, i, o: seen.setdefault("env", o))
    actions = policy.act(obs)
    assert actions.shape == (2, 8) and np.isfinite(actions).all()
    assert seen["env"].shape == (2, 24)
    # train.perception_points=false: the first version, images only
    _train(tmp_path, dataset, steps=1, **{**args, "name": "flat"}, perception_points=False)
    flat = load_policy("flat", tmp_path, device="cpu")
    assert not flat.perception.xyz and "observation.camera_poses" not in flat.info.features
    # lerobot-eval cannot run it (its policy alone would read the env's recorded poses)
    from factory.policy.lerobot_plugin import PolicyAdapter

    with pytest.raises(ValueError, match="perception network"):
        PolicyAdapter(policy.path)
    # bad settings: one-line errors naming the fix
    with pytest.raises(ConfigError, match=r"train\.inputs=rgb or rgbd"):
        _train(tmp_path, dataset, name="bad", inputs="state", vision="perception")
    with pytest.raises(ConfigError, match="end_to_end, perception"):
        _train(tmp_path, dataset, name="bad", inputs="rgbd", vision="pixels")


def test_per_sample_decoding_without_video_reader_names_the_cache(
    policy_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where torchvision has no ``io.VideoReader`` (lerobot's ``pyav`` backend reads through
    it; the GPU machine's torchvision lacks it), decoding per sample is refused with the
    setting that decodes every frame once instead."""
    import torchvision

    monkeypatch.delattr(torchvision.io, "VideoReader", raising=False)
    dataset = policy_run / "dataset" / "merged"
    with pytest.raises(PolicyError, match=r"train\.video_cache=memory") as e:
        _train(tmp_path, dataset, name="pyav", inputs="rgb", video_cache="off", steps=1)
    assert "\n" not in str(e.value)


def test_train_cameras_chooses_what_an_image_policy_reads(policy_run: Path, tmp_path: Path) -> None:
    """``train.cameras``: an image policy reads the cameras named (the evaluation then renders
    those only); a camera the dataset lacks is a one-line error listing the ones it has."""
    dataset = policy_run / "dataset" / "merged"
    result = _train(
        tmp_path, dataset, name="wrist", inputs="rgb", cameras=["wrist"], steps=1, batch_size=2
    )
    assert result["steps"] == 1
    info = json.loads((tmp_path / "policy" / "wrist" / "train.json").read_text())
    assert [k for k in info["features"] if k.startswith("observation.images.")] == [
        "observation.images.wrist"
    ]
    with pytest.raises(PolicyError, match="it records left, wrist") as e:
        _train(tmp_path, dataset, name="nope", inputs="rgb", cameras=["right"], steps=1)
    assert "\n" not in str(e.value)
