"""``stage=demos task=mobile_pick_place``: one work item of the mobile task on the CPU path.

:func:`run_mobile_item` is what :func:`factory.demos.stage.run_item` runs for the mobile task:
per scene it composes the scene with the mobile robot (:func:`~factory.tasks.mobile_pick_place.
mobile_setup`), plans each open slot with the slot's stable seed, executes and records it one
episode at a time (:func:`~factory.tasks.mobile_pick_place.execute_mobile`, one ``MjData``),
and stores the successes in the same episode store as the fixed task.

Stored episodes keep the fixed task's :class:`~factory.schema.episode.EpisodeInfo` fields,
and fill ``route`` (the route check's pick and place poses the drives ended at, their indices
in the route's lists, its pose counts, grid cell and footprint; :meth:`~factory.demos.
mobile_plan.MobilePlanner.route_record`): ``task`` is ``mobile_pick_place``, ``pick_id`` the object,
``support_id`` the pick support, ``target_id`` the place support, ``robot`` the spawn pose
(z = 0), ``phases`` the first frame of each phase (sub-tasks included), ``cameras`` the pinhole
cameras then ``fisheye_front``/``fisheye_back``. Arrays: as the fixed task (``time``,
``state``, ``joint_pos``, ``gripper``, ``ee_pose``, ``rgb/<camera>``, ``depth/<camera>``), with
``action`` of 11 columns (arm 7, gripper, base x, y, yaw) instead of 8, and in addition
``base_pose`` (F, 3), ``subtask`` (F,) int8 (index into ``SUBTASKS``) and ``subtask_done``
(F,) bool. There is no ``env_state``.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from factory.demos.slots import StageEnv, WorkItem
    from factory.tasks.mobile_pick_place import (
        MobileEpisodePlan,
        MobilePlanner,
        MobileRecordConfig,
        MobileRecording,
        MobileSetup,
    )

log = logging.getLogger(__name__)

TASK = "mobile_pick_place"


def mobile_payload(
    setup: MobileSetup,
    k: int,
    seed: int,
    plan: MobileEpisodePlan,
    rec: MobileRecording,
    cfg: MobileRecordConfig,
    recorder: str = "cpu",
) -> tuple[Any, dict[str, np.ndarray]]:
    """The metadata and arrays a successful mobile recording is stored as (episode ``k`` of
    its scene), its images drawn by the ``recorder`` (``cpu``: OpenGL, ``warp``: MuJoCo Warp's
    batch renderer, :mod:`factory.demos.mobile_gpu_pipeline`)."""
    from factory.demos.slots import episode_arrays, episode_meta
    from factory.schema.episode import RobotBase
    from factory.tasks.mobile_pick_place import STATE_SPEC

    objs = setup.objects
    scene = setup.scene
    instruction = (
        scene.task.instruction
        if scene.task is not None and scene.task.instruction
        else f"pick up the {objs.pick.category} and put it on the {objs.place_support.category}"
    )
    assert rec.outcome is not None
    meta = episode_meta(
        setup,
        k,
        seed,
        plan,
        rec,
        task=TASK,
        instruction=instruction,
        settings=cfg,
        rec_cfg=cfg,
        state_spec=int(STATE_SPEC),
        recorder=recorder,
        pick_id=objs.pick.id,
        target_id=objs.place_support.id,
        support_id=objs.pick_support.id,
        robot=RobotBase(float(plan.spawn[0]), float(plan.spawn[1]), 0.0, float(plan.spawn[2])),
        route=dict(plan.route),
    )
    arrays = episode_arrays(
        rec,
        base_pose=rec.base_pose.astype(np.float32),
        subtask=rec.subtask.astype(np.int8),
        subtask_done=rec.subtask_done.astype(bool),
    )
    return meta, arrays


def mobile_scene_planner(run_dir: Any, scene_id: str, dc: Any) -> tuple[MobileSetup, MobilePlanner]:
    """A scene of a run composed with the mobile robot, and its planner with the demos
    settings ``dc`` (``demos.*``): what ``stage=demos`` plans in and what the closed-loop env
    (:mod:`factory.policy.mobile_env`) simulates.

    Raises:
        FactoryError: the scene cannot be loaded or cannot host the task.
    """
    from factory.demos.plan.planner import PlannerConfig
    from factory.store import RunStore
    from factory.tasks.mobile_pick_place import MobileMotionConfig, MobilePlanner, mobile_setup
    from factory.tasks.pick_place.plan import MotionConfig

    run_store = RunStore(run_dir)
    setup = mobile_setup(run_store.load_scene(scene_id), run_store.assets_dir)
    motion = MobileMotionConfig(
        arm=MotionConfig(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    )
    planner = MobilePlanner(
        setup,
        motion,
        planner_cfg=PlannerConfig(timeout=dc.plan_timeout),
        max_grasps=dc.max_grasps,
        grasp_facing=dc.grasp_facing,
    )
    return setup, planner


def run_mobile_item(env: StageEnv, item: WorkItem) -> dict[str, Any]:
    """Fills the item's slots with mobile episodes; returns ``run_item``'s statistics.

    The cameras are ``demos.cameras`` (pinhole, on the robot) plus both fisheye cameras;
    ``demos.randomize``, ``demos.batch`` (episodes run one by one) and the GPU executor do
    not apply. Each episode logs one INFO line (slot, attempt, outcome, seconds of planning,
    simulation and rendering); a scene where the base cannot reach both supports logs one
    warning and counts its open slots as ``scene_unusable``.
    """
    import time

    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.slots import episode_id, episode_seed, item_stats
    from factory.errors import FactoryError
    from factory.tasks.mobile_pick_place import (
        FISHEYE_CAMERAS,
        MobileEpisodePlan,
        MobileRecordConfig,
        MobileRenderer,
        execute_mobile,
    )

    dc = env.demos
    out: dict[str, Any] = item_stats(item.scene_id)
    store = EpisodeStore(env.store_path)
    open_slots = [k for k in item.slots if episode_id(item.scene_id, k) not in store]
    if not open_slots:
        return out
    t0 = time.perf_counter()
    try:
        setup, planner = mobile_scene_planner(env.run_dir, item.scene_id, dc)
    except FactoryError as e:
        out["error"] = str(e)
        out["failures"]["scene_unusable"] += len(open_slots)
        return out
    out["cleared"] = list(setup.cleared)
    if planner.unusable:
        out["error"] = f"the robot's base cannot work there: {planner.unusable}"
        out["failures"]["scene_unusable"] += len(open_slots)
        return out
    log.info(
        "scene %s: set up in %.1f s%s",
        item.scene_id,
        time.perf_counter() - t0,
        f", took out {', '.join(setup.cleared)} for the base" if setup.cleared else "",
    )
    cfg = MobileRecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=(*dc.cameras, *FISHEYE_CAMERAS),
        depth=dc.depth,
        render=dc.render,
    )
    renderer = MobileRenderer(setup.model, cfg) if cfg.render else None
    try:
        for k in open_slots:
            for attempt in range(dc.attempts):
                t_ep = time.perf_counter()
                seed = episode_seed(env.seed, item.scene_id, k, attempt)
                res = planner.plan_episode(seed)
                if not isinstance(res, MobileEpisodePlan):
                    out["failures"][res.reason] += 1
                    log.info(
                        "scene %s slot %d attempt %d: %s after %.1f s of planning: %s",
                        item.scene_id,
                        k,
                        attempt,
                        res.reason,
                        res.seconds,
                        res.detail,
                    )
                    continue
                out["plan"].append(res.seconds)
                out["segments"].extend(res.plan_seconds.values())
                rec = execute_mobile(setup, res, cfg, renderer)
                out["simulate"] += rec.sim_seconds
                out["render"] += rec.render_seconds
                assert rec.outcome is not None
                verdict = "success" if rec.outcome.success else rec.outcome.reason
                log.info(
                    "scene %s slot %d attempt %d: %s in %.1f s (plan %.1f s, simulate %.1f s, "
                    "render %.1f s; %d frames, %.1f s of motion)",
                    item.scene_id,
                    k,
                    attempt,
                    verdict,
                    time.perf_counter() - t_ep,
                    res.seconds,
                    rec.sim_seconds,
                    rec.render_seconds,
                    len(rec.time),
                    float(rec.time[-1]),
                )
                if not rec.outcome.success:
                    out["failures"][rec.outcome.reason] += 1
                    log.debug("scene %s slot %d: %s", item.scene_id, k, rec.outcome.details)
                    continue
                store.write(*mobile_payload(setup, k, seed, res, rec, cfg))
                out["frames"] += len(rec.time)
                out["new"] += 1
                break
    finally:
        if renderer is not None:
            renderer.close()
    return out
