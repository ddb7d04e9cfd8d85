"""``stage=demos``: planned, executed and recorded demonstrations in every scene of a run, for
the task ``task=<name>`` (:func:`factory.tasks.get_task`).

Work is split into items: a scene and a chunk of up to ``demos.batch`` of its episode slots
that are not stored yet. An item sets up the task's scene (the robot's base spot is
deterministic per scene), then in rounds plans its open slots (seeds per slot and attempt),
executes and records the plans the way the task's execution model says, checks success and
stores the successful episodes in ``episodes/shard-<k>.zarr``; failed slots are tried again
up to ``demos.attempts`` times (:mod:`factory.demos.cpu_items`). Items run in
``demos.workers`` processes (each with its own simulation and GL context), or in this process;
with ``demos.executor=warp`` the GPU pipeline takes them (:mod:`factory.demos.gpu_pipeline`).
A scene that cannot host the task (objects missing, no base spot) is reported with its reason
and the run goes on. Re-running skips stored episodes, so an interrupted run resumes.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from factory.config import DemosConfig
from factory.context import StageContext
from factory.cores import usable_cores
from factory.demos.cpu_items import run_item, run_item_logged
from factory.demos.record.disk_room import DiskFull, DiskRoom
from factory.demos.record.slots import StageEnv, WorkItem, episode_id
from factory.errors import ConfigError, StoreError
from factory.store import atomic_write_json
from factory.tasks import get_task, task_of_scenes

__all__ = ["EXECUTORS", "check_config", "resolve_executor", "run"]

log = logging.getLogger(__name__)

EXECUTORS: dict[str, str] = {
    "auto": "warp when CUDA is present, else cpu",
    "cpu": "the CPU: mujoco.batch threads + EGL/OSMesa rendering (factory.demos.execute.cpu), "
    "or the task's own simulation an episode at a time",
    "warp": "the GPU pipeline (factory.demos.gpu_pipeline): MuJoCo Warp worlds + its batch "
    "renderer (factory.demos.execute.warp), or the task's simulation on the CPU and Warp "
    "rendering (factory.demos.execute.recording_render_warp)",
}
"""``demos.executor`` values."""

SUMMARY_SCHEMA_VERSION = 1


def resolve_executor(name: str) -> str:
    """``cpu`` or ``warp`` for a ``demos.executor`` value (``auto``: ``warp`` with CUDA).

    ``warp`` without CUDA runs on Warp's CPU device: correct but slow (meant for tests).
    """
    from factory.sim.backend import cuda_available

    if name == "auto":
        return "warp" if cuda_available() else "cpu"
    if name == "warp" and not cuda_available():
        log.warning("demos.executor=warp without CUDA: MuJoCo Warp runs on the CPU (slow)")
    return name


def check_config(dc: DemosConfig, task: str) -> None:
    """Raises :class:`ConfigError` naming a bad ``demos.*`` value or task (the registry's
    error, listing the tasks)."""
    get_task(task)
    if dc.executor not in EXECUTORS:
        raise ConfigError(
            f"demos.executor={dc.executor!r} is unknown: choose one of {', '.join(EXECUTORS)}"
        )
    if dc.gpu_batch < 1:
        raise ConfigError("demos.gpu_batch must be >= 1")
    if dc.gpu_retries not in ("cpu", "gpu"):
        raise ConfigError(f"demos.gpu_retries={dc.gpu_retries!r} is unknown: choose cpu or gpu")
    from factory.demos.episode_physics import EPISODE_PHYSICS

    if dc.episode_physics not in EPISODE_PHYSICS:
        raise ConfigError(
            f"demos.episode_physics={dc.episode_physics!r} is unknown: choose one of "
            f"{', '.join(EPISODE_PHYSICS)}"
        )
    if not 0.0 <= dc.gpu_tail < 0.5:
        raise ConfigError(
            f"demos.gpu_tail={dc.gpu_tail} is out of range: give the share of a scene's longest "
            "episodes to record on the CPU, from 0 (none) to below 0.5 (e.g. 0.01)"
        )
    if not dc.freeze_beyond >= 0:
        raise ConfigError(
            f"demos.freeze_beyond must be >= 0 m (0 keeps every object free), "
            f"got {dc.freeze_beyond}"
        )
    if not dc.lookalike_radius >= 0:
        raise ConfigError(
            f"demos.lookalike_radius must be >= 0 m (0 keeps look-alikes), "
            f"got {dc.lookalike_radius}"
        )
    if dc.depth not in ("uint16_mm", "float32"):
        raise ConfigError(f"demos.depth must be uint16_mm or float32, got {dc.depth!r}")
    unknown = [c for c in dc.cameras if c not in ("left", "right", "wrist")]
    if unknown:
        raise ConfigError(f"demos.cameras: unknown camera(s) {unknown}; use left, right, wrist")
    if dc.episodes_per_scene < 1 or dc.attempts < 1 or dc.batch < 1 or dc.workers < 0:
        raise ConfigError(
            "demos.episodes_per_scene, demos.attempts and demos.batch must be >= 1 and "
            "demos.workers >= 0"
        )
    if dc.fps <= 0 or dc.width < 8 or dc.height < 8:
        raise ConfigError("demos.fps must be > 0 and demos.width/height >= 8 px")


def _stats(values: list[float]) -> dict[str, float]:
    if not values:
        return {"n": 0}
    arr = np.asarray(values)
    return {
        "n": len(values),
        "median": float(np.median(arr)),
        "p95": float(np.percentile(arr, 95)),
        "mean": float(arr.mean()),
    }


def run(ctx: StageContext) -> dict[str, Any]:
    """Runs the demos stage for this shard's scenes; returns the summary."""
    from tqdm import tqdm

    from factory.console import terminal
    from factory.demos.record.episodes import EpisodeStore

    cfg = ctx.cfg
    dc = cfg.demos
    check_config(dc, cfg.task)
    store = ctx.require_store()
    ids = store.scene_ids()
    if not ids:
        raise StoreError(f"no scenes in {store.scenes_dir}: run stage=generate or ingest first")
    task = task_of_scenes(cfg.task, [store.load_scene(sid) for sid in ids])
    if task != cfg.task:
        log.info("stage=demos: every scene of the run was made for task=%s: recording it", task)
        cfg = replace(cfg, task=task)
    scene_ids = ctx.shard.select(ids)
    episodes = EpisodeStore(store.episodes_shard(ctx.shard))
    episodes.clean_staging()
    stored = set(episodes.episode_ids())
    items: list[WorkItem] = []
    for sid in scene_ids:
        todo = [k for k in range(dc.episodes_per_scene) if episode_id(sid, k) not in stored]
        for start in range(0, len(todo), dc.batch):
            items.append(WorkItem(sid, tuple(todo[start : start + dc.batch])))
    cores = usable_cores()
    executor = resolve_executor(dc.executor)
    if executor == "warp":
        workers = dc.workers or max(1, cores - 1)
    else:
        workers = min(dc.workers or cores, max(1, len(items)))
    nthread = dc.nthread or max(1, cores // workers)
    env = StageEnv(str(store.root), str(episodes.path), dc, cfg.task, cfg.seed, nthread)
    t_start = time.perf_counter()
    results: list[dict[str, Any]] = []
    total = sum(len(i.slots) for i in items)
    desc = "demos (gpu)" if executor == "warp" else "demos"
    room = DiskRoom(episodes.path, len(stored), total)
    closed = 0  # slots closed (stored or given up), for the disk's projection
    with tqdm(total=total, desc=desc, unit="episode", disable=None, file=terminal()) as bar:
        try:
            if executor == "warp" and items:
                from factory.demos.gpu_pipeline import run_gpu

                results = run_gpu(env, items, workers, bar, room=room)
            elif workers > 1:
                with ProcessPoolExecutor(workers) as pool:
                    futures = {pool.submit(run_item_logged, env, it): it for it in items}
                    for fut in as_completed(futures):
                        results.append(fut.result())
                        bar.update(len(futures[fut].slots))
                        closed += len(futures[fut].slots)
                        try:
                            room.check(len(episodes), closed)
                        except DiskFull:
                            pool.shutdown(cancel_futures=True)
                            raise
            else:
                for it in items:
                    results.append(run_item(env, it))
                    bar.update(len(it.slots))
                    closed += len(it.slots)
                    room.check(len(episodes), closed)
        finally:
            episodes.clean_staging()
    wall = time.perf_counter() - t_start
    scenes: dict[str, Any] = {
        sid: {"episodes": 0, "new": 0, "failures": Counter()} for sid in scene_ids
    }
    reasons: Counter[str] = Counter()
    for r in results:
        s = scenes[r["scene_id"]]
        s["new"] += r["new"]
        s["failures"].update(r["failures"])
        reasons.update(r["failures"])
        if r["error"]:
            s["error"] = r["error"]
            log.warning("scene %s: no demos: %s", r["scene_id"], r["error"])
        if "robot_base" in r:
            s["robot_base"] = r["robot_base"]
            s["cleared"] = r["cleared"]
    for eid in episodes.episode_ids():
        sid = eid.rsplit("-ep", 1)[0]
        if sid in scenes:
            scenes[sid]["episodes"] += 1
    for s in scenes.values():
        s["failures"] = dict(s["failures"])
    n_ok = sum(r["new"] for r in results)
    tried = n_ok + sum(v for k, v in reasons.items() if k != "scene_unusable")
    frames = sum(r["frames"] for r in results)
    render_s = sum(r["render"] for r in results)
    summary = {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "task": cfg.task,
        "shard": ctx.shard.name,
        "store": str(Path(episodes.path).relative_to(store.root)),
        "episodes_stored": len(episodes),
        "new_successes": n_ok,
        "failures": dict(reasons),
        "success_rate": n_ok / max(1, tried),
        "scenes": scenes,
        "executor": executor,
        "workers": workers,
        "threads_per_worker": nthread,
        "seconds": {
            "wall": wall,
            "plan_per_episode": _stats([t for r in results for t in r["plan"]]),
            "plan_per_segment": _stats([t for r in results for t in r["segments"]]),
            "simulate": sum(r["simulate"] for r in results),
            "render": render_s,
        },
        "frames": frames,
    }
    gpu = [r["warp_seconds"] for r in results if "warp_seconds" in r]
    if gpu:
        summary["seconds"]["gpu"] = {k: sum(g[k] for g in gpu) for k in gpu[0]}
    physics = [r["physics_seconds"] for r in results if "physics_seconds" in r]
    if physics:  # the episode execution's plans simulated on MuJoCo Warp
        summary["seconds"]["gpu_physics"] = {k: sum(g[k] for g in physics) for k in physics[0]}
    atomic_write_json(store.root / "episodes" / f"summary-{ctx.shard.name}.json", summary)
    log.info(
        "demos: %d new successful episodes, failures %s, %.1f s",
        n_ok,
        dict(reasons) or "none",
        wall,
    )
    return {k: summary[k] for k in ("episodes_stored", "new_successes", "failures", "success_rate")}
