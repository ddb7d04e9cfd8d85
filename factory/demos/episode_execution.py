"""The ``episode`` execution of ``stage=demos``: the task simulates each episode itself, one at
a time on one ``MjData`` (a :class:`~factory.demos.record.scene.SimulatingScene`: the mobile
task, whose base drives between supports; the articulated tasks ``open``, ``close`` and
``place_inside``, whose fingers move a part of the scene).

* CPU (:class:`EpisodeCpu`): a slot at a time, its attempts one after another; each episode is
  simulated, checked and drawn by the task
  (:meth:`~factory.demos.record.scene.SimulatingScene.simulate`) and logs one INFO line (slot,
  attempt, outcome, seconds of planning, simulation and rendering).
* GPU pipeline: such an episode's cost on a CPU is mostly its cameras (a mobile episode's about
  34 of its 40 s at 128 px), so the images alone move to the GPU. The planner processes plan and
  simulate a slot without images, trying its seeds until an episode succeeds
  (:func:`plan_and_simulate`, the CPU path's seeds and attempts), and return the recording's
  states and signals; the main process (:class:`EpisodeGpu`) renders the successful recordings
  of a scene on MuJoCo Warp with the scene's own cameras
  (:meth:`~factory.demos.record.scene.SimulatingScene.camera_rig`,
  :class:`~factory.demos.execute.recording_render_warp.WarpRecordingRenderer`): their frames
  fill the worlds of each render call back to back
  (:class:`~factory.demos.execute.recording_render_warp.RecordingStream`), and each episode,
  once its last frame is drawn, goes to a writer process (its images drawn into shared memory,
  which the writer maps in place: :class:`EpisodeGpu`). The scene's
  ``render`` seconds are the GPU's, ``warp_seconds`` its upload, draw, copy, frames and calls.
* ``stage=warmup`` (:func:`warm_up_scene`): the renderer's kernels of a scene compiled ahead
  into Warp's kernel cache.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from typing import TYPE_CHECKING, Any

import numpy as np

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
from factory.demos.record.scene import DemoScene, SimulatingScene
from factory.demos.record.slots import StageEnv, episode_seed
from factory.errors import ConfigError, FactoryError

if TYPE_CHECKING:
    from factory.sim.kernel_preload import PreloadReport

__all__ = [
    "EPISODE",
    "EpisodeCpu",
    "EpisodeGpu",
    "episode_slot",
    "plan_and_simulate",
    "warm_up_scene",
]

log = logging.getLogger(__name__)


def simulating(scene: DemoScene) -> SimulatingScene:
    """``scene`` as a :class:`SimulatingScene`.

    Raises:
        ConfigError: the task's ``demo_execution`` is ``episode`` but its scene does not
            simulate episodes.
    """
    if not isinstance(scene, SimulatingScene):
        raise ConfigError(
            f"task {scene.env.task!r}: demo_execution='episode' needs a SimulatingScene, "
            f"its demo_scene gave a {type(scene).__name__}"
        )
    return scene


class EpisodeCpu(CpuRecorder):
    """Each planned episode simulated and drawn by the task on the CPU."""

    def __init__(self, scene: DemoScene, env: StageEnv) -> None:
        self.scene = simulating(scene)
        self.rec_cfg = self.scene.record_config()
        self.renderer = self.scene.renderer(self.rec_cfg) if self.rec_cfg.render else None

    def execute(self, planned: list[tuple[int, int, Any]], attempt: dict[int, int]) -> list[Any]:
        recs = []
        for k, _, plan in planned:
            t0 = time.perf_counter()
            rec = self.scene.simulate(plan, self.rec_cfg, self.renderer)
            assert rec.outcome is not None
            log.info(
                "scene %s slot %d attempt %d: %s in %.1f s (plan %.1f s, simulate %.1f s, "
                "render %.1f s; %d frames, %.1f s of motion)",
                self.scene.scene_id,
                k,
                attempt[k],
                "success" if rec.outcome.success else rec.outcome.reason,
                plan.seconds + time.perf_counter() - t0,
                plan.seconds,
                rec.sim_seconds,
                rec.render_seconds,
                len(rec.time),
                float(rec.time[-1]),
            )
            recs.append(rec)
        return recs

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.close()


def plan_and_simulate(env: StageEnv, scene_id: str, slot: int, attempt: int = 0) -> SlotResult:
    """Plans and simulates (no images) one slot in a planner process, trying the slot's seeds
    from ``attempt`` on until an episode succeeds or ``demos.attempts`` are spent, as the CPU
    path does."""
    out = SlotResult(slot)
    try:
        scene = simulating(cached_scene(env, scene_id))
    except FactoryError as e:
        out.error = str(e)
        return out
    dc = env.demos
    cfg = scene.record_config(render=False)
    for a in range(attempt, dc.attempts):
        out.attempt, out.seed = a, episode_seed(env.seed, scene_id, slot, a)
        res = scene.plan(out.seed)
        if not isinstance(res, scene.plan_type):
            out.failures.append((res.reason, res.detail))
            continue
        out.plan_seconds.append(res.seconds)
        out.segments.extend(res.plan_seconds.values())
        rec = scene.simulate(res, cfg)
        out.simulate += rec.sim_seconds
        assert rec.outcome is not None
        if rec.outcome.success:
            out.plan, out.rec = res, rec
            return out
        out.failures.append((rec.outcome.reason, str(rec.outcome.details)))
    return out


class _Drawer:
    """A scene's successful recordings drawn on MuJoCo Warp with the scene's cameras (the
    renderer made at the first one) and handed to the writers (:class:`EpisodeGpu`); without
    ``demos.render`` written as they are."""

    def __init__(self, gpu: EpisodeGpu, sim: SimulatingScene, device: str | None) -> None:
        self.gpu, self.sim, self.device = gpu, sim, device
        self.cfg = sim.record_config()
        self.renderer: Any = None
        self.stream: Any = None
        self.slots: dict[int, tuple[int, int, Any]] = {}

    def add(
        self,
        slot: int,
        seed: int,
        plan: Any,
        rec: Any,
        out: dict[str, Any],
        waited: dict[str, float],
    ) -> None:
        """Queues a successful recording (of ``slot``, planned from ``seed``) for drawing and
        writes the recordings whose images are complete."""
        from factory.demos.execute.recording_render_warp import (
            RecordingStream,
            WarpRecordingRenderer,
        )

        out["new"] += 1
        out["frames"] += len(rec.time)
        self.slots[id(rec)] = (slot, seed, plan)
        sim, cfg = self.sim, self.cfg
        if not cfg.render:
            waited["writes"] += self.gpu._write(sim, rec, self.slots, cfg)
            return
        if self.renderer is None:
            self.renderer = WarpRecordingRenderer(
                sim.setup.model, sim.camera_rig(cfg), device=self.device
            )
            self.stream = RecordingStream(self.renderer)
        for done in self.stream.push(rec, self.gpu._alloc_for(rec, self.stream)):
            waited["writes"] += self.gpu._write(sim, done, self.slots, cfg)

    def finish(self, out: dict[str, Any], waited: dict[str, float]) -> None:
        """Draws and writes what is queued; files the renderer's seconds (``render``,
        ``warp_seconds``) into ``out`` and frees it."""
        if self.stream is not None:
            for rec in self.stream.flush():
                waited["writes"] += self.gpu._write(self.sim, rec, self.slots, self.cfg)
        if self.renderer is not None:
            t = self.renderer.times
            out["render"] = t.upload + t.draw + t.copy
            out["warp_seconds"] = vars(t).copy()
            self.renderer.close()
            self.renderer = self.stream = None


def episode_slot(env: StageEnv, scene_id: str, slot: int, attempt: int = 0) -> SlotResult:
    """A planner process's work on one slot: planned only where MuJoCo Warp simulates the
    scene's episodes (:func:`~factory.demos.episode_physics.plan_slot`), else planned and
    simulated (:func:`plan_and_simulate`); ``demos.episode_physics`` and the scene decide
    (:func:`~factory.demos.episode_physics.states_recorder`)."""
    from factory.demos.episode_physics import plan_slot, states_recorder

    try:
        scene = simulating(cached_scene(env, scene_id))
        on_gpu = states_recorder(scene, env.demos.episode_physics) is not None
    except FactoryError as e:
        out = SlotResult(slot, attempt=attempt)
        out.error = str(e)
        return out
    if on_gpu:
        return plan_slot(env, scene_id, slot, attempt)
    return plan_and_simulate(env, scene_id, slot, attempt)


class EpisodeGpu(GpuRecorder):
    """The main process of the GPU pipeline for the ``episode`` execution (one per run): each
    scene's recordings rendered as they come in, written with at most two writes per writer
    in flight.

    A recording's images are drawn into an arena of shared memory of its own
    (:class:`~factory.demos.execute.shared_frames.ArenaPool`, reused once its write is done),
    and the writer maps them in place: pickling an episode's images to a writer (61 MB for 250
    frames of three 128 px cameras) cost the main process about as much as drawing them.
    Where shared memory is not available (not Linux) the images are pickled as before.
    """

    def __init__(self, run: GpuRun) -> None:
        from factory.demos.execute import shared_frames
        from factory.demos.execute.gpu_calls import HOST_MEMORY_SHARE, memory_budget

        self.run = run
        self.writes: list[tuple[Future[None], Any]] = []  # (write, its arena or None)
        self.arenas: Any = None
        if shared_frames.supported():
            capacity = memory_budget(HOST_MEMORY_SHARE) or 0
            self.arenas = shared_frames.ArenaPool(capacity, self._reclaim)
        self._arena_of: dict[int, Any] = {}  # id(recording) -> its arena
        self._prepared: dict[str, Any] = {}  # scene id -> its physics, readied ahead
        self._lock = threading.Lock()
        self.shared = 0  # recordings handed to the writers in shared memory

    def prepare(self, scene: DemoScene) -> None:
        """Where MuJoCo Warp simulates the scene's episodes: makes its physics
        (:class:`~factory.demos.execute.plan_worlds.WarpPlanWorlds`) and compiles its kernels in
        the set-up thread, while the scene before records (MuJoCo Warp specialises some kernels
        to the model). A failure is logged; :meth:`record_scene` then makes it again and shows
        the error."""
        from factory.demos.episode_physics import states_recorder

        try:
            sim = simulating(scene)
            hook = states_recorder(sim, self.run.env.demos.episode_physics)
            if hook is None:
                return
            physics = self._physics(sim, hook)
            physics.warm_up()
        except Exception as e:
            log.warning(
                "demos %s: readying the GPU physics ahead failed (%s: %s); it is made when the "
                "scene's turn comes",
                scene.scene_id,
                type(e).__name__,
                e,
            )
            return
        with self._lock:
            self._prepared[scene.scene_id] = physics

    def _physics(self, sim: SimulatingScene, hook: Any) -> Any:
        """The scene's :class:`~factory.demos.execute.plan_worlds.WarpPlanWorlds`."""
        from factory.demos.execute.plan_worlds import WarpPlanWorlds

        return WarpPlanWorlds(
            sim.setup.model,
            hook.robot_geom,
            hook.allowed,
            sim.record_config(render=False).fps,
            device=self.run.device,
            max_worlds=self.run.env.demos.gpu_batch,
        )

    def _settle_done(self) -> None:
        """Collects finished writes (a failed one raises) and gives their arenas back."""
        for entry in [e for e in self.writes if e[0].done()]:
            entry[0].result()
            self.writes.remove(entry)
            if entry[1] is not None:
                self.arenas.give(entry[1])

    def _reclaim(self) -> None:
        """Waits until a write finishes and gives its arena back (the pool is full)."""
        pending = [w for w, _ in self.writes if not w.done()]
        if pending:
            wait(pending, return_when=FIRST_COMPLETED)
        self._settle_done()

    def _alloc_for(self, rec: Any, stream: Any) -> Callable[[tuple[int, ...], Any], Any]:
        """Where ``rec``'s images go: an arena of its own, or plain memory without arenas."""
        if self.arenas is None:
            return np.empty
        from factory.demos.execute.shared_frames import Arena

        arena = self.arenas.take(Arena.bytes_for(stream.image_specs(len(rec.state))))
        self._arena_of[id(rec)] = arena
        return arena.empty

    def _write(self, scene: SimulatingScene, rec: Any, slots: dict[int, Any], cfg: Any) -> float:
        """Hands a rendered recording to a writer; returns the seconds waited for earlier
        writes."""
        from factory.demos.execute.shared_frames import share

        k, seed, plan = slots.pop(id(rec))
        arena = self._arena_of.pop(id(rec), None)
        t0 = time.perf_counter()
        while sum(not w.done() for w, _ in self.writes) >= 2 * self.run.nwriters:
            wait([w for w, _ in self.writes if not w.done()], return_when=FIRST_COMPLETED)
        waited = time.perf_counter() - t0
        self._settle_done()
        recorder = "warp" if cfg.render else "cpu"  # no images: all of it on the CPU
        meta, arrays = scene.payload(k, seed, plan, rec, cfg, recorder)
        if arena is not None:
            arrays = share(arrays, [arena])
            self.shared += 1
        self.writes.append(
            (self.run.writers.submit(store_episode, self.run.env.store_path, meta, arrays), arena)
        )
        return waited

    def record_scene(
        self,
        scene: DemoScene,
        futures: list[Future[SlotResult]],
        attempt: dict[int, int],
        out: dict[str, Any],
        waited: dict[str, float],
    ) -> float:
        """Records the scene's slots: the planner processes' recordings drawn as they come in
        (``demos.episode_physics=cpu``), or the scene's plans simulated on MuJoCo Warp first
        (``warp``: :meth:`_simulate_scene`); returns the GPU seconds (``render``, and the
        physics' with ``warp``)."""
        from factory.demos.episode_physics import states_recorder

        sim = simulating(scene)
        draw = _Drawer(self, sim, self.run.device)
        hook = states_recorder(sim, self.run.env.demos.episode_physics)
        if hook is not None:
            physics = self._simulate_scene(sim, hook, draw, futures, attempt, out, waited)
        else:
            physics = 0.0
            left = set(futures)
            while left:
                t_wait = time.perf_counter()
                done, _ = wait(left, return_when=FIRST_COMPLETED)
                waited["plans"] += time.perf_counter() - t_wait
                for fut in done:
                    left.discard(fut)
                    res = fut.result()
                    tally(out, res)
                    if self.run.bar is not None:
                        self.run.bar.update(1)
                    if res.error or res.rec is None:
                        continue
                    draw.add(res.slot, res.seed, res.plan, res.rec, out, waited)
        draw.finish(out, waited)
        return float(out["render"]) + physics

    def _simulate_scene(
        self,
        sim: SimulatingScene,
        hook: Any,
        draw: _Drawer,
        futures: list[Future[SlotResult]],
        attempt: dict[int, int],
        out: dict[str, Any],
        waited: dict[str, float],
    ) -> float:
        """``demos.episode_physics=warp``: rounds of the scene's plans (as the planner
        processes return them, all of a round's together) stepped on MuJoCo Warp, recorded from
        their states with the task's hook, the successes drawn and written, the failures
        planned again from their next seed in the next round; returns the physics' seconds."""
        from factory.demos.episode_physics import simulate_plans

        dc = self.run.env.demos
        cfg = sim.record_config(render=False)
        with self._lock:
            runner = self._prepared.pop(sim.scene_id, None)
        if runner is None:  # not prepared, or its preparation failed
            runner = self._physics(sim, hook)
        t_physics = 0.0
        while futures:
            t_wait = time.perf_counter()
            results = [f.result() for f in futures]
            waited["plans"] += time.perf_counter() - t_wait
            planned: list[tuple[int, int, Any]] = []
            for res in results:
                attempt[res.slot] = res.attempt
                tally(out, res)
                if res.plan is not None:
                    planned.append((res.slot, res.seed, res.plan))
            t0 = time.perf_counter()
            recs = simulate_plans(runner, hook, [p for _, _, p in planned], cfg) if planned else []
            t_physics += time.perf_counter() - t0
            retry = []
            for (k, seed, plan), rec in zip(planned, recs, strict=True):
                assert rec.outcome is not None
                if rec.outcome.success:
                    draw.add(k, seed, plan, rec, out, waited)
                    continue
                out["failures"][rec.outcome.reason] += 1
                log.info(
                    "scene %s slot %d: %s: %s",
                    out["scene_id"],
                    k,
                    rec.outcome.reason,
                    str(rec.outcome.details)[:200],
                )
                attempt[k] += 1
                if attempt[k] < dc.attempts:
                    retry.append(k)
            if self.run.bar is not None:
                self.run.bar.update(len(futures) - len(retry))
            futures = self.run.submit(sim.scene_id, retry, attempt) if retry else []
        out["simulate"] += t_physics
        t = runner.times
        out["physics_seconds"] = {
            "setup": t.setup,
            "periods": t.periods,
            "host": t.host,
            "record": t.record,
            "calls": t.calls,
            "worlds": t.worlds,
            "frames": t.frames,
        }
        return t_physics

    def close(self) -> None:
        for w, _ in self.writes:
            w.result()
        self.writes = []
        if self.arenas is not None:
            self.arenas.close()
        if self.shared:
            log.info("episode images handed to the writers in shared memory: %d", self.shared)


def warm_up_scene(scene: DemoScene, env: StageEnv, device: str) -> PreloadReport:
    """Compiles the kernels :class:`EpisodeGpu` launches in ``scene`` (set up without its
    planner) on Warp device ``device`` (``stage=warmup``): where MuJoCo Warp simulates the
    scene's episodes (``demos.episode_physics``), the physics of one world
    (:meth:`~factory.demos.execute.plan_worlds.WarpPlanWorlds.warm_up`); with ``demos.render``,
    a renderer of one world with the scene's camera rig and the run's recording settings
    (:meth:`~factory.demos.execute.recording_render_warp.WarpRecordingRenderer.warm_up`); both
    then dropped; the kernels stay loaded in this process and compiled in Warp's kernel
    cache. Nothing to simulate or draw: nothing is compiled."""
    from factory.demos.episode_physics import states_recorder
    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer

    sim = simulating(scene)
    cfg = sim.record_config()
    reports = []
    hook = states_recorder(sim, env.demos.episode_physics)
    if hook is not None:
        from factory.demos.execute.plan_worlds import WarpPlanWorlds

        physics = WarpPlanWorlds(
            sim.setup.model, hook.robot_geom, hook.allowed, cfg.fps, device=device, max_worlds=1
        )
        reports.append(physics.warm_up())
    if cfg.render:
        renderer = WarpRecordingRenderer(sim.setup.model, sim.camera_rig(cfg), device, max_worlds=1)
        try:
            reports.append(renderer.warm_up())
        finally:
            renderer.close()
    return _joined(reports)


def _joined(reports: list[PreloadReport]) -> PreloadReport:
    """One report of several preloads (counts and seconds added; the first error)."""
    from factory.sim.kernel_preload import PreloadReport

    if not reports:
        return PreloadReport(0, 0, 0.0, 0.0, 0, "")
    return PreloadReport(
        sum(r.modules for r in reports),
        sum(r.compiled for r in reports),
        sum(r.trace_s for r in reports),
        sum(r.load_s for r in reports),
        max(r.workers for r in reports),
        next((r.error for r in reports if r.error), ""),
        sum(r.wait_s for r in reports),
    )


EPISODE = Execution(
    round_slots=1,
    queue_per_worker=2,
    slot_worker=episode_slot,
    cpu_recorder=EpisodeCpu,
    gpu_recorder=EpisodeGpu,
    warm_up=warm_up_scene,
)
"""The ``episode`` execution (see the module)."""
