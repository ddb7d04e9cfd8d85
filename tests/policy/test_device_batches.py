"""``train.loader=device``: batches gathered by index from features and frames held where the
model trains equal the DataLoader path's samples, stacked; sampling, augmentation and the
settings' errors. Run here on CPU tensors (the same code runs on CUDA)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

pytest.importorskip("lerobot")
require_robot_models()

from factory.config import TrainConfig
from factory.errors import ConfigError, PolicyError


def _opened(policy_run: Path, inputs: str, action: str, options: dict[str, Any]) -> tuple[Any, Any]:
    """The dataset and its converted view (frames decoded into memory) of a setting, with the
    windows of the policy of ``options`` (``train.options``)."""
    from factory.policy.inputs import input_spec
    from factory.policy.train import open_dataset, policy_config

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec(inputs, feats, action)
    cfg = policy_config(TrainConfig(inputs=inputs, action=action, options=options), spec, "cpu")
    return open_dataset(dataset, spec, cfg, augment=False, video_cache="memory")


@pytest.mark.parametrize(
    ("inputs", "action"),
    [("state", "tool"), ("state", "tool_rel"), ("state", "joint"), ("rgbd", "tool")],
)
def test_device_batches_equal_the_dataloader_samples(
    policy_run: Path, tiny_options: dict[str, Any], inputs: str, action: str
) -> None:
    """Episode starts and ends (clamped windows, pad masks) included; RGB and depth of both
    cameras for rgbd."""
    import torch

    from factory.policy.device_batches import DeviceBatches

    base, trainset = _opened(policy_run, inputs, action, tiny_options)
    assert trainset.frames is not None
    batches = DeviceBatches(trainset.frames, "cpu", batch_size=4)
    ends = base.meta.episodes["dataset_to_index"]
    picks = [0, 1, int(ends[0]) - 2, int(ends[0]) - 1, int(ends[0]), len(base) - 1]
    got = batches.gather(torch.tensor(picks))
    want = [trainset[i] for i in picks]
    assert set(got) == set(want[0])
    if inputs == "rgbd":
        assert {"observation.images.left", "observation.depth.wrist"} <= set(got)
    for key in want[0]:
        ref = torch.stack([w[key] for w in want])
        assert got[key].shape == ref.shape and got[key].dtype == ref.dtype, key
        assert torch.allclose(got[key].float(), ref.float(), atol=1e-6), key
    assert bool(got["action_is_pad"][-1, -1])  # the last frame's window runs past its episode


def test_epochs_draw_every_allowed_frame_once(
    policy_run: Path, tiny_options: dict[str, Any]
) -> None:
    """An epoch is a permutation of the sampler's frames (reproducible from the seed), served
    in full batches: the last of an epoch is topped up with the next epoch's first frames (one
    batch shape for a compiled model)."""
    import torch

    from factory.policy.device_batches import DeviceBatches

    _, trainset = _opened(policy_run, "state", "tool", tiny_options)
    pool = np.arange(3, 40)  # 37 frames
    a = DeviceBatches(trainset.frames, "cpu", batch_size=5, indices=pool, seed=1)
    drawn = [a._take(5) for _ in range(7)]
    first = a._order.clone()
    assert sorted(first.tolist()) == pool.tolist()  # epoch 1: a permutation of the pool
    assert torch.equal(torch.cat(drawn), first[:35])
    batch = next(a)  # 2 of epoch 1, 3 of epoch 2: one shape
    assert batch["observation.state"].shape[0] == 5
    assert not torch.equal(a._order, first) and sorted(a._order.tolist()) == pool.tolist()
    assert a._pos == 3
    small = DeviceBatches(trainset.frames, "cpu", batch_size=16, indices=np.arange(3, 9), seed=1)
    assert next(small)["observation.state"].shape[0] == 16  # smaller pool than a batch
    b = DeviceBatches(trainset.frames, "cpu", batch_size=5, indices=pool, seed=1)
    next(b)
    c = DeviceBatches(trainset.frames, "cpu", batch_size=5, indices=pool, seed=1)
    next(c)
    assert torch.equal(c._order, b._order)


def test_augmentation_shifts_a_cameras_rgb_and_depth_alike(
    policy_run: Path, tiny_options: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Augmented RGB stays in [0, 1] and differs from the plain batch; a camera's depth image
    gets its RGB image's shift (so that a depth pixel stays under its colour) and no colour
    change; cameras get their own shifts; a sample's observation steps get the same draw (at an
    episode's first frame both steps are that frame, and stay equal)."""
    import torch

    from factory.policy import device_batches
    from factory.policy.device_batches import DeviceBatches

    two_steps = {"diffusion": {**tiny_options["diffusion"], "n_obs_steps": 2}}
    _, trainset = _opened(policy_run, "rgbd", "tool", two_steps)
    plain = DeviceBatches(trainset.frames, "cpu", batch_size=4)
    aug = DeviceBatches(trainset.frames, "cpu", batch_size=4, augment=True, seed=3)
    shifts: list[Any] = []
    real = device_batches._shift

    def recording(img: Any, shift: Any) -> Any:
        shifts.append(shift)
        return real(img, shift)

    monkeypatch.setattr(device_batches, "_shift", recording)
    idx = torch.tensor([0, 5, 9, 20])
    p, a = plain.gather(idx), aug.gather(idx)
    img, depth = "observation.images.left", "observation.depth.left"
    assert a[img].shape == p[img].shape and a[img].min() >= 0 and a[img].max() <= 1
    assert not torch.allclose(a[img], p[img])
    keys = list(trainset.frames.videos)
    by_key = dict(zip(keys, shifts, strict=True))
    assert by_key[img] is by_key[depth]
    assert not torch.equal(by_key[img], by_key["observation.images.wrist"])
    assert torch.equal(a[depth], real(p[depth], by_key[depth]))  # shifted, colours kept
    assert not torch.equal(a[depth], p[depth])
    assert a[img].shape[1] == 2 and torch.equal(a[img][0, 0], a[img][0, 1])


def test_shift_moves_whole_pixels() -> None:
    import torch

    from factory.policy.device_batches import _shift

    x = torch.arange(16.0).reshape(1, 1, 4, 4)
    moved = _shift(x, torch.tensor([[0.5, 0.0]]))  # a quarter of twice the width: one pixel
    assert torch.equal(moved[0, 0, :, :3], x[0, 0, :, 1:])  # content moves left by one pixel
    assert torch.equal(moved[0, 0, :, 3], x[0, 0, :, 3])  # the border repeats the edge


def test_base_relative_on_tensors_matches_numpy() -> None:
    import torch

    from factory.policy.device_batches import base_relative_t
    from factory.policy.inputs import base_relative

    rng = np.random.default_rng(0)
    target = rng.normal(size=(4, 6, 3)).astype(np.float32)
    now = rng.normal(size=(4, 3)).astype(np.float32)
    got = base_relative_t(torch.from_numpy(target), torch.from_numpy(now)).numpy()
    np.testing.assert_allclose(got, base_relative(target, now), atol=1e-6)


def test_loader_setting() -> None:
    from factory.policy.device_batches import resolve_loader
    from factory.policy.train_stage import check_config

    assert resolve_loader("auto", "cuda", True) == "device"
    assert resolve_loader("auto", "cuda", False) == "dataloader"
    assert resolve_loader("auto", "cpu", True) == "dataloader"
    assert resolve_loader("device", "cpu", True) == "device"
    with pytest.raises(PolicyError, match=r"train\.video_cache=memory"):
        resolve_loader("device", "cuda", False)
    with pytest.raises(ConfigError, match=r"train\.loader must be one of auto, device, dataloader"):
        check_config(TrainConfig(name="x", loader="gpu"))


def test_training_with_the_device_loader(
    policy_run: Path, tmp_path: Path, tiny_options: dict[str, Any]
) -> None:
    """stage=train train.loader=device (here on the CPU device) trains and saves."""
    from factory.config import FactoryConfig
    from factory.context import StageContext
    from factory.policy.train_stage import run as train_stage
    from factory.store import RunStore, Shard

    dataset = policy_run / "dataset" / "merged"
    tc = TrainConfig(
        name="dev",
        dataset=str(dataset),
        steps=2,
        batch_size=2,
        save_every=2,
        log_every=1,
        threads=1,
        options=tiny_options,
        loader="device",
        device="cpu",
    )
    cfg = FactoryConfig(stage="train", run_dir=str(tmp_path), train=tc)
    out = train_stage(StageContext(cfg, RunStore(tmp_path), Shard(0, 1)))
    assert out["steps"] == 2
    log = [json.loads(line) for line in (tmp_path / "policy" / "dev" / "train_log.jsonl").open()]
    assert log[-1]["step"] == 2 and np.isfinite(log[-1]["loss"])
