"""A scene's planned episodes in GPU calls that fit memory (the ``batch`` execution's GPU
side, :mod:`factory.demos.batch_execution`).

A call's recordings live in host memory (its frame buffers, in shared arenas the writers read,
:mod:`factory.demos.execute.shared_frames`), and, while the call runs, its images on the
device: :func:`gpu_calls` deals a scene's episodes over as few calls as fit a byte budget
(:func:`memory_budget`, :func:`device_budget`), each packed onto its worlds back to back;
:func:`split_tail` leaves the longest few to the CPU executor; :func:`populate_first_arena`
allocates the first call's arena while the first plans are made.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from factory.demos.execute.shared_frames import ArenaPool

__all__ = [
    "GPU_MEMORY_SHARE",
    "HOST_MEMORY_SHARE",
    "device_budget",
    "episode_bytes",
    "gpu_calls",
    "memory_budget",
    "populate_first_arena",
    "sizing_line",
    "split_tail",
]

log = logging.getLogger(__name__)


def populate_first_arena(pool: ArenaPool, nbytes: int) -> None:
    """Takes an arena of ``nbytes`` from ``pool``, allocates its pages
    (:meth:`~factory.demos.execute.shared_frames.Arena.populate`) and gives it back: run in a
    thread while the stage's first plans are made, so that the first call's image copy finds
    its pages there (about 16 s for 90 GB on an H200 node, on one core). No CUDA call: the
    copies go through :class:`~factory.demos.execute.staged_copy.StagedCopy`'s page-locked
    buffers, and the arena itself is never page-locked (locking 90 GB held the CUDA driver,
    and so the first scene's kernel loading, for 51 s)."""
    t0 = time.perf_counter()
    arena = pool.take(nbytes)
    try:
        populated = arena.populate(nbytes)
    finally:
        pool.give(arena)
    log.info(
        "%s %.1f GB of host memory for the first call's images in %.1f s",
        "allocated" if populated else "could not allocate ahead",
        nbytes / 1e9,
        time.perf_counter() - t0,
    )


HOST_MEMORY_SHARE = 0.35
"""Share of the host's available memory one GPU call's recordings may take (the call's frame
buffers; the episodes' recordings are views into them). The previous call's recordings may
still be in memory while they are written, so two calls take at most 70 % of it."""


GPU_MEMORY_SHARE = 0.6
"""Share of the device's free memory a call's images may take when they stay on the device
until the call ends (the rest: the worlds' physics data, the renderer and its buffers)."""


def memory_budget(share: float = HOST_MEMORY_SHARE) -> int | None:
    """Bytes one GPU call's recordings may take: ``share`` of the host's available memory now
    (None where the platform does not say)."""
    import os

    try:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):  # pragma: no cover - non-POSIX
        return None
    return int(share * avail)


def device_budget(device: str) -> int | None:
    """Bytes of a CUDA device's free memory a call's image store may take
    (:data:`GPU_MEMORY_SHARE`); None on the CPU."""
    import warp as wp

    dev = wp.get_device(device)
    return int(GPU_MEMORY_SHARE * dev.free_memory) if dev.is_cuda else None


def episode_bytes(plan: Any, rec_cfg: Any, timestep: float) -> int:
    """Bytes of host memory one episode's recording takes: ``frames x cameras x height x
    width`` pixels of RGB (3 bytes) and depth (2 or 4 bytes) plus small per-frame signals."""
    frames = len(plan.ctrl) * timestep * rec_cfg.fps + 2
    depth_bytes = 2 if rec_cfg.depth == "uint16_mm" else 4
    pixels = len(rec_cfg.cameras) * rec_cfg.height * rec_cfg.width if rec_cfg.render else 0
    return int(frames * (pixels * (3 + depth_bytes) + 4096))


def gpu_calls(
    planned: list[tuple[int, int, Any]],
    gpu_batch: int,
    rec_cfg: Any,
    timestep: float,
    scene_id: str = "",
    budget: int | None = None,
) -> list[tuple[list[tuple[int, int, Any]], int]]:
    """The planned episodes of a scene in GPU calls, and the worlds of each call.

    A call packs its episodes onto worlds back to back
    (:func:`~factory.demos.execute.world_schedule.packed_schedule`; at most ``gpu_batch`` worlds,
    and no more than keep the call about as long as its longest episode,
    :func:`~factory.demos.execute.world_schedule.worlds_for`), so episode lengths cost little
    padding and a scene needs one call as long as its recordings fit in memory: ``budget`` bytes per
    call (a share of host memory, and of device memory when images stay on the device). Where
    they do not, the episodes are dealt, longest first, over as few calls as fit, so that every
    call has the same mix of lengths.

    Args:
        planned: ``(slot, seed, EpisodePlan)`` of one scene.
        gpu_batch: most worlds per call.
        rec_cfg: the recording config (frames, cameras, image size).
        timestep: physics step (s).
        scene_id: for the log.
        budget: bytes of memory a call's recordings may take (None: :func:`memory_budget`).

    Returns:
        ``(episodes, worlds)`` per call.
    """
    if not planned:
        return []
    if budget is None:
        budget = memory_budget()
    order = sorted(planned, key=lambda item: (-len(item[2].ctrl), item[0]))
    size = [episode_bytes(p, rec_cfg, timestep) for _, _, p in order]
    calls = 1 if budget is None else max(1, -(-sum(size) // max(1, budget)))
    while True:
        groups = [order[j::calls] for j in range(calls)]
        used = [sum(size[j::calls]) for j in range(calls)]
        if budget is None or max(used) <= budget or calls >= len(order):
            break
        calls += 1
    from factory.demos.execute.world_schedule import worlds_for

    per_frame = max(1, round(1.0 / (rec_cfg.fps * timestep)))
    out = []
    for g in groups:
        frames = [-(-len(p.ctrl) // per_frame) + 1 for _, _, p in g]
        out.append((g, worlds_for(frames, gpu_batch)))
    log.info(
        "scene %s: %d episode(s) in %d GPU call(s) of %s episodes on %s worlds (at most "
        "demos.gpu_batch=%d); recordings %s GB a call, budget %s",
        scene_id,
        len(order),
        calls,
        "/".join(str(len(g)) for g in groups),
        "/".join(str(w) for _, w in out),
        gpu_batch,
        "/".join(f"{u / 1e9:.1f}" for u in used),
        "none" if budget is None else f"{budget / 1e9:.1f} GB",
    )
    return out


def sizing_line(
    device: str,
    budget: int | None,
    host: int | None,
    on_device: int | None,
    gpu_batch: int,
    images_on_device: bool,
    host_share: float = HOST_MEMORY_SHARE,
) -> str:
    """The GPU demos stage's sizing decision in one line: how many bytes a call's recordings
    may take and why (the host's share of its available memory, the device's share of its free
    memory where images stay on the device until a call ends), and the most worlds a call
    runs."""
    parts = []
    if host is not None:
        parts.append(f"host {host / 1e9:.1f} GB ({host_share:.0%} of its available memory)")
    if on_device is not None:
        share = f"{GPU_MEMORY_SHARE:.0%} of its free memory"
        parts.append(f"{device} {on_device / 1e9:.1f} GB ({share})")
    limit = "no limit" if budget is None else f"{budget / 1e9:.1f} GB"
    where = "on the device until the call ends" if images_on_device else "copied to the host"
    return (
        f"GPU sizing on {device}: a call's recordings may take {limit} (the least of: "
        f"{', '.join(parts) or 'nothing known'}); at most demos.gpu_batch={gpu_batch} worlds "
        f"a call; images {where}"
    )


def split_tail(
    planned: list[tuple[int, int, Any]], share: float
) -> tuple[list[tuple[int, int, Any]], list[tuple[int, int, Any]]]:
    """Splits a scene's planned episodes into those for the GPU and its longest ``share``
    (rounded down; ties broken by slot) for the CPU executor: a GPU call lasts as long as its
    longest episode, so a few long plans would lengthen the call of all the others.

    Args:
        planned: ``(slot, seed, EpisodePlan)`` of one scene.
        share: 0 to below 1.

    Returns:
        ``(for the GPU, for the CPU)``, each in the order of ``planned``.
    """
    n = int(share * len(planned))
    if n <= 0:
        return planned, []
    order = sorted(planned, key=lambda item: (-len(item[2].ctrl), item[0]))
    tail = {item[0] for item in order[:n]}
    return [p for p in planned if p[0] not in tail], [p for p in planned if p[0] in tail]
