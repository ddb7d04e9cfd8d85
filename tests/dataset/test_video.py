"""The per-feature video encoder behind the LeRobot writer: exact depth, no dropped frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from factory.dataset.lerobot_export import pack_depth_mm, unpack_depth_mm
from factory.dataset.video import VideoCodec, frame_encoder, lossless_codec, rgb_codec
from factory.errors import StoreError


def _decode(path: Path) -> np.ndarray:
    import av

    with av.open(str(path)) as container:
        return np.stack([f.to_ndarray(format="rgb24") for f in container.decode(video=0)])


def test_lossless_depth_survives_noise(tmp_path: Path) -> None:
    """Packed millimetres of pure noise (the hardest case for a codec) decode bit for bit."""
    rng = np.random.default_rng(0)
    mm = rng.integers(0, 65535, size=(12, 24, 40), dtype=np.uint16)
    enc = frame_encoder(20, {"d": lossless_codec(), "c": rgb_codec()})
    enc.start_episode(["d", "c"], tmp_path)
    smooth = np.zeros((24, 40, 3), np.uint8)
    smooth[..., 0] = np.arange(40, dtype=np.uint8) * 6
    for f in range(12):
        enc.feed_frame("d", pack_depth_mm(mm[f]))
        enc.feed_frame("c", smooth)
    results = enc.finish_episode()
    frames = _decode(results["d"][0])
    assert frames.shape == (12, 24, 40, 3)
    assert np.array_equal(unpack_depth_mm(frames), mm)
    # float tensors as lerobot's loader returns them
    as_float = np.moveaxis(frames[3], -1, 0).astype(np.float32) / 255.0
    assert np.array_equal(unpack_depth_mm(as_float), mm[3])
    rgb = _decode(results["c"][0])
    assert rgb.shape == (12, 24, 40, 3)
    assert np.abs(rgb.astype(float) - smooth).mean() < 4.0
    stats = results["c"][1]
    assert stats["mean"].shape == (3,) and stats["count"][0] == 12
    assert 0 <= stats["min"][0] <= stats["max"][0] <= 255


def test_no_frame_is_dropped(tmp_path: Path) -> None:
    """More frames than the queue holds, fed as fast as possible: every one is encoded."""
    enc = frame_encoder(30, {"c": rgb_codec(preset="medium")})
    enc.start_episode(["c"], tmp_path)
    rng = np.random.default_rng(1)
    n = 300
    for _ in range(n):
        enc.feed_frame("c", rng.integers(0, 255, size=(64, 64, 3), dtype=np.uint8))
    path, stats = enc.finish_episode()["c"]
    assert len(_decode(path)) == n and stats["count"][0] == n


def test_encoder_errors(tmp_path: Path) -> None:
    enc = frame_encoder(20, {"c": VideoCodec("no_such_codec", "yuv420p")})
    enc.start_episode(["c"], tmp_path)
    for _ in range(5):  # the failing encoder drains its queue: feeding never blocks
        enc.feed_frame("c", np.zeros((16, 16, 3), np.uint8))
    with pytest.raises(StoreError, match="video encoding failed: c: "):
        enc.finish_episode()
    enc = frame_encoder(20, {"c": rgb_codec()})
    with pytest.raises(StoreError, match=r"no video codec for features \['x'\]"):
        enc.start_episode(["x"], tmp_path)
    enc.start_episode(["c"], tmp_path)
    with pytest.raises(StoreError, match=r"expected an \(H, W, 3\) uint8 image"):
        enc.feed_frame("c", np.zeros((16, 16), np.uint8))
    enc.cancel_episode()
    assert not [p for p in tmp_path.rglob("*.mp4")]  # cancelled episodes leave no video
