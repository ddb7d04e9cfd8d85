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

__all__ = ["EPISODE", "EpisodeCpu", "EpisodeGpu", "plan_and_simulate", "warm_up_scene"]

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
        self.shared = 0  # recordings handed to the writers in shared memory

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
        """Renders the scene's successful recordings as the planner processes return them;
        returns the GPU seconds (``render``)."""
        from factory.demos.execute.recording_render_warp import (
            RecordingStream,
            WarpRecordingRenderer,
        )

        sim = simulating(scene)
        cfg = sim.record_config()
        bar = self.run.bar
        renderer: WarpRecordingRenderer | None = None
        stream: RecordingStream | None = None
        slots: dict[int, tuple[int, int, Any]] = {}
        left = set(futures)
        while left:
            t_wait = time.perf_counter()
            done, _ = wait(left, return_when=FIRST_COMPLETED)
            waited["plans"] += time.perf_counter() - t_wait
            for fut in done:
                left.discard(fut)
                res = fut.result()
                tally(out, res)
                if bar is not None:
                    bar.update(1)
                if res.error or res.rec is None:
                    continue
                out["new"] += 1
                out["frames"] += len(res.rec.time)
                slots[id(res.rec)] = (res.slot, res.seed, res.plan)
                if not cfg.render:
                    waited["writes"] += self._write(sim, res.rec, slots, cfg)
                    continue
                if renderer is None:
                    renderer = WarpRecordingRenderer(
                        sim.setup.model, sim.camera_rig(cfg), device=self.run.device
                    )
                    stream = RecordingStream(renderer)
                assert stream is not None
                for rec in stream.push(res.rec, self._alloc_for(res.rec, stream)):
                    waited["writes"] += self._write(sim, rec, slots, cfg)
        if stream is not None:
            for rec in stream.flush():
                waited["writes"] += self._write(sim, rec, slots, cfg)
        if renderer is not None:
            t = renderer.times
            out["render"] = t.upload + t.draw + t.copy
            out["warp_seconds"] = vars(t).copy()
            renderer.close()
            del renderer, stream
        return float(out["render"])

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
    planner) on Warp device ``device`` (``stage=warmup``): a renderer of one world with the
    scene's camera rig and the run's recording settings, warmed up
    (:meth:`~factory.demos.execute.recording_render_warp.WarpRecordingRenderer.warm_up`), then
    dropped; the kernels stay loaded in this process and compiled in Warp's kernel cache. With
    ``demos.render=false`` the pipeline draws nothing and nothing is compiled."""
    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer
    from factory.sim.kernel_preload import PreloadReport

    sim = simulating(scene)
    cfg = sim.record_config()
    if not cfg.render:
        return PreloadReport(0, 0, 0.0, 0.0, 0, "")
    renderer = WarpRecordingRenderer(sim.setup.model, sim.camera_rig(cfg), device, max_worlds=1)
    try:
        return renderer.warm_up()
    finally:
        renderer.close()


EPISODE = Execution(
    round_slots=1,
    queue_per_worker=2,
    slot_worker=plan_and_simulate,
    cpu_recorder=EpisodeCpu,
    gpu_recorder=EpisodeGpu,
    warm_up=warm_up_scene,
)
"""The ``episode`` execution (see the module)."""
