"""``stage=demos``: planned, executed and recorded demonstrations in every scene of a run.

Per scene of this shard: choose the robot's base spot, then fill ``demos.episodes_per_scene``
episode slots. Each round plans every open slot (new object poses and seeds; optionally in a
process pool), executes the plans together in batches, checks success and stores the
successful episodes in ``episodes/shard-<k>.zarr``. Failures are counted by reason. A scene
that cannot host the task (objects missing, no base spot) is reported with its reason and the
run goes on. Re-running skips stored episodes, so an interrupted run resumes.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import ConfigError, FactoryError, StoreError
from factory.stages import StageContext
from factory.store import atomic_write_json

log = logging.getLogger(__name__)

TASKS: dict[str, str] = {"pick_place": "pick up an object and put it in or on a target"}
"""Robot tasks ``stage=demos`` can record (``task=<name>``)."""

SUMMARY_SCHEMA_VERSION = 1


def episode_seed(root: int, scene_id: str, slot: int, attempt: int) -> int:
    """A stable per-episode seed (independent of shard layout and order)."""
    digest = hashlib.sha256(f"{root}/{scene_id}/{slot}/{attempt}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def episode_id(scene_id: str, slot: int) -> str:
    return f"{scene_id}-ep{slot:03d}"


@dataclass(frozen=True)
class _Job:
    scene_json: str
    assets: str | None
    placement: Any
    rig: Any
    motion: Any
    planner: Any
    max_grasps: int
    randomize: bool
    seed: int


_PLANNERS: dict[tuple[str, Any], Any] = {}


def _planner_for(job: _Job) -> Any:
    from factory.demos.pick_place import EpisodePlanner, SceneSetup, compose
    from factory.demos.robot import RobotIndex
    from factory.demos.task import task_objects
    from factory.schema import load_scene

    key = (job.scene_json, job.placement)
    if key not in _PLANNERS:
        _PLANNERS.clear()
        scene = load_scene(job.scene_json)
        model = compose(scene, job.assets, job.placement, job.rig)
        setup = SceneSetup(
            scene, task_objects(scene), job.placement, model, RobotIndex.of(model), job.rig, 0.0
        )
        _PLANNERS[key] = EpisodePlanner(
            setup, planner_cfg=job.planner, motion=job.motion, max_grasps=job.max_grasps
        )
    return _PLANNERS[key]


def _plan_job(job: _Job) -> Any:
    """Plans one episode (runs in a worker process or inline)."""
    return _planner_for(job).plan_episode(job.seed, job.randomize)


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

    from factory import __version__
    from factory.demos.episodes import EpisodeStore
    from factory.demos.execute import STATE_SPEC, FrameRenderer, RecordConfig, execute
    from factory.demos.pick_place import EpisodePlan, MotionConfig, setup_scene
    from factory.demos.planner import PlannerConfig
    from factory.schema.episode import EpisodeInfo, RobotBase

    cfg = ctx.cfg
    dc = cfg.demos
    if cfg.task not in TASKS:
        raise ConfigError(f"unknown task {cfg.task!r}: choose one of {', '.join(TASKS)}")
    if dc.backend != "cpu":
        raise ConfigError(
            f"demos.backend={dc.backend!r} is not available: batched execution runs on 'cpu' "
            "(mujoco.batch)"
        )
    if dc.depth not in ("uint16_mm", "float32"):
        raise ConfigError(f"demos.depth must be uint16_mm or float32, got {dc.depth!r}")
    unknown = [c for c in dc.cameras if c not in ("left", "right", "wrist")]
    if unknown:
        raise ConfigError(f"demos.cameras: unknown camera(s) {unknown}; use left, right, wrist")
    if dc.episodes_per_scene < 1 or dc.attempts < 1 or dc.batch < 1:
        raise ConfigError("demos.episodes_per_scene, demos.attempts and demos.batch must be >= 1")
    store = ctx.require_store()
    ids = store.scene_ids()
    if not ids:
        raise StoreError(f"no scenes in {store.scenes_dir}: run stage=generate or ingest first")
    scene_ids = ctx.shard.select(ids)
    episodes = EpisodeStore(store.episodes_shard(ctx.shard))
    episodes.clean_staging()
    rec_cfg = RecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=tuple(dc.cameras),
        depth=dc.depth,
        render=dc.render,
    )
    motion = MotionConfig(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    planner_cfg = PlannerConfig(timeout=dc.plan_timeout)
    workers = dc.workers or (os.cpu_count() or 1)
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    t_start = time.perf_counter()
    scenes: dict[str, Any] = {}
    plan_times: list[float] = []
    segment_times: list[float] = []
    sim_s = render_s = 0.0
    n_ok = 0
    reasons: Counter[str] = Counter()
    total_slots = len(scene_ids) * dc.episodes_per_scene
    bar = tqdm(total=total_slots, desc="demos", unit="episode", disable=None)
    try:
        for scene_id in scene_ids:
            slots = [
                k for k in range(dc.episodes_per_scene) if episode_id(scene_id, k) not in episodes
            ]
            bar.update(dc.episodes_per_scene - len(slots))
            info: dict[str, Any] = {
                "episodes": dc.episodes_per_scene - len(slots),
                "new": 0,
                "failures": {},
            }
            scenes[scene_id] = info
            if not slots:
                continue
            scene = store.load_scene(scene_id)
            try:
                setup = setup_scene(scene, store.assets_dir)
            except FactoryError as e:
                info["error"] = str(e)
                reasons["scene_unusable"] += len(slots)
                log.warning("scene %s: no demos: %s", scene_id, e)
                bar.update(len(slots))
                continue
            info["robot_base"] = [setup.placement.x, setup.placement.y, setup.placement.yaw]
            renderer = FrameRenderer(setup.model, rec_cfg) if rec_cfg.render else None
            fails: Counter[str] = Counter()
            attempt = {k: 0 for k in slots}
            open_slots = list(slots)
            while open_slots:
                jobs = [
                    _Job(
                        str(store.scene_json(scene_id)),
                        str(store.assets_dir),
                        setup.placement,
                        setup.rig,
                        motion,
                        planner_cfg,
                        dc.max_grasps,
                        dc.randomize,
                        episode_seed(cfg.seed, scene_id, k, attempt[k]),
                    )
                    for k in open_slots
                ]
                results = list(pool.map(_plan_job, jobs)) if pool else [_plan_job(j) for j in jobs]
                planned: list[tuple[int, _Job, EpisodePlan]] = []
                for k, job, res in zip(open_slots, jobs, results, strict=True):
                    if isinstance(res, EpisodePlan):
                        planned.append((k, job, res))
                        plan_times.append(res.seconds)
                        segment_times.extend(res.plan_seconds.values())
                    else:
                        fails[res.reason] += 1
                        log.info("scene %s slot %d: plan failed: %s", scene_id, k, res.detail)
                done: set[int] = set()
                for start in range(0, len(planned), dc.batch):
                    chunk = planned[start : start + dc.batch]
                    recs = execute(setup, [p for _, _, p in chunk], rec_cfg, dc.nthread, renderer)
                    for (k, job, plan), rec in zip(chunk, recs, strict=True):
                        sim_s += rec.sim_seconds
                        render_s += rec.render_seconds
                        assert rec.outcome is not None
                        if not rec.outcome.success:
                            fails[rec.outcome.reason] += 1
                            continue
                        per_frame = max(1, round(1.0 / (dc.fps * setup.model.opt.timestep)))
                        meta = EpisodeInfo(
                            episode_id=episode_id(scene_id, k),
                            scene_id=scene_id,
                            task=cfg.task,
                            instruction=scene.task.instruction
                            if scene.task and scene.task.instruction
                            else f"put the {setup.objects.pick.category.replace('_', ' ')} "
                            f"{setup.objects.relation} the "
                            f"{setup.objects.target.category.replace('_', ' ')}",
                            seed=job.seed,
                            success=True,
                            failure_reason="",
                            pick_id=setup.objects.pick.id,
                            target_id=setup.objects.target.id,
                            support_id=setup.objects.support.id,
                            robot=RobotBase(
                                setup.placement.x,
                                setup.placement.y,
                                setup.placement.z,
                                setup.placement.yaw,
                            ),
                            fps=dc.fps,
                            timestep=float(setup.model.opt.timestep),
                            n_frames=len(rec.time),
                            cameras=list(rec_cfg.cameras) if rec_cfg.render else [],
                            image_size=[dc.height, dc.width],
                            depth_format=dc.depth,
                            state_spec=int(STATE_SPEC),
                            phases={n: int(np.ceil(s / per_frame)) for n, s in plan.phases.items()},
                            grasp_width=plan.grasp_width,
                            plan_seconds=plan.plan_seconds,
                            outcome=rec.outcome.details,
                            factory_version=__version__,
                        )
                        arrays: dict[str, np.ndarray] = {
                            "time": rec.time,
                            "state": rec.state,
                            "joint_pos": rec.joint_pos.astype(np.float32),
                            "gripper": rec.gripper.astype(np.float32),
                            "ee_pose": rec.ee_pose.astype(np.float32),
                            "action": rec.action.astype(np.float32),
                        }
                        for cam, im in rec.rgb.items():
                            arrays[f"rgb/{cam}"] = im
                        for cam, dp in rec.depth.items():
                            arrays[f"depth/{cam}"] = dp
                        episodes.write(meta, arrays)
                        done.add(k)
                        info["new"] += 1
                        n_ok += 1
                        bar.update(1)
                for k in open_slots:
                    if k not in done:
                        attempt[k] += 1
                exhausted = [k for k in open_slots if k not in done and attempt[k] >= dc.attempts]
                bar.update(len(exhausted))
                open_slots = [k for k in open_slots if k not in done and attempt[k] < dc.attempts]
            if renderer is not None:
                renderer.close()
            info["episodes"] += info["new"]
            info["failures"] = dict(fails)
            reasons.update(fails)
    finally:
        bar.close()
        if pool is not None:
            pool.shutdown()
        episodes.clean_staging()
    wall = time.perf_counter() - t_start
    summary = {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "task": cfg.task,
        "shard": ctx.shard.name,
        "store": str(Path(episodes.path).relative_to(store.root)),
        "episodes_stored": len(episodes),
        "new_successes": n_ok,
        "failures": dict(reasons),
        "success_rate": n_ok
        / max(1, n_ok + sum(v for k, v in reasons.items() if k != "scene_unusable")),
        "scenes": scenes,
        "seconds": {
            "wall": wall,
            "plan_per_episode": _stats(plan_times),
            "plan_per_segment": _stats(segment_times),
            "simulate": sim_s,
            "render": render_s,
        },
    }
    atomic_write_json(store.root / "episodes" / f"summary-{ctx.shard.name}.json", summary)
    log.info(
        "demos: %d new successful episodes, failures %s, %.1f s",
        n_ok,
        dict(reasons) or "none",
        wall,
    )
    return {k: summary[k] for k in ("episodes_stored", "new_successes", "failures", "success_rate")}
