"""``stage=demos`` on the CPU executor: one work item (a scene and some of its episode slots)
planned, executed, recorded and stored in one process (:func:`run_item`), for every task.

The item's scene comes from the task (:func:`~factory.demos.execution.cached_scene`); in
rounds, the open slots of a round (:attr:`~factory.demos.execution.Execution.round_slots`:
all of them for a batch of worlds, one for a task that simulates an episode at a time) are
planned with their slot's next seed, executed and recorded together by the task's
:class:`~factory.demos.execution.CpuRecorder`, and the successes stored; a failed slot is
tried again with its next seed up to ``demos.attempts`` times. The stage runs items in worker
processes (:func:`run_item_logged`); the GPU pipeline hands the episodes that failed in its
execution to the same function, with the attempts they have left.
"""

from __future__ import annotations

import logging
from typing import Any

from factory.demos.execution import cached_scene, execution_of
from factory.demos.record.slots import StageEnv, WorkItem, episode_id, episode_seed, item_stats
from factory.errors import FactoryError

__all__ = ["run_item", "run_item_logged"]

log = logging.getLogger(__name__)


def run_item(
    env: StageEnv, item: WorkItem, first_attempts: dict[int, int] | None = None
) -> dict[str, Any]:
    """Fills the item's slots (in a worker process or inline); returns its statistics
    (:func:`~factory.demos.record.slots.item_stats`, and the scene's summary keys).

    Args:
        env: the stage's settings.
        item: the scene and its slots.
        first_attempts: slot -> the attempt (seed) to start from (default 0): the GPU
            executor's retries continue where its own attempts stopped.
    """
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks import get_task

    dc = env.demos
    sid = item.scene_id
    out: dict[str, Any] = item_stats(sid)
    store = EpisodeStore(env.store_path)
    attempt = {k: (first_attempts or {}).get(k, 0) for k in item.slots}
    open_slots = [
        k for k in item.slots if episode_id(sid, k) not in store and attempt[k] < dc.attempts
    ]
    if not open_slots:
        return out
    try:
        scene = cached_scene(env, sid)
    except FactoryError as e:
        out["error"] = str(e)
        out["failures"]["scene_unusable"] += len(open_slots)
        return out
    out.update(scene.summary())
    execution = execution_of(get_task(env.task))
    size = execution.round_slots or len(open_slots)
    recorder = execution.cpu_recorder(scene, env)
    try:
        for start in range(0, len(open_slots), size):
            slots = open_slots[start : start + size]
            while slots:
                planned: list[tuple[int, int, Any]] = []
                for k in slots:
                    seed = episode_seed(env.seed, sid, k, attempt[k])
                    res = scene.plan(seed)
                    if isinstance(res, scene.plan_type):
                        planned.append((k, seed, res))
                        out["plan"].append(res.seconds)
                        out["segments"].extend(res.plan_seconds.values())
                        continue
                    out["failures"][res.reason] += 1
                    log.info(
                        "scene %s slot %d attempt %d: %s after %.1f s of planning: %s",
                        sid,
                        k,
                        attempt[k],
                        res.reason,
                        res.seconds,
                        res.detail,
                    )
                done: set[int] = set()
                recs = recorder.execute(planned, attempt) if planned else []
                for (k, seed, plan), rec in zip(planned, recs, strict=True):
                    out["simulate"] += rec.sim_seconds
                    out["render"] += rec.render_seconds
                    assert rec.outcome is not None
                    if not rec.outcome.success:
                        out["failures"][rec.outcome.reason] += 1
                        log.debug("scene %s slot %d: %s", sid, k, rec.outcome.details)
                        continue
                    store.write(*scene.payload(k, seed, plan, rec, recorder.rec_cfg))
                    out["frames"] += len(rec.time)
                    out["new"] += 1
                    done.add(k)
                for k in slots:
                    if k not in done:
                        attempt[k] += 1
                slots = [k for k in slots if k not in done and attempt[k] < dc.attempts]
    finally:
        recorder.close()
    return out


def run_item_logged(
    env: StageEnv, item: WorkItem, first_attempts: dict[int, int] | None = None
) -> dict[str, Any]:
    """:func:`run_item` in a worker process (warnings logged)."""
    logging.basicConfig(level=logging.WARNING)
    return run_item(env, item, first_attempts)
