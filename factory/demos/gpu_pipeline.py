"""``stage=demos`` with the GPU executor: planning in CPU worker processes feeding the GPU.

Scenes are taken one after another. The episode slots of a scene are planned in a pool of
``spawn``ed worker processes (one plan per task, each worker keeping the scene's planner), the
plans are executed and recorded together on the worlds of one MuJoCo Warp model
(:class:`~factory.demos.execute.warp.WarpExecutor`: up to ``demos.gpu_batch`` worlds per call,
each world taking its next episode as soon as its last one ends), and the successful
recordings are written by a few processes while the GPU goes on; they read the images in
place from the call's shared memory (:mod:`factory.demos.execute.shared_frames`). While the GPU
runs a
scene, the pool already plans the next scene's episodes, so neither waits for the other as long
as planning keeps up. Failed slots are planned again with their next seed
(``demos.attempts``), exactly as on the CPU path: the same seeds give the same plans, so the CPU
and GPU executors record the same episodes up to float32 physics. The few episodes that plan
but fail in execution (0.3-1 % of a kitchen's) are retried by the planner processes with the
CPU executor (``demos.gpu_retries=cpu``) while the GPU goes on to the next scene: a GPU call
of a dozen worlds would take as long per frame as one of a thousand.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import time
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any

from factory.demos.execute import shared_frames
from factory.demos.execute.shared_frames import ArenaPool, share
from factory.demos.slots import (
    StageEnv,
    WorkItem,
    cached_setup,
    episode_id,
    episode_instruction,
    episode_payload,
    episode_seed,
    item_stats,
    record_config,
    scene_planner,
    slots_by_scene,
    store_episode,
)
from factory.errors import FactoryError

log = logging.getLogger(__name__)


def plan_slot(
    env: StageEnv, scene_id: str, slot: int, attempt: int
) -> tuple[int, int, Any, int, list[tuple[str, str]], Any]:
    """Plans one episode slot in a worker, trying the slot's next seeds (attempts ``attempt``,
    ``attempt + 1``, ... below ``demos.attempts``) until one plans, as the CPU path does.

    Returns:
        ``(slot, seed, result, attempt, failed, look)``: the result is an ``EpisodePlan``, the
        last ``PlanFailure``, or a string (the scene cannot host the task, and why);
        ``attempt`` is the attempt of the result; ``failed`` the ``(reason, detail)`` of the
        attempts that did not plan; ``look`` the planned episode's appearance and model patch
        (:func:`~factory.demos.record.appearance.episode_looks` of its seed; None when nothing is
        rendered or the plan failed), drawn here so that the process feeding the GPU does
        not (1.5 ms an episode, ten times that on a busy node).
    """
    from factory.demos.record.appearance import episode_looks, setup_index
    from factory.tasks.pick_place.plan import EpisodePlan

    try:
        setup, planner = cached_setup(env, scene_id)
    except FactoryError as e:
        return slot, 0, str(e), attempt, [], None
    failed: list[tuple[str, str]] = []
    dc = env.demos
    while True:
        seed = episode_seed(env.seed, scene_id, slot, attempt)
        res = planner.plan_episode(seed, dc.randomize)
        if isinstance(res, EpisodePlan):
            look = None
            if dc.render:
                index = setup_index(setup, record_config(dc).cameras)
                (look,) = episode_looks(setup.model, index, dc.appearance, [seed])
            return slot, seed, res, attempt, failed, look
        failed.append((res.reason, res.detail))
        if attempt + 1 >= dc.attempts:
            return slot, seed, res, attempt, failed, None
        attempt += 1


def writer_count() -> int:
    """Processes writing (compressing) recorded episodes while the GPU goes on: all cores but
    two (2-14). They share the cores with the planners, which need about a third of a 16-core
    node in steady state; more writers shorten the stage's last writes, which nothing else
    overlaps (8 writers took 38 s for a scene's 1,536 episodes). Threads do not help: zarr runs
    every write of a process on one event loop, about 3 times the cost of the compression
    itself (0.25 s per 65 MB episode on one core)."""
    import os

    return max(2, min(14, (os.cpu_count() or 2) - 2))


def lock_first_arena(pool: ArenaPool, nbytes: int, device: str) -> None:
    """Takes an arena of ``nbytes`` from ``pool``, page-locks it for ``device`` and gives it
    back: run in a thread while the stage's first plans are made (nothing else uses the GPU
    then), so the first call's image copy finds locked pages. Locking fresh memory faults every
    page in first (about 40 s for 68 GB on an H200 node); the driver holds other CUDA calls
    meanwhile, which is why it must not overlap a GPU call."""
    import warp as wp

    t0 = time.perf_counter()
    arena = pool.take(nbytes)
    try:
        locked = arena.pin(nbytes, int(wp.get_device(device).context))
    finally:
        pool.give(arena)
    log.info(
        "page-locked %.1f GB of host memory for the first call's images: %s in %.1f s",
        nbytes / 1e9,
        "done" if locked else "refused",
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
    and
    no more than keep the call about as long as its longest episode,
    :func:`~factory.demos.execute.world_schedule.worlds_for`), so episode lengths cost little
    padding
    and a scene needs one call as long as its recordings fit in memory: ``budget`` bytes per
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
    if calls > 1:
        log.info(
            "scene %s: %d GPU calls of %s episodes (memory for the recordings: %.1f GB a call)",
            scene_id,
            calls,
            "/".join(str(len(g)) for g in groups),
            (budget or 0) / 1e9,
        )
    from factory.demos.execute.world_schedule import worlds_for

    per_frame = max(1, round(1.0 / (rec_cfg.fps * timestep)))
    out = []
    for g in groups:
        frames = [-(-len(p.ctrl) // per_frame) + 1 for _, _, p in g]
        out.append((g, worlds_for(frames, gpu_batch)))
    return out


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


def run_gpu(
    env: StageEnv, items: list[WorkItem], workers: int, bar: Any = None, device: str | None = None
) -> list[dict[str, Any]]:
    """Fills the slots of ``items`` with the GPU executor; one statistics dict per scene (the
    keys of :func:`factory.demos.cpu_items.run_item`'s)."""
    from factory.demos.execute.warp import WarpExecutor
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks.pick_place.plan import EpisodePlan

    dc = env.demos
    rec_cfg = record_config(dc)
    store = EpisodeStore(env.store_path)
    by_scene = slots_by_scene(items)
    scenes = list(by_scene)
    results: list[dict[str, Any]] = []
    ctx = mp.get_context("spawn")
    with (
        ProcessPoolExecutor(max(1, workers), mp_context=ctx, initializer=_init_worker) as pool,
        ProcessPoolExecutor(writer_count(), mp_context=ctx, initializer=_init_worker) as writers,
        ThreadPoolExecutor(1) as prep,
        ThreadPoolExecutor(1) as prep_pin,
    ):

        def submit(scene_id: str, slots: list[int], attempt: dict[int, int]) -> list[Future[Any]]:
            return [pool.submit(plan_slot, env, scene_id, k, attempt[k]) for k in slots]

        def to_cpu(
            out: dict[str, Any], scene_id: str, slots: list[int], at: dict[int, int]
        ) -> None:
            """Has the planner processes record ``slots`` with the CPU executor, from their
            attempts ``at``, in up to ``workers`` items (counted into ``out`` at the end)."""
            from factory.demos.cpu_items import run_item_logged

            for part in spread(slots, workers):
                item = WorkItem(scene_id, tuple(part))
                first = {k: at[k] for k in part}
                cpu_retries.append((out, len(part), pool.submit(run_item_logged, env, item, first)))

        def open_slots(scene_id: str) -> list[int]:
            return [k for k in by_scene[scene_id] if episode_id(scene_id, k) not in store]

        attempts = {s: dict.fromkeys(by_scene[s], 0) for s in scenes}
        # The CPU executor's runs of each scene's execution failures (gpu_retries=cpu).
        cpu_retries: list[tuple[dict[str, Any], int, Future[Any]]] = []
        pending: dict[str, list[Future[Any]]] = {}
        setups: dict[str, Future[Any]] = {}
        # Each GPU call's writes and the shared memory they read, oldest first.
        in_flight: list[tuple[list[Future[Any]], list[Any]]] = []

        # Images stay on the device during a call and go to host memory in one block at its
        # end, once the previous call's writes are done: one call's recordings in host memory
        # at a time (twice the share), and the device's memory bounds a call too.
        shared = shared_frames.supported()
        keep = shared and dc.gpu_images_on_device  # images on the device until a call ends
        budget = memory_budget(2 * HOST_MEMORY_SHARE if keep else HOST_MEMORY_SHARE)
        capacity = memory_budget(2 * HOST_MEMORY_SHARE)  # every arena together
        from factory.sim.backend import cuda_available

        dev = device or ("cuda:0" if cuda_available() else "cpu")
        on_device = device_budget(dev) if keep else None
        if on_device is not None:
            budget = on_device if budget is None else min(budget, on_device)

        def settle(writes: list[Future[Any]], arenas: list[Any]) -> None:
            for w in writes:
                w.result()
            for arena in arenas:
                assert arena_pool is not None
                arena_pool.give(arena)

        def reclaim() -> None:
            t_wait = time.perf_counter()
            while in_flight:
                settle(*in_flight.pop(0))
            reclaimed[0] += time.perf_counter() - t_wait

        reclaimed = [0.0]  # seconds the arena pool waited for writers

        arena_pool = ArenaPool(capacity or budget or 0, reclaim) if shared else None
        # The first call's arena is locked while the first plans are made (the GPU is idle).
        early: Future[Any] | None = None
        if arena_pool is not None and keep and budget and dev.startswith("cuda") and scenes:
            early = prep_pin.submit(lock_first_arena, arena_pool, budget, dev)

        if scenes:
            pending[scenes[0]] = submit(scenes[0], open_slots(scenes[0]), attempts[scenes[0]])
            setups[scenes[0]] = prep.submit(scene_planner, env.run_dir, scenes[0], dc)
        for idx, sid in enumerate(scenes):
            out: dict[str, Any] = item_stats(sid, executor="warp")
            results.append(out)
            futures = pending.pop(sid, [])
            if idx + 1 < len(scenes):
                nxt = scenes[idx + 1]
                pending[nxt] = submit(nxt, open_slots(nxt), attempts[nxt])
                setups[nxt] = prep.submit(scene_planner, env.run_dir, nxt, dc)
            try:
                setup, _ = setups.pop(sid).result()  # made while the GPU ran the last scene
            except FactoryError as e:
                for f in futures:
                    f.cancel()
                out["error"] = str(e)
                out["failures"]["scene_unusable"] += len(by_scene[sid])
                if bar is not None:
                    bar.update(len(by_scene[sid]))
                continue
            out["robot_base"] = [setup.placement.x, setup.placement.y, setup.placement.yaw]
            out["cleared"] = list(setup.cleared)
            instruction = episode_instruction(setup)
            executor = WarpExecutor(
                setup, rec_cfg, device=device, arenas=arena_pool, images_on_device=keep
            )
            attempt = attempts[sid]
            t_scene = time.perf_counter()
            waited = {"plans": 0.0, "writes": 0.0}
            reclaimed_before = reclaimed[0]
            while futures:
                planned: list[tuple[int, int, Any]] = []
                t_wait = time.perf_counter()
                for f in futures:
                    f.result()
                waited["plans"] += time.perf_counter() - t_wait
                looks_of: dict[int, Any] = {}
                for f in futures:
                    k, seed, res, attempt[k], failed, looks_of[k] = f.result()
                    for reason, detail in failed:
                        out["failures"][reason] += 1
                        log.info("scene %s slot %d: plan failed: %s", sid, k, detail)
                    if isinstance(res, EpisodePlan):
                        planned.append((k, seed, res))
                        out["plan"].append(res.seconds)
                        out["segments"].extend(res.plan_seconds.values())
                    elif isinstance(res, str):
                        out["failures"]["scene_unusable"] += 1
                done: set[int] = set()
                tail: list[int] = []  # slots whose plan the CPU executor records
                if dc.gpu_retries == "cpu" and dc.gpu_tail > 0:
                    planned, longest = split_tail(planned, dc.gpu_tail)
                    tail = [k for k, _, _ in longest]
                    to_cpu(out, sid, tail, attempt)  # the same seeds: the same plans again
                    out["cpu_tail"] = len(tail)
                if early is not None:  # the arena pool is this thread's again
                    t_wait = time.perf_counter()
                    early.result()
                    early = None
                    log.info("waited %.1f s for the first arena", time.perf_counter() - t_wait)
                for chunk, worlds in gpu_calls(
                    planned, dc.gpu_batch, rec_cfg, setup.model.opt.timestep, sid, budget
                ):
                    # Calls whose writes are done give their arenas back. The arena pool's
                    # byte budget bounds the recordings in memory (it waits for writers only
                    # when a call would exceed it); without arenas, at most two calls' worth.
                    while in_flight and all(w.done() for w in in_flight[0][0]):
                        settle(*in_flight.pop(0))
                    t_wait = time.perf_counter()
                    while arena_pool is None and len(in_flight) > 1:
                        settle(*in_flight.pop(0))
                    waited["writes"] += time.perf_counter() - t_wait
                    t0 = time.perf_counter()
                    looks = None
                    if rec_cfg.render:  # the episodes' appearances (seeded, drawn by planners)
                        looks = [looks_of[k] for k, _, _ in chunk]
                    recs = executor.execute([p for _, _, p in chunk], worlds=worlds, looks=looks)
                    arenas = executor.take_arenas()
                    out["simulate"] += time.perf_counter() - t0
                    writes: list[Future[Any]] = []
                    for (k, seed, plan), rec in zip(chunk, recs, strict=True):
                        assert rec.outcome is not None
                        if not rec.outcome.success:
                            out["failures"][rec.outcome.reason] += 1
                            continue
                        meta, arrays = episode_payload(
                            env, setup, k, seed, plan, rec, rec_cfg, instruction, "warp"
                        )
                        # Images stay in the shared arena: the writer maps them.
                        arrays = share(arrays, arenas)
                        writes.append(writers.submit(store_episode, str(store.path), meta, arrays))
                        out["frames"] += len(rec.time)
                        out["new"] += 1
                        done.add(k)
                    in_flight.append((writes, arenas))
                    del recs
                retry = []  # slots whose plan failed in execution: their next seed
                for k, _, res, _, _, _ in (f.result() for f in futures):
                    if k in done or k in tail or not isinstance(res, EpisodePlan):
                        continue
                    attempt[k] += 1
                    if attempt[k] < dc.attempts:
                        retry.append(k)
                if bar is not None:
                    bar.update(len(futures) - len(retry) - len(tail))
                if retry and dc.gpu_retries == "cpu":
                    to_cpu(out, sid, retry, attempt)
                    out["cpu_retries"] = len(retry)
                    retry = []
                futures = submit(sid, retry, attempt) if retry else []
            waited["writes"] += reclaimed[0] - reclaimed_before  # inside GPU calls
            out["warp_seconds"] = vars(executor.times)
            out["waited_s"] = waited
            log.info(
                "scene %s: %d new, %.1f s (GPU %.1f s, waiting for plans %.1f s, for earlier "
                "writes %.1f s)",
                sid,
                out["new"],
                time.perf_counter() - t_scene,
                out["simulate"],
                waited["plans"],
                waited["writes"],
            )
        t_wait = time.perf_counter()
        retried_new = 0
        for out, n, fut in cpu_retries:
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
        if cpu_retries:
            log.info(
                "CPU executor: %d episodes (%d longest, %d retries) of %d scenes, %d new; waited "
                "%.1f s for them at the end",
                sum(n for _, n, _ in cpu_retries),
                sum(r.get("cpu_tail", 0) for r in results),
                sum(r.get("cpu_retries", 0) for r in results),
                len({id(r) for r, _, _ in cpu_retries}),
                retried_new,
                time.perf_counter() - t_wait,
            )
        for writes, arenas in in_flight:
            settle(writes, arenas)
        if arena_pool is not None:
            arena_pool.close()
    return results
