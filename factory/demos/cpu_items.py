"""``stage=demos`` on the CPU executor: one work item (a scene and some of its episode slots)
planned, executed, recorded and stored in one process (:func:`run_item`).

The stage runs items in worker processes (:func:`run_item_logged`); the GPU pipeline hands the
episodes that failed in its execution to the same function, with the attempts they have left.
"""

from __future__ import annotations

import logging
from typing import Any

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
)
from factory.errors import FactoryError

log = logging.getLogger(__name__)


def run_item(
    env: StageEnv, item: WorkItem, first_attempts: dict[int, int] | None = None
) -> dict[str, Any]:
    """Fills the item's slots (in a worker process or inline); returns its statistics.

    Args:
        env: the stage's settings.
        item: the scene and its slots.
        first_attempts: slot -> the attempt (seed) to start from (default 0): the GPU
            executor's retries continue where its own attempts stopped.
    """
    from factory.demos.execute.cpu import FrameRenderer, execute
    from factory.demos.record.appearance import episode_looks, setup_index
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks.pick_place.plan import EpisodePlan

    if env.task == "mobile_pick_place":  # CPU path, one episode at a time
        from factory.demos.mobile_items import run_mobile_item

        return run_mobile_item(env, item)
    dc = env.demos
    out: dict[str, Any] = item_stats(item.scene_id)
    try:
        setup, planner = cached_setup(env, item.scene_id)
    except FactoryError as e:
        out["error"] = str(e)
        out["failures"]["scene_unusable"] += len(item.slots)
        return out
    out["robot_base"] = [setup.placement.x, setup.placement.y, setup.placement.yaw]
    out["cleared"] = list(setup.cleared)
    rec_cfg = record_config(dc)
    store = EpisodeStore(env.store_path)
    renderer = FrameRenderer(setup.model, rec_cfg) if rec_cfg.render else None
    look_index = setup_index(setup, rec_cfg.cameras) if rec_cfg.render else None
    instruction = episode_instruction(setup)
    attempt = {k: (first_attempts or {}).get(k, 0) for k in item.slots}
    open_slots = [
        k
        for k in item.slots
        if episode_id(item.scene_id, k) not in store and attempt[k] < dc.attempts
    ]
    try:
        while open_slots:
            planned: list[tuple[int, int, EpisodePlan]] = []
            for k in open_slots:
                seed = episode_seed(env.seed, item.scene_id, k, attempt[k])
                res = planner.plan_episode(seed, dc.randomize)
                if isinstance(res, EpisodePlan):
                    planned.append((k, seed, res))
                    out["plan"].append(res.seconds)
                    out["segments"].extend(res.plan_seconds.values())
                else:
                    out["failures"][res.reason] += 1
                    log.info("scene %s slot %d: plan failed: %s", item.scene_id, k, res.detail)
            looks = None
            if look_index is not None:
                seeds = [seed for _, seed, _ in planned]
                looks = episode_looks(setup.model, look_index, dc.appearance, seeds)
            plans = [p for _, _, p in planned]
            recs = execute(setup, plans, rec_cfg, env.nthread, renderer, looks)
            done: set[int] = set()
            for (k, seed, plan), rec in zip(planned, recs, strict=True):
                out["simulate"] += rec.sim_seconds
                out["render"] += rec.render_seconds
                assert rec.outcome is not None
                if not rec.outcome.success:
                    out["failures"][rec.outcome.reason] += 1
                    continue
                store.write(*episode_payload(env, setup, k, seed, plan, rec, rec_cfg, instruction))
                out["frames"] += len(rec.time)
                done.add(k)
                out["new"] += 1
            for k in open_slots:
                if k not in done:
                    attempt[k] += 1
            open_slots = [k for k in open_slots if k not in done and attempt[k] < dc.attempts]
    finally:
        if renderer is not None:
            renderer.close()
    return out


def run_item_logged(
    env: StageEnv, item: WorkItem, first_attempts: dict[int, int] | None = None
) -> dict[str, Any]:
    """:func:`run_item` in a worker process (warnings logged)."""
    logging.basicConfig(level=logging.WARNING)
    return run_item(env, item, first_attempts)
