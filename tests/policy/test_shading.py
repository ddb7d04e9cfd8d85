"""``train.augment_shading`` (:mod:`factory.policy.shading`): a smooth gain field, per-channel
gains and soft highlights on RGB images, drawn per sample and the same over its observation
steps; depth untouched; both loaders; bad strengths refused."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

torch = pytest.importorskip("torch")

from factory.errors import ConfigError
from factory.policy.shading import HIGHLIGHT_SIGMA, MAX_STRENGTH, SampleShading, shade


def _grey(b: int = 8, t: int = 2, size: int = 32) -> Any:
    return torch.full((b, t, 3, size, size), 0.5)


def test_off_is_the_same_images() -> None:
    img = _grey()
    assert shade(img, 0.0) is img


def test_bounds_shape_and_steps() -> None:
    """The gain stays within its strength (a grey image ends within the field's and channel's
    extremes, plus at most one highlight of ``strength``), varies across the image and between
    samples, and is the same over a sample's observation steps."""
    s = 0.2
    g = torch.Generator().manual_seed(0)
    out = shade(_grey(), s, g)
    assert out.shape == (8, 2, 3, 32, 32) and out.dtype == torch.float32
    lo = 0.5 * (1 - s) * (1 - s / 4)
    hi = 0.5 * (1 + s) * (1 + s / 4) + s
    assert out.min() >= lo - 1e-6 and out.max() <= hi + 1e-6
    assert torch.equal(out[:, 0], out[:, 1])  # one draw per sample, over its steps
    assert not torch.allclose(out[0], out[1])  # samples draw their own
    spread = out[:, 0].amax(dim=(-2, -1)) - out[:, 0].amin(dim=(-2, -1))
    assert (spread > 0.01).all()  # not a constant gain: it varies across each image


def test_no_step_axis_and_clamp_and_seed() -> None:
    """(B, 3, H, W) works too; bright pixels clamp at 1; a seeded generator repeats."""
    img = torch.rand((4, 3, 16, 16))
    a = shade(img, MAX_STRENGTH, torch.Generator().manual_seed(7))
    b = shade(img, MAX_STRENGTH, torch.Generator().manual_seed(7))
    assert a.shape == img.shape and torch.equal(a, b)
    assert a.max() <= 1.0 and a.min() >= 0.0
    assert shade(torch.ones((2, 3, 8, 8)), 0.3).max() == 1.0


def test_highlight_is_local() -> None:
    """A highlight adds light around one point: on a black image (no gain can brighten it)
    whatever lights up lies within a few sigma of its brightest pixel."""
    g = torch.Generator().manual_seed(3)
    out = shade(torch.zeros((64, 3, 64, 64)), 0.4, g)
    lit = out.amax(dim=1)  # (B, H, W)
    have = lit.amax(dim=(-2, -1)) > 0.05
    assert 0 < int(have.sum()) < 64  # some images have one, some do not
    for b in torch.nonzero(have).flatten()[:5]:
        y, x = divmod(int(lit[b].argmax()), 64)
        ys, xs = torch.nonzero(lit[b] > 0.01 * lit[b].max(), as_tuple=True)
        far = ((ys - y) ** 2 + (xs - x) ** 2).float().sqrt().max() / 64
        assert far < 4 * HIGHLIGHT_SIGMA


def test_sample_transform_wraps_the_other_transforms() -> None:
    """The DataLoader path's transform applies lerobot's transforms first, then the shading, on
    one sample's (T, 3, H, W) images."""
    calls: list[Any] = []

    def then(x: Any) -> Any:
        calls.append(x.shape)
        return x * 0 + 0.5

    out = SampleShading(0.2, then)(torch.rand((2, 3, 16, 16)))
    assert calls == [(2, 3, 16, 16)] and out.shape == (2, 3, 16, 16)
    assert torch.equal(out[0], out[1]) and not torch.allclose(out, torch.full_like(out, 0.5))


def test_device_batches_shade_rgb_not_depth(policy_run: Path, tiny_options: dict[str, Any]) -> None:
    """``DeviceBatches(shading=...)`` changes a camera's RGB images and leaves its depth as the
    plain batch's (no ``augment``: no shift)."""
    from factory.config import TrainConfig
    from factory.policy.device_batches import DeviceBatches
    from factory.policy.inputs import input_spec
    from factory.policy.train import open_dataset, policy_config

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    spec = input_spec("rgbd", feats, "tool")
    cfg = policy_config(TrainConfig(inputs="rgbd", options=tiny_options), spec, "cpu")
    _, trainset = open_dataset(dataset, spec, cfg, augment=False, video_cache="memory")
    idx = torch.tensor([0, 5, 9])
    plain = DeviceBatches(trainset.frames, "cpu", batch_size=3).gather(idx)
    shaded = DeviceBatches(trainset.frames, "cpu", batch_size=3, shading=0.3).gather(idx)
    img, depth = "observation.images.left", "observation.depth.left"
    assert not torch.allclose(shaded[img], plain[img])
    assert torch.equal(shaded[depth], plain[depth])
    # the DataLoader path's view shades its samples' RGB the same way
    _, shaded_set = open_dataset(
        dataset, spec, cfg, augment=False, video_cache="memory", shading=0.3
    )
    assert isinstance(shaded_set.augment, SampleShading)
    one = shaded_set[0]
    assert torch.equal(one[depth], trainset[0][depth])
    assert not torch.allclose(one[img], trainset[0][img])


@pytest.mark.parametrize("bad", [-0.1, 0.6])
def test_bad_strength_is_refused(bad: float) -> None:
    from factory.config import TrainConfig
    from factory.policy.train_stage import check_config

    with pytest.raises(ConfigError, match=r"train\.augment_shading must be in \[0, 0\.5\]"):
        check_config(TrainConfig(name="shaded", augment_shading=bad))
