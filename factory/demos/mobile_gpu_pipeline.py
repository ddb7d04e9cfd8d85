"""``stage=demos task=mobile_pick_place`` with the GPU executor: CPU processes plan and simulate,
the GPU renders.

A mobile episode's cost on a CPU is its five cameras (about 34 of its 40 s at 128 px), so the
pipeline moves the images alone to the GPU. ``spawn``ed worker processes each take an episode
slot, plan it and simulate it on the CPU without images (:func:`plan_and_simulate`: the CPU
path's :func:`~factory.tasks.mobile_pick_place.execute.execute_mobile` with ``render=False``, the
same
seeds and retries as :func:`~factory.demos.mobile_items.run_mobile_item`), and return the
recording's states and signals. The main process renders the successful recordings of a scene
on MuJoCo Warp (:class:`~factory.demos.execute.mobile_render_warp.WarpMobileRenderer`): their frames
fill the worlds of each render call back to back (:class:`~factory.demos.execute.mobile_render_warp.
RecordingStream`), and each episode, once its last frame is drawn, goes to a writer process
(:func:`~factory.demos.slots.store_episode`, images as numpy arrays). Scenes are rendered one
after another while the workers already plan and simulate the next scenes' slots (submitted
ahead until at least twice as many slots as workers are pending).

Per scene the statistics record ``executor="warp"``, the workers' planning and simulation
seconds, the GPU's rendering seconds (``render``) and ``warp_seconds`` (upload, draw, copy,
frames, calls); each scene logs one line in the GPU pipeline's format (``scene <id>: <n> new,
<s> s (GPU <s> s, waiting for plans <s> s, for earlier writes <s> s)``).
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import time
from concurrent.futures import (
    FIRST_COMPLETED,
    Future,
    ProcessPoolExecutor,
    ThreadPoolExecutor,
    wait,
)
from dataclasses import dataclass, field
from typing import Any

from factory.demos.slots import (
    StageEnv,
    WorkItem,
    episode_id,
    episode_seed,
    item_stats,
    slots_by_scene,
)
from factory.errors import FactoryError

log = logging.getLogger(__name__)

_KEEP = 2
"""Scenes whose set-up and planner a worker keeps."""

_SCENES: dict[str, Any] = {}


@dataclass
class SlotResult:
    """What a worker returns for one episode slot (picklable).

    Attributes:
        slot: the slot. seed, attempt: of the last attempt.
        plan: the successful episode's plan (None: no success).
        rec: its recording (states and signals, no images).
        failures: ``(reason, detail)`` of each failed attempt, in order.
        plan_seconds: planning time of each attempt that planned (s).
        segments: planning time of each planned motion (s).
        simulate: simulation time over the attempts (s).
        error: the scene cannot host the task, and why ('' otherwise).
    """

    slot: int
    seed: int = 0
    attempt: int = 0
    plan: Any = None
    rec: Any = None
    failures: list[tuple[str, str]] = field(default_factory=list)
    plan_seconds: list[float] = field(default_factory=list)
    segments: list[float] = field(default_factory=list)
    simulate: float = 0.0
    error: str = ""


def record_config(dc: Any, render: bool | None = None) -> Any:
    """The mobile recording settings of ``demos.*``: the pinhole ``demos.cameras`` plus both
    fisheye cameras (a :class:`~factory.tasks.mobile_pick_place.execute.MobileRecordConfig`)."""
    from factory.tasks.mobile_pick_place import FISHEYE_CAMERAS, MobileRecordConfig

    return MobileRecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=(*dc.cameras, *FISHEYE_CAMERAS),
        depth=dc.depth,
        render=dc.render if render is None else render,
    )


def _scene(env: StageEnv, scene_id: str) -> Any:
    """The scene's set-up and planner, made once per worker and scene (the last few kept)."""
    from factory.demos.mobile_items import mobile_scene_planner

    if scene_id in _SCENES:
        _SCENES[scene_id] = _SCENES.pop(scene_id)
    else:
        while len(_SCENES) >= _KEEP:
            del _SCENES[next(iter(_SCENES))]
        _SCENES[scene_id] = mobile_scene_planner(env.run_dir, scene_id, env.demos)
    return _SCENES[scene_id]


def plan_and_simulate(env: StageEnv, scene_id: str, slot: int, attempt: int = 0) -> SlotResult:
    """Plans and simulates (no images) one slot in a worker, trying the slot's seeds from
    ``attempt`` on until an episode succeeds or ``demos.attempts`` are spent, as
    :func:`~factory.demos.mobile_items.run_mobile_item` does."""
    from factory.tasks.mobile_pick_place import MobileEpisodePlan, execute_mobile

    out = SlotResult(slot)
    try:
        setup, planner = _scene(env, scene_id)
    except FactoryError as e:
        out.error = str(e)
        return out
    if planner.unusable:
        out.error = f"the robot's base cannot work there: {planner.unusable}"
        return out
    dc = env.demos
    cfg = record_config(dc, render=False)
    for a in range(attempt, dc.attempts):
        out.attempt, out.seed = a, episode_seed(env.seed, scene_id, slot, a)
        res = planner.plan_episode(out.seed)
        if not isinstance(res, MobileEpisodePlan):
            out.failures.append((res.reason, res.detail))
            continue
        out.plan_seconds.append(res.seconds)
        out.segments.extend(res.plan_seconds.values())
        rec = execute_mobile(setup, res, cfg)
        out.simulate += rec.sim_seconds
        assert rec.outcome is not None
        if rec.outcome.success:
            out.plan, out.rec = res, rec
            return out
        out.failures.append((rec.outcome.reason, str(rec.outcome.details)))
    return out


def _main_setup(run_dir: str, scene_id: str) -> Any:
    """The scene composed with the mobile robot in the main process (the model the workers
    simulate; deterministic)."""
    from factory.store import RunStore
    from factory.tasks.mobile_pick_place import mobile_setup

    store = RunStore(run_dir)
    return mobile_setup(store.load_scene(scene_id), store.assets_dir)


def run_mobile_gpu(
    env: StageEnv, items: list[WorkItem], workers: int, bar: Any = None, device: str | None = None
) -> list[dict[str, Any]]:
    """Fills the slots of ``items`` (mobile task): planned and simulated in ``workers``
    processes, rendered on MuJoCo Warp (``device``, default CUDA when present), written by
    writer processes. One statistics dict per scene (the keys of
    :func:`factory.demos.stage.run_item`'s)."""
    from factory.demos.execute.mobile_render_warp import RecordingStream, WarpMobileRenderer
    from factory.demos.gpu_pipeline import _init_worker, writer_count
    from factory.demos.mobile_items import mobile_payload
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.slots import store_episode

    dc = env.demos
    cfg = record_config(dc)
    store = EpisodeStore(env.store_path)
    by_scene = slots_by_scene(items)
    scenes = list(by_scene)
    results: list[dict[str, Any]] = []
    ctx = mp.get_context("spawn")
    nwriters = writer_count()
    with (
        ProcessPoolExecutor(max(1, workers), mp_context=ctx, initializer=_init_worker) as pool,
        ProcessPoolExecutor(nwriters, mp_context=ctx, initializer=_init_worker) as writers,
        ThreadPoolExecutor(1) as prep,
    ):
        pending: dict[str, list[Future[SlotResult]]] = {}
        setups: dict[str, Future[Any]] = {}
        writes: list[Future[None]] = []
        ahead = [0]  # index of the next scene to submit

        def submit_ahead(current: int) -> None:
            """Submits scenes until the next one is in and enough slots are pending."""
            while ahead[0] < len(scenes):
                queued = sum(len(f) for f in pending.values())
                if ahead[0] > current + 1 and queued >= 2 * max(1, workers):
                    break
                sid = scenes[ahead[0]]
                todo = [k for k in by_scene[sid] if episode_id(sid, k) not in store]
                pending[sid] = [pool.submit(plan_and_simulate, env, sid, k) for k in todo]
                setups[sid] = prep.submit(_main_setup, env.run_dir, sid)
                ahead[0] += 1

        def write(setup: Any, rec: Any, slots: dict[int, tuple[int, int, Any]]) -> float:
            """Hands a rendered recording to a writer; returns the seconds waited for
            earlier writes (at most two per writer in flight)."""
            k, seed, plan = slots.pop(id(rec))
            t0 = time.perf_counter()
            while sum(not w.done() for w in writes) >= 2 * nwriters:
                wait([w for w in writes if not w.done()], return_when=FIRST_COMPLETED)
            waited = time.perf_counter() - t0
            for w in [w for w in writes if w.done()]:
                w.result()  # a failed write raises here
                writes.remove(w)
            recorder = "warp" if cfg.render else "cpu"  # no images: all of it on the CPU
            meta, arrays = mobile_payload(setup, k, seed, plan, rec, cfg, recorder)
            writes.append(writers.submit(store_episode, str(store.path), meta, arrays))
            return waited

        for idx, sid in enumerate(scenes):
            out: dict[str, Any] = item_stats(sid, executor="warp")
            results.append(out)
            submit_ahead(idx)
            futures = pending.pop(sid)
            t_scene = time.perf_counter()
            waited = {"plans": 0.0, "writes": 0.0}
            try:
                setup = setups.pop(sid).result()
            except FactoryError as e:
                for f in futures:
                    f.cancel()
                out["error"] = str(e)
                out["failures"]["scene_unusable"] += len(futures)
                if bar is not None:
                    bar.update(len(by_scene[sid]))
                continue
            out["cleared"] = list(setup.cleared)
            renderer: WarpMobileRenderer | None = None
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
                    for reason, detail in res.failures:
                        out["failures"][reason] += 1
                        log.info("scene %s slot %d: %s: %s", sid, res.slot, reason, detail[:200])
                    out["plan"].extend(res.plan_seconds)
                    out["segments"].extend(res.segments)
                    out["simulate"] += res.simulate
                    if bar is not None:
                        bar.update(1)
                    if res.error:
                        out["error"] = res.error
                        out["failures"]["scene_unusable"] += 1
                        continue
                    if res.rec is None:
                        continue
                    out["new"] += 1
                    out["frames"] += len(res.rec.time)
                    slots[id(res.rec)] = (res.slot, res.seed, res.plan)
                    if not cfg.render:
                        waited["writes"] += write(setup, res.rec, slots)
                        continue
                    if renderer is None:
                        renderer = WarpMobileRenderer(setup.model, cfg, device=device)
                        stream = RecordingStream(renderer)
                    assert stream is not None
                    for rec in stream.push(res.rec):
                        waited["writes"] += write(setup, rec, slots)
            if stream is not None:
                for rec in stream.flush():
                    waited["writes"] += write(setup, rec, slots)
            if renderer is not None:
                t = renderer.times
                out["render"] = t.upload + t.draw + t.copy
                out["warp_seconds"] = vars(t).copy()
                renderer.close()
                del renderer, stream
            out["waited_s"] = waited
            log.info(
                "scene %s: %d new, %.1f s (GPU %.1f s, waiting for plans %.1f s, for earlier "
                "writes %.1f s)",
                sid,
                out["new"],
                time.perf_counter() - t_scene,
                out["render"],
                waited["plans"],
                waited["writes"],
            )
        for w in writes:
            w.result()
    return results
