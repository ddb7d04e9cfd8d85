"""What a successful recording is stored as: its :class:`~factory.schema.episode.EpisodeInfo`
(:func:`episode_meta`) and its arrays (:func:`episode_arrays`), the parts every task fills the
same way; a task's :meth:`~factory.demos.record.scene.DemoScene.payload` adds its own fields
and arrays."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from factory.demos.record.slots import episode_id
from factory.schema.episode import EpisodeInfo

__all__ = ["STATE_SPEC", "episode_arrays", "episode_meta"]

STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
"""The recorded MuJoCo state (``mj_setState`` with it reproduces the simulation exactly)."""


def episode_meta(
    setup: Any,
    k: int,
    seed: int,
    plan: Any,
    rec: Any,
    *,
    task: str,
    instruction: str,
    rec_cfg: Any,
    recorder: str,
    **fields: Any,
) -> EpisodeInfo:
    """The metadata of a successful recording stored as episode ``k`` of its scene.

    Args:
        setup: the scene set-up (``scene``, ``model``, ``cleared``).
        k: the episode slot.
        seed: the episode's seed.
        plan: the episode plan (``phases`` in physics steps, ``grasp_width`` m,
            ``plan_seconds``).
        rec: the recording (``time`` (F,) s, ``outcome``).
        task: the task name stored.
        instruction: the task instruction stored.
        rec_cfg: the recording settings (``fps`` Hz, ``width``/``height`` px, ``depth``,
            ``cameras``, ``render``).
        recorder: the executor that recorded it (``cpu`` or ``warp``).
        **fields: the task's own :class:`~factory.schema.episode.EpisodeInfo` fields (object
            ids, robot pose, ...).
    """
    from factory import __version__

    per_frame = max(1, round(1.0 / (rec_cfg.fps * setup.model.opt.timestep)))
    scene_id = setup.scene.id
    return EpisodeInfo(
        episode_id=episode_id(scene_id, k),
        scene_id=scene_id,
        task=task,
        instruction=instruction,
        seed=seed,
        success=True,
        failure_reason="",
        fps=rec_cfg.fps,
        timestep=float(setup.model.opt.timestep),
        n_frames=len(rec.time),
        cameras=list(rec_cfg.cameras) if rec_cfg.render else [],
        image_size=[rec_cfg.height, rec_cfg.width],
        depth_format=rec_cfg.depth,
        state_spec=int(STATE_SPEC),
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
    """The arrays a recording is stored as: the robot signals every task records (``time``,
    ``state``, ``joint_pos``, ``gripper``, ``ee_pose``, ``action``; F rows each), then the
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
