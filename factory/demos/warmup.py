"""``stage=warmup``: the GPU kernels of a run's ``stage=demos`` compiled ahead, into Warp's
kernel cache (``sim.kernel_cache``).

On a bare GPU machine the first GPU call of ``stage=demos`` waits for MuJoCo Warp's kernels to
compile (50-75 s with the parallel preload; MuJoCo Warp specialises some kernels to each
scene's model). This stage does that work beforehand, e.g. as a cluster's first job or right
after ``stage=generate``, so that ``stage=demos`` reads the kernels from the cache. It takes
the scenes ``stage=demos`` would record in (this shard's, those with episode slots not stored
yet), sets each up without its planner (:meth:`~factory.tasks.base.Task.demo_scene`) and has
the task's execution compile the kernels its GPU recorder will launch there
(:attr:`~factory.demos.execution.Execution.warm_up`), one scene after the other, with one log
line per scene::

    warmup 2/10 kitchen_xxx: 6 of 86 modules compiled in 9.1 s (kernel cache <dir>: 74 read, 6
    loaded for an earlier scene)

The device is CUDA's where present, else Warp's CPU device (the kernels ``demos.executor=warp``
runs without CUDA; they do not spare a GPU machine its compiling). A task whose execution
compiles nothing ahead (:attr:`~factory.demos.execution.Execution.warm_up` None) gets a one-line
reason and a summary saying nothing was compiled; a scene that cannot host the task is listed
with its reason and the stage goes on. The summary is written to ``run_dir/warmup.json``
(``warmup-<shard>.json`` for one shard of several; :data:`SUMMARY_SCHEMA_VERSION`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from factory.config import FactoryConfig
from factory.context import StageContext
from factory.demos.record.slots import StageEnv, episode_id
from factory.errors import FactoryError, StoreError
from factory.store import RunStore, Shard, atomic_write_json

if TYPE_CHECKING:
    from factory.demos.record.scene import DemoScene
    from factory.sim.kernel_preload import PreloadReport

__all__ = ["SUMMARY_SCHEMA_VERSION", "run", "summary_path", "warm_device"]

log = logging.getLogger(__name__)

SUMMARY_SCHEMA_VERSION = 1


def summary_path(store: RunStore, shard: Shard) -> Path:
    """Where the stage's summary goes: ``run_dir/warmup.json``, or ``warmup-<shard>.json``
    when the run is split into several shards."""
    name = "warmup.json" if shard.count == 1 else f"warmup-{shard.name}.json"
    return store.root / name


def warm_device() -> str:
    """The Warp device whose kernels the stage compiles: ``cuda:0`` where CUDA is present,
    else ``cpu`` (logged: those kernels serve ``demos.executor=warp`` on this machine only)."""
    from factory.sim.backend import cuda_available

    if cuda_available():
        return "cuda:0"
    log.info(
        "warmup: no CUDA device: compiling for Warp's CPU device (what demos.executor=warp "
        "runs here without CUDA); run stage=warmup on a GPU machine to fill its kernels"
    )
    return "cpu"


def _scenes_to_record(ctx: StageContext, store: RunStore) -> tuple[str, list[str], list[str]]:
    """The task and scenes ``stage=demos`` would record in with this config: the run's scenes
    (the default task standing aside for the one every scene claims), this shard's, those with
    episode slots not stored yet; and this shard's scenes that are complete.

    Raises:
        StoreError: the run has no scenes (names the stages that make them).
    """
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks import task_of_scenes

    ids = store.scene_ids()
    if not ids:
        raise StoreError(
            f"no scenes in {store.scenes_dir}: run stage=generate or stage=ingest first, then "
            "stage=warmup"
        )
    cfg = ctx.cfg
    task = task_of_scenes(cfg.task, [store.load_scene(sid) for sid in ids])
    stored = set(EpisodeStore(store.episodes_shard(ctx.shard)).episode_ids())
    todo: list[str] = []
    done: list[str] = []
    for sid in ctx.shard.select(ids):
        slots = range(cfg.demos.episodes_per_scene)
        (done if all(episode_id(sid, k) in stored for k in slots) else todo).append(sid)
    return task, todo, done


def run(ctx: StageContext) -> dict[str, Any]:
    """Compiles the GPU kernels of this shard's scenes (see the module); returns the summary's
    totals (the whole summary is in ``warmup.json``).

    Raises:
        StoreError: the run has no scenes.
        ConfigError: a bad ``demos.*`` value or task.
    """
    from factory.demos.execution import execution_of
    from factory.demos.stage import check_config
    from factory.tasks import get_task

    cfg = ctx.cfg
    check_config(cfg.demos, cfg.task)
    store = ctx.require_store()
    task_name, scene_ids, complete = _scenes_to_record(ctx, store)
    if task_name != cfg.task:
        log.info("stage=warmup: every scene of the run was made for task=%s: warming it", task_name)
        cfg = replace(cfg, task=task_name)
    task = get_task(task_name)
    execution = execution_of(task)
    summary: dict[str, Any] = {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "task": task_name,
        "shard": ctx.shard.name,
        "device": None,
        "kernel_cache": None,
        "scenes": [],
        "complete": complete,
        "nothing_to_warm": "",
    }
    if complete:
        log.info(
            "warmup: %d scene(s) skipped: their episodes are all stored (stage=demos does not "
            "run them)",
            len(complete),
        )
    t0 = time.perf_counter()
    if execution.warm_up is None:
        reason = (
            f"task={task_name} compiles no GPU kernels ahead: its demos execution "
            f"({task.demo_execution}) has no warm-up; nothing compiled"
        )
        log.warning("warmup: %s", reason)
        summary["nothing_to_warm"] = reason
    elif scene_ids:
        _warm_scenes(ctx, store, cfg, execution.warm_up, scene_ids, summary)
    else:
        summary["nothing_to_warm"] = "every scene's episodes are stored: nothing to warm up"
        log.info("warmup: %s", summary["nothing_to_warm"])
    scenes = summary["scenes"]
    warmed = [s for s in scenes if "error" not in s]
    summary["totals"] = {
        "scenes": len(scenes),
        "warmed": len(warmed),
        "failed": len(scenes) - len(warmed),
        "modules": sum(s["modules"] for s in warmed),
        "loaded": sum(s["loaded"] for s in warmed),
        "compiled": sum(s["compiled"] for s in warmed),
        "seconds": time.perf_counter() - t0,
    }
    path = atomic_write_json(summary_path(store, ctx.shard), summary)
    totals = summary["totals"]
    detail = summary["nothing_to_warm"] or (
        f"{totals['compiled']} modules compiled, {totals['failed']} scene(s) failed, "
        f"device {summary['device']}"
    )
    return {
        "scenes_warmed": totals["warmed"],
        "scenes_failed": totals["failed"],
        "modules_compiled": totals["compiled"],
        "device": summary["device"],
        "kernel_cache": summary["kernel_cache"],
        "path": str(path),
        "produced": [
            {
                "what": "scenes warmed up",
                "count": totals["warmed"],
                "path": str(path),
                "detail": detail,
            }
        ],
    }


def _warm_scenes(
    ctx: StageContext,
    store: RunStore,
    cfg: FactoryConfig,
    warm_up: Callable[[DemoScene, StageEnv, str], PreloadReport],
    scene_ids: list[str],
    summary: dict[str, Any],
) -> None:
    """Sets up and warms up each scene in turn, filling ``summary`` (``device``,
    ``kernel_cache``, one ``scenes`` entry each: ``scene_id``, ``modules`` traced, ``loaded``
    now (compiled or read from the kernel cache), ``compiled`` (new entries in the kernel
    cache), ``setup_s`` and ``seconds`` of the warm-up; or ``error``)."""
    from tqdm import tqdm

    from factory.console import terminal
    from factory.sim.backend import init_warp
    from factory.sim.kernel_cache import cached_modules, kernel_cache_dir
    from factory.tasks import get_task

    task = get_task(cfg.task)
    device = warm_device()
    cache = kernel_cache_dir(init_warp())
    summary["device"], summary["kernel_cache"] = device, cache
    env = StageEnv(
        str(store.root), str(store.episodes_shard(ctx.shard)), cfg.demos, cfg.task, cfg.seed, 1
    )
    n = len(scene_ids)
    with tqdm(total=n, desc="warmup", unit="scene", disable=None, file=terminal()) as bar:
        for i, sid in enumerate(scene_ids, 1):
            entry: dict[str, Any] = {"scene_id": sid}
            summary["scenes"].append(entry)
            t_setup = time.perf_counter()
            try:
                scene = task.demo_scene(env, sid, False)
            except FactoryError as e:
                entry["error"] = str(e)
                log.warning("warmup %d/%d %s: not warmed up: %s", i, n, sid, e)
                bar.update(1)
                continue
            entry["setup_s"] = time.perf_counter() - t_setup
            before = cached_modules(cache)
            t_warm = time.perf_counter()
            report = warm_up(scene, env, device)
            entry["seconds"] = time.perf_counter() - t_warm
            # New cache entries are the modules compiled now (another process filling the same
            # cache at this moment would count too).
            compiled = min(report.compiled, max(0, cached_modules(cache) - before))
            entry.update(modules=report.modules, loaded=report.compiled, compiled=compiled)
            if report.error:
                entry["trace_error"] = report.error
            log.info(
                "warmup %d/%d %s: %d of %d modules compiled in %.1f s (kernel cache %s: %d read, "
                "%d loaded for an earlier scene)%s",
                i,
                n,
                sid,
                compiled,
                report.modules,
                entry["seconds"],
                cache,
                report.compiled - compiled,
                report.modules - report.compiled,
                f"; the trace stopped early ({report.error}): the rest compile in stage=demos"
                if report.error
                else "",
            )
            bar.update(1)
