"""``stage=demos`` with the GPU executor: planner processes feeding the GPU, for every task.

Scenes are taken one after another. The episode slots of a scene are submitted to a pool of
``spawn``ed planner processes (each keeping the scenes it works in,
:func:`~factory.demos.execution.cached_scene`) ahead of the GPU: the next scene's while the
GPU runs this one, and more while fewer than the execution's
:attr:`~factory.demos.execution.Execution.queue_per_worker` slots per process are pending, so
neither waits for the other as long as planning keeps up. Meanwhile a thread of the main
process sets up the next scene for the GPU (the task's scene without its planner). What the
processes do per slot and what the GPU does per scene is the task's execution model
(:mod:`factory.demos.execution`: :mod:`~factory.demos.batch_execution` plans in the processes
and executes and draws on MuJoCo Warp's worlds; :mod:`~factory.demos.episode_execution` plans
and simulates in the processes and draws on the GPU). Successful recordings are written by a
few writer processes while the GPU goes on; slots the execution hands back run on the CPU
executor in the planner processes (:func:`~factory.demos.cpu_items.run_item_logged`) and are
counted into their scene at the end.

Per scene the statistics record ``executor="warp"``, the seconds waited for plans and for
earlier writes (``waited_s``) and the GPU's; each scene logs one line (``scene <id>: <n> new,
<s> s (GPU <s> s, waiting for plans <s> s, for earlier writes <s> s)``).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import time
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any

from factory.demos.execution import GpuRun, SlotResult, execution_of
from factory.demos.record.disk_room import DiskFull, DiskRoom
from factory.demos.record.slots import (
    StageEnv,
    WorkItem,
    episode_id,
    item_stats,
    slots_by_scene,
)
from factory.errors import FactoryError

__all__ = ["WORKER_NICENESS", "run_gpu", "spread", "writer_count"]

log = logging.getLogger(__name__)


def writer_count() -> int:
    """Processes writing (compressing) recorded episodes while the GPU goes on: all cores but
    two (2-14). They share the cores with the planners, which need about a third of a 16-core
    node in steady state; more writers shorten the stage's last writes, which nothing else
    overlaps (8 writers took 38 s for a scene's 1,536 episodes). Threads do not help: zarr runs
    every write of a process on one event loop, about 3 times the cost of the compression
    itself (0.25 s per 65 MB episode on one core)."""
    from factory.cores import usable_cores

    return max(2, min(14, usable_cores() - 2))


def spread(slots: list[int], workers: int) -> list[list[int]]:
    """``slots`` in at most ``workers`` work items of nearly equal size (in order), so that
    the CPU executor records them in parallel."""
    parts = max(1, min(len(slots), workers))
    return [slots[j::parts] for j in range(parts)] if slots else []


WORKER_NICENESS = 10
"""Niceness of the planner and writer processes: the process feeding the GPU is the stage's
critical path (its set-up, appearance tables and filing are CPU work), while planners and
writers keep ahead of it with time to spare; at equal priority, 30 busy processes on a 16-core
node slowed its CPU work about tenfold."""


def _init_worker() -> None:
    import contextlib
    import os

    logging.basicConfig(level=logging.WARNING)
    with contextlib.suppress(AttributeError, OSError):  # platforms without nice
        os.nice(WORKER_NICENESS)


def _merge_cpu_runs(cpu_runs: list[tuple[dict[str, Any], int, Future[Any]]], bar: Any) -> None:
    """Counts the CPU executor's runs into their scenes' statistics (``cpu_retry_seconds``:
    their simulation and rendering seconds), once they are done."""
    t_wait = time.perf_counter()
    retried_new = 0
    for out, n, fut in cpu_runs:
        got = fut.result()
        retried_new += got["new"]
        for key in ("new", "frames"):
            out[key] += got[key]
        out["failures"].update(got["failures"])
        out["plan"].extend(got["plan"])
        out["segments"].extend(got["segments"])
        cpu_s = out.setdefault("cpu_retry_seconds", {"simulate": 0.0, "render": 0.0})
        cpu_s["simulate"] += got["simulate"]
        cpu_s["render"] += got["render"]
        if bar is not None:
            bar.update(n)
    if cpu_runs:
        scenes = {id(r): r for r, _, _ in cpu_runs}.values()
        log.info(
            "CPU executor: %d episodes (%d longest, %d retries) of %d scenes, %d new; waited "
            "%.1f s for them at the end",
            sum(n for _, n, _ in cpu_runs),
            sum(r.get("cpu_tail", 0) for r in scenes),
            sum(r.get("cpu_retries", 0) for r in scenes),
            len(scenes),
            retried_new,
            time.perf_counter() - t_wait,
        )


def run_gpu(
    env: StageEnv,
    items: list[WorkItem],
    workers: int,
    bar: Any = None,
    device: str | None = None,
    room: DiskRoom | None = None,
) -> list[dict[str, Any]]:
    """Fills the slots of ``items`` with the GPU executor: ``workers`` planner processes, the
    GPU of ``device`` (Warp's; default CUDA when present), writer processes. One statistics
    dict per scene (the keys of :func:`factory.demos.cpu_items.run_item`'s).

    Raises:
        DiskFull: before a scene, ``room`` finds that the episodes left would not fit on the
            store's disk (the planner processes' queued slots are cancelled; the writers finish
            the episodes already recorded).
    """
    from factory.demos.cpu_items import run_item_logged
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks import get_task

    task = get_task(env.task)
    execution = execution_of(task)
    work_slot = execution.slot_worker
    store = EpisodeStore(env.store_path)
    by_scene = slots_by_scene(items)
    scenes = list(by_scene)
    results: list[dict[str, Any]] = []
    if not scenes:
        return results
    ctx = mp.get_context("spawn")
    nwriters = writer_count()
    with (
        ProcessPoolExecutor(max(1, workers), mp_context=ctx, initializer=_init_worker) as pool,
        ProcessPoolExecutor(nwriters, mp_context=ctx, initializer=_init_worker) as writers,
        ThreadPoolExecutor(1) as prep,
    ):
        # The CPU executor's runs of slots the execution hands back (its longest, its retries).
        cpu_runs: list[tuple[dict[str, Any], int, Future[Any]]] = []
        attempts = {s: dict.fromkeys(by_scene[s], 0) for s in scenes}
        pending: dict[str, list[Future[SlotResult]]] = {}
        setups: dict[str, Future[Any]] = {}
        ahead = [0]  # index of the next scene to submit

        def submit(scene_id: str, slots: list[int], at: dict[int, int]) -> list[Future[SlotResult]]:
            return [pool.submit(work_slot, env, scene_id, k, at[k]) for k in slots]

        def to_cpu(
            out: dict[str, Any], scene_id: str, slots: list[int], at: dict[int, int]
        ) -> None:
            """Has the planner processes record ``slots`` with the CPU executor, from their
            attempts ``at``, in up to ``workers`` items (counted into ``out`` at the end)."""
            for part in spread(slots, workers):
                item = WorkItem(scene_id, tuple(part))
                first = {k: at[k] for k in part}
                cpu_runs.append((out, len(part), pool.submit(run_item_logged, env, item, first)))

        def set_up(scene_id: str) -> Any:
            """The scene set up without its planner, and readied for its GPU calls (its
            kernels compiled) while the scene before records on the GPU."""
            scene = task.demo_scene(env, scene_id, False)
            gpu.prepare(scene)
            return scene

        def submit_ahead(current: int) -> None:
            """Submits scenes until the next one is in and enough slots are pending."""
            while ahead[0] < len(scenes):
                queued = sum(len(f) for f in pending.values())
                if ahead[0] > current + 1 and queued >= execution.queue_per_worker * max(
                    1, workers
                ):
                    break
                sid = scenes[ahead[0]]
                todo = [k for k in by_scene[sid] if episode_id(sid, k) not in store]
                pending[sid] = submit(sid, todo, attempts[sid])
                setups[sid] = prep.submit(set_up, sid)
                ahead[0] += 1

        gpu = execution.gpu_recorder(
            GpuRun(env, pool, writers, nwriters, bar, device, submit, to_cpu)
        )
        for idx, sid in enumerate(scenes):
            if room is not None:
                try:
                    room.check(len(store), sum(len(by_scene[s]) for s in scenes[:idx]))
                except DiskFull:
                    for fs in pending.values():
                        for f in fs:
                            f.cancel()
                    gpu.close()  # the episodes recorded are written
                    raise
            out: dict[str, Any] = item_stats(sid, executor="warp")
            results.append(out)
            submit_ahead(idx)
            futures = pending.pop(sid)
            t_scene = time.perf_counter()
            waited = {"plans": 0.0, "writes": 0.0}
            try:
                scene = setups.pop(sid).result()  # made while the GPU ran the last scene
            except FactoryError as e:
                for f in futures:
                    f.cancel()
                out["error"] = str(e)
                out["failures"]["scene_unusable"] += len(by_scene[sid])
                if bar is not None:
                    bar.update(len(by_scene[sid]))
                continue
            out.update(scene.summary())
            gpu_seconds = gpu.record_scene(scene, futures, attempts[sid], out, waited)
            out["waited_s"] = waited
            log.info(
                "scene %s: %d new, %.1f s (GPU %.1f s, waiting for plans %.1f s, for earlier "
                "writes %.1f s)",
                sid,
                out["new"],
                time.perf_counter() - t_scene,
                gpu_seconds,
                waited["plans"],
                waited["writes"],
            )
        _merge_cpu_runs(cpu_runs, bar)
        gpu.close()
    return results
