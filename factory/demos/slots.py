"""Episode slots of ``stage=demos``: their seeds and ids, work items, the scene set-up each
process keeps, and writing a recorded episode (shared by the CPU path in
:mod:`factory.demos.stage`, the GPU pipeline in :mod:`factory.demos.gpu_pipeline` and the
mobile task's :mod:`factory.demos.mobile_items`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.config import DemosConfig


def episode_seed(root: int, scene_id: str, slot: int, attempt: int) -> int:
    """A stable per-episode seed (independent of shard layout, workers and order)."""
    digest = hashlib.sha256(f"{root}/{scene_id}/{slot}/{attempt}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def episode_id(scene_id: str, slot: int) -> str:
    return f"{scene_id}-ep{slot:03d}"


@dataclass(frozen=True)
class WorkItem:
    """A scene and the episode slots to fill in it."""

    scene_id: str
    slots: tuple[int, ...]


def slots_by_scene(items: list[WorkItem]) -> dict[str, list[int]]:
    """The slots of ``items`` per scene, scenes in their first item's order (the GPU
    pipelines take a scene's slots together)."""
    by_scene: dict[str, list[int]] = {}
    for it in items:
        by_scene.setdefault(it.scene_id, []).extend(it.slots)
    return by_scene


@dataclass(frozen=True)
class StageEnv:
    """What a worker needs besides the item (picklable)."""

    run_dir: str
    store_path: str
    demos: DemosConfig
    task: str
    seed: int
    nthread: int


def item_stats(scene_id: str, **extra: Any) -> dict[str, Any]:
    """A fresh statistics dict of one work item (what :func:`factory.demos.stage.run` sums)."""
    from collections import Counter

    return {
        "scene_id": scene_id,
        "new": 0,
        "failures": Counter(),
        "error": None,
        "plan": [],
        "segments": [],
        "simulate": 0.0,
        "render": 0.0,
        "frames": 0,
        **extra,
    }


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


def scene_planner(run_dir: str | Path, scene_id: str, dc: DemosConfig) -> tuple[Any, Any]:
    """A scene of a run composed with the robot as ``stage=demos`` records it, and its planner.

    The base spot, cleared objects and cameras come from
    :func:`~factory.tasks.pick_place.plan.setup_scene` (deterministic per scene); island sleeping
    follows ``demos.sleep``; the planner's timing, timeout and grasp count follow ``demos``.

    Returns:
        ``(SceneSetup, EpisodePlanner)``.

    Raises:
        TaskError: the scene cannot host the task (objects missing, no base spot).
    """
    import mujoco

    from factory.demos.plan.planner import PlannerConfig
    from factory.store import RunStore
    from factory.tasks.pick_place.plan import EpisodePlanner, MotionConfig, setup_scene

    store = RunStore(run_dir)
    scene = store.load_scene(scene_id)
    setup = setup_scene(scene, store.assets_dir, freeze_beyond=dc.freeze_beyond)
    if not dc.sleep:
        setup.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    motion = MotionConfig(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    planner = EpisodePlanner(
        setup,
        planner_cfg=PlannerConfig(timeout=dc.plan_timeout),
        motion=motion,
        max_grasps=dc.max_grasps,
        grasp_facing=dc.grasp_facing,
    )
    return setup, planner


_SETUPS: dict[str, Any] = {}
_KEEP_SETUPS = 3
"""Scene setups a process keeps (the GPU pipeline's planners see the tasks of two scenes
interleaved: the one on the GPU and the next)."""


def cached_setup(env: StageEnv, scene_id: str) -> Any:
    """The scene's setup and planner, made once per process and scene (the last few kept)."""
    if scene_id in _SETUPS:
        _SETUPS[scene_id] = _SETUPS.pop(scene_id)  # most recently used last
    else:
        while len(_SETUPS) >= _KEEP_SETUPS:
            del _SETUPS[next(iter(_SETUPS))]
        _SETUPS[scene_id] = scene_planner(env.run_dir, scene_id, env.demos)
    return _SETUPS[scene_id]


def episode_instruction(setup: Any) -> str:
    """The scene's task instruction, else one made from the task objects."""
    scene, objects = setup.scene, setup.objects
    if scene.task and scene.task.instruction:
        return str(scene.task.instruction)
    return (
        f"put the {objects.pick.category.replace('_', ' ')} {objects.relation} the "
        f"{objects.target.category.replace('_', ' ')}"
    )


def store_episode(store_path: str, meta: Any, arrays: dict[str, np.ndarray]) -> None:
    """Writes one episode into the store at ``store_path`` (run in writer processes: each has
    its own zarr event loop, so episodes compress and write in parallel). Arrays given as
    :class:`~factory.demos.execute.shared_frames.SharedView` are read in place from the caller's
    shared memory."""
    from factory.demos.execute.shared_frames import opened
    from factory.demos.record.episodes import EpisodeStore

    EpisodeStore(store_path).write(meta, opened(arrays))


def episode_meta(
    setup: Any,
    k: int,
    seed: int,
    plan: Any,
    rec: Any,
    *,
    task: str,
    instruction: str,
    settings: Any,
    rec_cfg: Any,
    state_spec: int,
    recorder: str,
    **fields: Any,
) -> Any:
    """The metadata of a successful recording stored as episode ``k`` of its scene (the
    fields every task fills the same way; shared by the fixed and the mobile task).

    Args:
        setup: the scene set-up (``scene``, ``model``, ``cleared``).
        k: the episode slot.
        seed: the episode's seed.
        plan: the episode plan (``phases`` in steps, ``grasp_width``, ``plan_seconds``).
        rec: the recording (``time``, ``outcome``).
        task: the task name stored.
        instruction: the task instruction stored.
        settings: frame rate, image size and depth format (``fps``, ``width``, ``height``,
            ``depth``).
        rec_cfg: the recording settings (``cameras``, ``render``).
        state_spec: the MuJoCo state spec of the ``state`` array.
        recorder: the executor that recorded it (``cpu`` or ``warp``).
        **fields: the task's own :class:`~factory.schema.episode.EpisodeInfo` fields (object
            ids, robot pose, ...).

    Returns:
        The :class:`~factory.schema.episode.EpisodeInfo`.
    """
    from factory import __version__
    from factory.schema.episode import EpisodeInfo

    per_frame = max(1, round(1.0 / (settings.fps * setup.model.opt.timestep)))
    scene_id = setup.scene.id
    return EpisodeInfo(
        episode_id=episode_id(scene_id, k),
        scene_id=scene_id,
        task=task,
        instruction=instruction,
        seed=seed,
        success=True,
        failure_reason="",
        fps=settings.fps,
        timestep=float(setup.model.opt.timestep),
        n_frames=len(rec.time),
        cameras=list(rec_cfg.cameras) if rec_cfg.render else [],
        image_size=[settings.height, settings.width],
        depth_format=settings.depth,
        state_spec=int(state_spec),
        phases={n: int(np.ceil(s / per_frame)) for n, s in plan.phases.items()},
        grasp_width=plan.grasp_width,
        plan_seconds=plan.plan_seconds,
        outcome=rec.outcome.details,
        factory_version=__version__,
        cleared=list(setup.cleared),
        recorder=recorder,
        **fields,
    )


def episode_arrays(rec: Any, **extra: np.ndarray) -> dict[str, np.ndarray]:
    """The arrays a recording is stored as: the robot signals every task records, then the
    task's own ``extra`` arrays (as given), then ``rgb/<camera>`` and ``depth/<camera>``."""
    arrays: dict[str, np.ndarray] = {
        "time": rec.time,
        "state": rec.state,
        "joint_pos": rec.joint_pos.astype(np.float32),
        "gripper": rec.gripper.astype(np.float32),
        "ee_pose": rec.ee_pose.astype(np.float32),
        "action": rec.action.astype(np.float32),
        **extra,
    }
    for cam, im in rec.rgb.items():
        arrays[f"rgb/{cam}"] = im
    for cam, dp in rec.depth.items():
        arrays[f"depth/{cam}"] = dp
    return arrays


def episode_payload(
    env: StageEnv,
    setup: Any,
    k: int,
    seed: int,
    plan: Any,
    rec: Any,
    rec_cfg: Any,
    instruction: str,
    recorder: str = "cpu",
) -> tuple[Any, dict[str, np.ndarray]]:
    """The metadata and arrays a successful recording is stored as (episode ``k``), recorded
    by the ``recorder`` executor (``cpu`` or ``warp``)."""
    from factory.demos.execute.cpu import STATE_SPEC
    from factory.schema.episode import RobotBase

    objects = setup.objects
    meta = episode_meta(
        setup,
        k,
        seed,
        plan,
        rec,
        task=env.task,
        instruction=instruction,
        settings=env.demos,
        rec_cfg=rec_cfg,
        state_spec=int(STATE_SPEC),
        recorder=recorder,
        pick_id=objects.pick.id,
        target_id=objects.target.id,
        support_id=objects.support.id,
        robot=RobotBase(
            setup.placement.x, setup.placement.y, setup.placement.z, setup.placement.yaw
        ),
        frozen=list(getattr(setup, "frozen", ())),
        appearance=getattr(rec, "appearance", None),
    )
    return meta, episode_arrays(rec, env_state=rec.env_state.astype(np.float32))
