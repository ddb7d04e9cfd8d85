"""Small animated GIFs: from an episode's recorded frames, and from rollout videos.

GIFs (not videos) because every browser shows them in an ``<img>``, offline, with no codec.
They are kept small: subsampled to ``fps``, scaled to ``size`` px on their longest side, and
thinned further until they fit in ``max_bytes``.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

MAX_BYTES = 1_000_000
"""A GIF larger than this is thinned (every other frame) until it fits."""

COLORS = 128
"""Entries of a GIF's palette (one palette for all its frames): 127 colours and the
transparent index that marks a pixel unchanged from the frame before."""
TRANSPARENT = COLORS - 1


def subsample(n_frames: int, src_fps: float, fps: float) -> list[int]:
    """Indices of the frames that play ``n_frames`` frames at ``src_fps`` Hz at ``fps`` Hz.

    Returns:
        increasing frame indices, the first always 0 (all frames if ``fps >= src_fps``).
    """
    if n_frames <= 0:
        return []
    if fps >= src_fps:
        return list(range(n_frames))
    duration = n_frames / src_fps
    picks = [min(n_frames - 1, round(k * src_fps / fps)) for k in range(math.ceil(duration * fps))]
    return sorted(set(picks))


def to_gif(
    frames: Sequence[np.ndarray] | np.ndarray,
    fps: float,
    size: int,
    max_bytes: int = MAX_BYTES,
) -> bytes:
    """Encodes RGB frames as a looping GIF.

    Args:
        frames: (H, W, 3) uint8 images, already at the GIF's rate.
        fps: playback rate (Hz).
        size: longest side of the GIF (px); frames are scaled down to it, never up.
        max_bytes: thin the frames (every other one, slower playback kept in real time) until
            the GIF is at most this large, or one frame is left.

    Returns:
        the GIF's bytes.

    Raises:
        ValueError: no frames.
    """
    from PIL import Image

    if len(frames) == 0:
        raise ValueError("a GIF needs at least one frame")
    h, w = frames[0].shape[:2]
    scale = min(1.0, size / max(h, w))
    out_size = (max(1, round(w * scale)), max(1, round(h * scale)))
    rgb = []
    for f in frames:
        im = Image.fromarray(np.ascontiguousarray(f[..., :3]).astype(np.uint8), "RGB")
        if im.size != out_size:
            im = im.resize(out_size, Image.Resampling.LANCZOS)
        rgb.append(im)
    # One palette for all frames (from up to 16 of them, stacked), no dithering: unchanged
    # pixels keep their index, so each frame stores only the box that changed (~2x smaller),
    # and inside it a pixel equal to the frame before is the transparent index (frames are
    # not disposed, so the one before shows through): long runs of it compress well, another
    # ~2x for a moving camera (a mobile episode's five views: 7.2 -> 3.5 MB).
    sample = rgb[:: max(1, len(rgb) // 16)]
    strip = Image.fromarray(np.concatenate([np.asarray(im) for im in sample], axis=0), "RGB")
    palette = strip.quantize(colors=COLORS - 1, method=Image.Quantize.MEDIANCUT)
    indices = [np.asarray(im.quantize(palette=palette, dither=Image.Dither.NONE)) for im in rgb]
    colors = (palette.getpalette() or [])[: 3 * (COLORS - 1)]
    colors += [0] * (3 * COLORS - len(colors))  # the last entry: transparent
    step = 1
    while True:
        picked = indices[::step]
        images = []
        for k, idx in enumerate(picked):
            frame = idx.copy()
            if k:
                frame[idx == picked[k - 1]] = TRANSPARENT
            im = Image.fromarray(frame.astype(np.uint8), "P")
            im.putpalette(colors)
            images.append(im)
        buf = io.BytesIO()
        images[0].save(
            buf,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=max(20, round(1000 * step / fps)),
            loop=0,
            optimize=False,
            disposal=1,
            transparency=TRANSPARENT,
        )
        data = buf.getvalue()
        if len(data) <= max_bytes or len(picked) == 1:
            return data
        step *= 2


def episode_gif(
    store: Path, episode_id: str, camera: str, fps: float, size: int
) -> tuple[bytes, str]:
    """A GIF of one stored episode's RGB frames.

    Args:
        store: the episode store (``episodes/shard-<k>.zarr``).
        episode_id: the episode.
        camera: the camera (empty: the episode's first; one it lacks: its first too).
        fps: GIF rate (Hz); size: longest side (px).

    Returns:
        the GIF's bytes and the camera shown.

    Raises:
        StoreError: the store or episode cannot be read (zarr missing, no such episode).
        KeyError: the episode has no RGB frames (recorded with ``demos.render=false``).
    """
    from factory.demos.record.episodes import EpisodeStore

    episodes = EpisodeStore(store)
    info = episodes.info(episode_id)
    cam = camera if camera in info.cameras else (info.cameras[0] if info.cameras else camera)
    rgb = episodes.arrays(episode_id)[f"rgb/{cam}"]
    idx = subsample(int(rgb.shape[0]), float(info.fps), fps)
    frames = np.asarray(rgb.oindex[idx])
    return to_gif(frames, min(fps, float(info.fps)), size), cam


def video_gif(path: Path, fps: float, size: int) -> bytes:
    """A GIF of a video file (mp4 decoded with PyAV; a GIF is re-encoded smaller if needed).

    Raises:
        ImportError: PyAV is not installed (an mp4 needs it).
        OSError, ValueError: the file cannot be decoded or has no frames.
    """
    if path.suffix.lower() == ".gif":
        from PIL import Image, ImageSequence

        data = path.read_bytes()
        if len(data) <= MAX_BYTES:
            return data
        with Image.open(path) as im:
            gif_frames = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]
            gif_fps = 1000.0 / max(20, int(im.info.get("duration", 100)))
        idx = subsample(len(gif_frames), gif_fps, fps)
        return to_gif([gif_frames[i] for i in idx], min(fps, gif_fps), size)
    import av

    frames: list[np.ndarray] = []
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        src_fps = float(stream.average_rate or 20)
        next_t = 0.0
        for k, frame in enumerate(container.decode(stream)):
            t = float(frame.time) if frame.time is not None else k / src_fps
            if t + 1e-6 >= next_t:
                frames.append(frame.to_ndarray(format="rgb24"))
                next_t += 1.0 / fps
    if not frames:
        raise ValueError(f"{path.name}: no frames")
    return to_gif(frames, min(fps, src_fps), size)
