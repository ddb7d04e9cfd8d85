"""Every frame of a LeRobot dataset's video features, decoded once into memory.

``LeRobotDataset.__getitem__`` decodes the frames of a sample from the videos on each call: it
seeks to the key frame before the wanted time and decodes forward (PyAV cannot seek to a
frame), for every camera and observation step. For the factory's short 128 x 128 streams that
is tens of milliseconds per frame, so an RGB-D policy (six streams, two observation steps)
waited on decoding, not on the GPU. Decoding each video file once, front to back, takes
seconds; the frames then live in memory as uint8 RGB (H, W, 3) and depth as uint16 millimetres
(H, W), about 49 kB and 33 kB a frame at 128 x 128.

Frames are placed by the dataset's own bookkeeping: episode ``e``'s frames of a video key are
the file's frames from ``round(from_timestamp * fps)`` on (``meta/episodes``), at dataset
indices ``dataset_from_index .. dataset_to_index``. ``tests/policy/test_train.py`` checks that
samples read from here equal ``LeRobotDataset``'s own.
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import PolicyError

log = logging.getLogger(__name__)

DEPTH_PREFIX = "observation.depth."


def frame_bytes(keys: list[str], shape: tuple[int, int]) -> int:
    """Bytes per dataset frame of the decoded ``keys`` ((H, W) images)."""
    h, w = shape
    return sum(h * w * (2 if k.startswith(DEPTH_PREFIX) else 3) for k in keys)


def available_bytes() -> int:
    """Memory the system has available now (``MemAvailable``; physical pages elsewhere)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))


def _decode_file(path: Path) -> np.ndarray:
    """All frames of a video file as (F, H, W, 3) uint8 RGB."""
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
    if not frames:
        raise PolicyError(f"{path} holds no video frames: re-run stage=dataset force=true")
    return np.stack(frames)


def decode_videos(base: Any, keys: list[str], workers: int = 0) -> dict[str, np.ndarray]:
    """The frames of ``keys`` for every frame of a loaded ``LeRobotDataset``, in dataset order.

    Args:
        base: the ``LeRobotDataset`` (its ``meta`` and ``root``).
        keys: video feature keys; depth keys (``observation.depth.*``) come back as uint16 mm.
        workers: decoding threads (0: one per core).

    Returns:
        key -> (N, H, W, 3) uint8 RGB, or (N, H, W) uint16 mm for depth; N = dataset frames.

    Raises:
        PolicyError: a video is shorter than its episodes say.
    """
    meta = base.meta
    eps = meta.episodes
    fps = float(meta.fps)
    n = int(eps["dataset_to_index"][-1]) if len(eps["dataset_to_index"]) else 0
    jobs: dict[tuple[str, Path], list[tuple[int, int, int]]] = {}
    for key in keys:
        for e in range(len(eps["episode_index"])):
            path = Path(base.root) / meta.get_video_file_path(e, key)
            start = int(eps["dataset_from_index"][e])
            length = int(eps["dataset_to_index"][e]) - start
            first = round(float(eps[f"videos/{key}/from_timestamp"][e]) * fps)
            jobs.setdefault((key, path), []).append((start, length, first))
    out: dict[str, np.ndarray] = {}

    def one(item: tuple[tuple[str, Path], list[tuple[int, int, int]]]) -> None:
        (key, path), spans = item
        frames = _decode_file(path)
        depth = key.startswith(DEPTH_PREFIX)
        for start, length, first in spans:
            clip = frames[first : first + length]
            if len(clip) != length:
                raise PolicyError(
                    f"{path} has {len(frames)} frames, fewer than its episodes need "
                    f"({first + length}): re-run stage=dataset force=true"
                )
            if depth:
                clip = (clip[..., 0].astype(np.uint16) << 8) | clip[..., 1].astype(np.uint16)
            out[key][start : start + length] = clip

    for key in keys:
        h, w = meta.features[key]["shape"][:2]
        shape = (n, h, w) if key.startswith(DEPTH_PREFIX) else (n, h, w, 3)
        out[key] = np.empty(shape, np.uint16 if key.startswith(DEPTH_PREFIX) else np.uint8)
    with ThreadPoolExecutor(workers or os.cpu_count() or 1) as pool:
        list(pool.map(one, jobs.items()))
    return out
