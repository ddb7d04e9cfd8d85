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
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from factory.cores import usable_cores
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


PROCESS_MIN_FRAMES = 20_000
"""Decoded frames (all keys together) from which the files are decoded in worker processes
rather than threads. Threads with PyAV's own frame threading decoded 58,494 frames x 6 streams
in 89 s on 16 cores (H200 node): 3,900 frames/s in all, less than one single-threaded decoder
alone (about 8,700 frames/s of these 128 px streams on one core); the frame conversion holds
Python's lock. Below this many frames the processes' start-up (about a second) costs more."""


def _decode_file(path: Path) -> np.ndarray:
    """All frames of a video file as (F, H, W, 3) uint8 RGB, decoded on one thread (the
    files are decoded side by side)."""
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        stream.thread_count = 1
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
    if not frames:
        raise PolicyError(f"{path} holds no video frames: re-run stage=dataset force=true")
    return np.stack(frames)


def _decode_key_file(path: str, depth: bool) -> np.ndarray:
    """A file's frames: (F, H, W, 3) uint8 RGB, or (F, H, W) uint16 millimetres for a packed
    depth video (``mm = 256 * R + G``)."""
    frames = _decode_file(Path(path))
    if depth:
        return (frames[..., 0].astype(np.uint16) << 8) | frames[..., 1].astype(np.uint16)
    return frames


def decode_videos(base: Any, keys: list[str], workers: int = 0) -> dict[str, np.ndarray]:
    """The frames of ``keys`` for every frame of a loaded ``LeRobotDataset``, in dataset order.

    Args:
        base: the ``LeRobotDataset`` (its ``meta`` and ``root``).
        keys: video feature keys; depth keys (``observation.depth.*``) come back as uint16 mm.
        workers: files decoded at once (0: one per core); in worker processes from
            :data:`PROCESS_MIN_FRAMES` frames on, else in threads.

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
    for key in keys:
        h, w = meta.features[key]["shape"][:2]
        shape = (n, h, w) if key.startswith(DEPTH_PREFIX) else (n, h, w, 3)
        out[key] = np.empty(shape, np.uint16 if key.startswith(DEPTH_PREFIX) else np.uint8)

    def place(key: str, path: Path, frames: np.ndarray) -> None:
        for start, length, first in jobs[(key, path)]:
            clip = frames[first : first + length]
            if len(clip) != length:
                raise PolicyError(
                    f"{path} has {len(frames)} frames, fewer than its episodes need "
                    f"({first + length}): re-run stage=dataset force=true"
                )
            out[key][start : start + length] = clip

    items = list(jobs)
    count = min(workers or usable_cores(), len(items)) or 1
    if count > 1 and n * len(keys) >= PROCESS_MIN_FRAMES:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(count, mp_context=ctx) as pool:
            pending = {
                pool.submit(_decode_key_file, str(path), key.startswith(DEPTH_PREFIX)): (key, path)
                for key, path in items
            }
            for fut in as_completed(list(pending)):
                key, path = pending.pop(fut)  # the file's frames go as soon as they are placed
                place(key, path, fut.result())
        return out

    def one(item: tuple[str, Path]) -> None:
        key, path = item
        place(key, path, _decode_key_file(str(path), key.startswith(DEPTH_PREFIX)))

    with ThreadPoolExecutor(count) as threads:
        list(threads.map(one, items))
    return out
