"""The ``batch`` execution of ``stage=demos``: a scene's plans are open-loop control sequences,
executed and recorded together on a batch of worlds (the fixed-base task).

* CPU (:class:`BatchCpu`): one ``mujoco.batch`` of an item's planned episodes per round,
  images drawn with OpenGL (:func:`factory.demos.execute.cpu.execute`).
* GPU pipeline: the planner processes plan a slot from its next seeds and draw the planned episode's
  appearance (:func:`plan_slot`); the main process (:class:`BatchGpu`) takes a scene's plans
  together, leaves the longest share to the CPU executor (``demos.gpu_tail``), executes the rest on
  the worlds of one MuJoCo Warp model in as few calls as memory allows
  (:class:`~factory.demos.execute.warp.WarpExecutor`,
  :func:`~factory.demos.execute.gpu_calls.gpu_calls`), and hands the successes to the writers, which
  read the images in place from the call's shared memory
  (:mod:`factory.demos.execute.shared_frames`). Slots whose plan failed in execution go on with
  their next seed: on the CPU executor (``demos.gpu_retries=cpu``, while the GPU goes on to the next
  scene: a GPU call of a dozen worlds would take as long per frame as one of a thousand) or planned
  again for the GPU. The same seeds give the same plans, so the CPU and GPU executors record the
  same episodes up to float32 physics.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from factory.config import DemosConfig
from factory.demos.execute import shared_frames
from factory.demos.execute.gpu_calls import (
    HOST_MEMORY_SHARE,
    device_budget,
    gpu_calls,
    memory_budget,
    populate_first_arena,
    sizing_line,
    split_tail,
)
from factory.demos.execute.shared_frames import ArenaPool, share
from factory.demos.execution import (
    CpuRecorder,
    Execution,
    GpuRecorder,
    GpuRun,
    SlotResult,
    cached_scene,
    store_episode,
    tally,
)
from factory.demos.record.scene import DemoScene
from factory.demos.record.slots import StageEnv, episode_seed
from factory.errors import FactoryError
from factory.sim.kernel_preload import PreloadReport

__all__ = ["BATCH", "BatchCpu", "BatchGpu", "plan_slot", "record_config", "warm_up_scene"]

log = logging.getLogger(__name__)


def record_config(dc: DemosConfig) -> Any:
    """The recording settings of ``demos.*`` (a
    :class:`~factory.demos.execute.cpu.RecordConfig`)."""
    from factory.demos.execute.cpu import RecordConfig

    return RecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=tuple(dc.cameras),
        depth=dc.depth,
        render=dc.render,
        shadows=dc.shadows,
    )


class BatchCpu(CpuRecorder):
    """A round's plans in one ``mujoco.batch`` (``env.nthread`` threads), each episode drawn
    with its appearance (``demos.appearance``, seeded by the episode's seed)."""

    def __init__(self, scene: DemoScene, env: StageEnv) -> None:
        from factory.demos.execute.cpu import FrameRenderer
        from factory.demos.record.appearance import setup_index

        self.scene, self.env = scene, env
        self.rec_cfg = record_config(env.demos)
        model = scene.setup.model
        self.renderer = FrameRenderer(model, self.rec_cfg) if self.rec_cfg.render else None
        self.look_index = (
            setup_index(scene.setup, self.rec_cfg.cameras) if self.rec_cfg.render else None
        )

    def execute(self, planned: list[tuple[int, int, Any]], attempt: dict[int, int]) -> list[Any]:
        from factory.demos.execute.cpu import execute
        from factory.demos.record.appearance import episode_looks

        setup = self.scene.setup
        looks = None
        if self.look_index is not None:
            seeds = [seed for _, seed, _ in planned]
            looks = episode_looks(setup.model, self.look_index, self.env.demos.appearance, seeds)
        plans = [p for _, _, p in planned]
        return execute(setup, plans, self.rec_cfg, self.env.nthread, self.renderer, looks)

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.close()


def plan_slot(env: StageEnv, scene_id: str, slot: int, attempt: int) -> SlotResult:
    """Plans one episode slot in a planner process, trying the slot's next seeds (attempts
    ``attempt``, ``attempt + 1``, ... below ``demos.attempts``) until one plans, as the CPU
    path does. The planned episode's appearance and model patch
    (:func:`~factory.demos.record.appearance.episode_looks` of its seed; when images are
    drawn) are drawn here so that the process feeding the GPU does not (1.5 ms an episode,
    ten times that on a busy node)."""
    from factory.demos.record.appearance import episode_looks, setup_index

    out = SlotResult(slot, attempt=attempt)
    try:
        scene = cached_scene(env, scene_id)
    except FactoryError as e:
        out.error = str(e)
        return out
    dc = env.demos
    while True:
        out.attempt, out.seed = attempt, episode_seed(env.seed, scene_id, slot, attempt)
        res = scene.plan(out.seed)
        if isinstance(res, scene.plan_type):
            out.plan = res
            out.plan_seconds.append(res.seconds)
            out.segments.extend(res.plan_seconds.values())
            if dc.render:
                index = setup_index(scene.setup, record_config(dc).cameras)
                (out.look,) = episode_looks(scene.setup.model, index, dc.appearance, [out.seed])
            return out
        out.failures.append((res.reason, res.detail))
        if attempt + 1 >= dc.attempts:
            return out
        attempt += 1


class BatchGpu(GpuRecorder):
    """The main process of the GPU pipeline for the ``batch`` execution (one per run).

    Images stay on the device during a call (``demos.gpu_images_on_device``, where shared
    memory works) and go to host memory in one block at its end, once the previous call's
    writes are done: one call's recordings in host memory at a time (twice the share), and the
    device's memory bounds a call too. Calls whose writes are done give their arenas back; the
    arena pool's byte budget bounds the recordings in memory (it waits for writers only when a
    call would exceed it); without arenas, at most two calls' worth are in memory.
    """

    def __init__(self, run: GpuRun) -> None:
        from factory.sim.backend import cuda_available

        self.run = run
        self.rec_cfg = record_config(run.env.demos)
        self.shared = shared_frames.supported()
        self.keep = self.shared and run.env.demos.gpu_images_on_device
        share = 2 * HOST_MEMORY_SHARE if self.keep else HOST_MEMORY_SHARE
        budget = memory_budget(share)
        capacity = memory_budget(2 * HOST_MEMORY_SHARE)  # every arena together
        dev = run.device or ("cuda:0" if cuda_available() else "cpu")
        on_device = device_budget(dev) if self.keep else None
        host = budget
        if on_device is not None:
            budget = on_device if budget is None else min(budget, on_device)
        self.budget = budget
        log.info(
            sizing_line(
                dev, budget, host, on_device, run.env.demos.gpu_batch, bool(self.keep), share
            )
        )
        # Executors made and warmed up ahead in the set-up thread, by scene id (at most two).
        self._prepared: dict[str, Any] = {}
        self._lock = threading.Lock()
        # Each GPU call's writes and the shared memory they read, oldest first.
        self.in_flight: list[tuple[list[Future[Any]], list[Any]]] = []
        self.reclaimed = 0.0  # seconds the arena pool waited for writers
        self.arena_pool = ArenaPool(capacity or budget or 0, self._reclaim) if self.shared else None
        # The first call's arena gets its pages while the first plans are made.
        self.early: Future[Any] | None = None
        self._populate: ThreadPoolExecutor | None = None
        if self.arena_pool is not None and self.keep and budget and dev.startswith("cuda"):
            self._populate = ThreadPoolExecutor(1)
            self.early = self._populate.submit(populate_first_arena, self.arena_pool, budget)

    def _executor(self, scene: DemoScene) -> Any:
        from factory.demos.execute.warp import WarpExecutor

        return WarpExecutor(
            scene.setup,
            self.rec_cfg,
            device=self.run.device,
            arenas=self.arena_pool,
            images_on_device=self.keep,
        )

    def prepare(self, scene: DemoScene) -> None:
        """Makes the scene's executor and compiles its kernels (:meth:`WarpExecutor.warm_up`),
        in the set-up thread: a later scene's kernels (MuJoCo Warp specialises some to the
        model's degrees of freedom: 21-33 s of an H100 node per scene) compile while the scene
        before runs on the GPU. An error is logged; :meth:`record_scene` then makes the
        executor again and shows it."""
        try:
            executor = self._executor(scene)
            executor.warm_up()
        except Exception as e:
            log.warning(
                "demos %s: readying the GPU executor ahead failed (%s: %s); it is made when the "
                "scene's turn comes",
                scene.scene_id,
                type(e).__name__,
                e,
            )
            return
        with self._lock:
            self._prepared[scene.scene_id] = executor

    def _settle(self, writes: list[Future[Any]], arenas: list[Any]) -> None:
        for w in writes:
            w.result()
        for arena in arenas:
            assert self.arena_pool is not None
            self.arena_pool.give(arena)

    def _reclaim(self) -> None:
        t_wait = time.perf_counter()
        while self.in_flight:
            self._settle(*self.in_flight.pop(0))
        self.reclaimed += time.perf_counter() - t_wait

    def record_scene(
        self,
        scene: DemoScene,
        futures: list[Future[SlotResult]],
        attempt: dict[int, int],
        out: dict[str, Any],
        waited: dict[str, float],
    ) -> float:
        """Takes the scene's plans together, executes them in GPU calls, retries the slots
        that failed in execution (see the class); returns the GPU seconds."""

        run, rec_cfg, dc = self.run, self.rec_cfg, self.run.env.demos
        sid = scene.scene_id
        with self._lock:
            executor = self._prepared.pop(sid, None)
        if executor is None:  # not prepared, or its preparation failed
            executor = self._executor(scene)
        reclaimed_before = self.reclaimed
        executor.warm_up()  # the kernels compile while the scene's plans are made (if not yet)
        while futures:
            t_wait = time.perf_counter()
            results = [f.result() for f in futures]
            waited["plans"] += time.perf_counter() - t_wait
            planned: list[tuple[int, int, Any]] = []
            looks_of: dict[int, Any] = {}
            for res in results:
                attempt[res.slot] = res.attempt
                looks_of[res.slot] = res.look
                tally(out, res)
                if res.plan is not None:
                    planned.append((res.slot, res.seed, res.plan))
            done: set[int] = set()
            tail: list[int] = []  # slots whose plan the CPU executor records
            if dc.gpu_retries == "cpu" and dc.gpu_tail > 0:
                planned, longest = split_tail(planned, dc.gpu_tail)
                tail = [k for k, _, _ in longest]
                run.to_cpu(out, sid, tail, attempt)  # the same seeds: the same plans again
                out["cpu_tail"] = len(tail)
            if self.early is not None:  # the arena pool is this thread's again
                t_wait = time.perf_counter()
                self.early.result()
                self.early = None
                log.info("waited %.1f s for the first arena", time.perf_counter() - t_wait)
            timestep = scene.setup.model.opt.timestep
            for chunk, worlds in gpu_calls(
                planned, dc.gpu_batch, rec_cfg, timestep, sid, self.budget
            ):
                while self.in_flight and all(w.done() for w in self.in_flight[0][0]):
                    self._settle(*self.in_flight.pop(0))
                t_wait = time.perf_counter()
                while self.arena_pool is None and len(self.in_flight) > 1:
                    self._settle(*self.in_flight.pop(0))
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
                    meta, arrays = scene.payload(k, seed, plan, rec, rec_cfg, "warp")
                    # Images stay in the shared arena: the writer maps them.
                    arrays = share(arrays, arenas)
                    path = run.env.store_path
                    writes.append(run.writers.submit(store_episode, path, meta, arrays))
                    out["frames"] += len(rec.time)
                    out["new"] += 1
                    done.add(k)
                self.in_flight.append((writes, arenas))
                del recs
            retry = []  # slots whose plan failed in execution: their next seed
            for res in results:
                k = res.slot
                if k in done or k in tail or res.plan is None:
                    continue
                attempt[k] += 1
                if attempt[k] < dc.attempts:
                    retry.append(k)
            if run.bar is not None:
                run.bar.update(len(futures) - len(retry) - len(tail))
            if retry and dc.gpu_retries == "cpu":
                run.to_cpu(out, sid, retry, attempt)
                out["cpu_retries"] = len(retry)
                retry = []
            futures = run.submit(sid, retry, attempt) if retry else []
        waited["writes"] += self.reclaimed - reclaimed_before  # inside GPU calls
        out["warp_seconds"] = vars(executor.times)
        return float(out["simulate"])

    def close(self) -> None:
        for writes, arenas in self.in_flight:
            self._settle(writes, arenas)
        if self.arena_pool is not None:
            self.arena_pool.close()
        if self._populate is not None:
            self._populate.shutdown()


def warm_up_scene(scene: DemoScene, env: StageEnv, device: str) -> PreloadReport:
    """Compiles the kernels :class:`BatchGpu` launches in ``scene`` (set up without its
    planner) on Warp device ``device``: the scene's
    :class:`~factory.demos.execute.warp.WarpExecutor` with the run's recording settings,
    warmed up (:meth:`~factory.demos.execute.warp.WarpExecutor.warm_up`), then dropped; the
    kernels stay loaded in this process and compiled in Warp's kernel cache."""
    from factory.demos.execute.warp import WarpExecutor

    return WarpExecutor(scene.setup, record_config(env.demos), device=device).warm_up()


BATCH = Execution(
    round_slots=0,
    queue_per_worker=0,
    slot_worker=plan_slot,
    cpu_recorder=BatchCpu,
    gpu_recorder=BatchGpu,
    warm_up=warm_up_scene,
)
"""The ``batch`` execution (see the module)."""
