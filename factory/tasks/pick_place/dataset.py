"""What the fixed-base pick-and-place task writes into its LeRobot datasets.

Features of every frame (the export adds the cameras' videos and the instruction):

* ``observation.state`` (8,) float32: arm joints (rad) and the gripper opening (m);
* ``observation.ee_pose`` (7,) float32: tool position (m) and quaternion wxyz, world frame;
* ``observation.environment_state`` (14,) float32: the pick object's position (m) and
  quaternion wxyz, then the target's (the place container or support), world frame (body
  frames of the two objects); datasets exported before it lack the feature and still load;
* ``action`` (8,) float32: desired arm joints (rad) and the gripper command (m).

Declarations are plain data (LeRobot's feature format) and the readers numpy: the export
(:mod:`factory.dataset`, a floor above) takes them through
:class:`~factory.tasks.pick_place.task.PickPlaceTask`. The mobile task builds on the arm's
(:data:`ARM_NAMES`, :func:`arrays_of`, :func:`arm_state`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.errors import StoreError

LAYOUT = "fixed"
"""``layout`` of the task's datasets (their ``meta/factory.json`` holds none: written before
there were two)."""
ROBOT_TYPE = "franka_panda"
"""lerobot's ``robot_type`` of the task's datasets."""
ARM_NAMES = [f"joint{i}" for i in range(1, 8)] + ["gripper"]
"""Columns of the arm's ``observation.state`` and ``action``."""
EE_POSE_NAMES = ["x", "y", "z", "qw", "qx", "qy", "qz"]
"""Columns of ``observation.ee_pose``."""
ENV_STATE_KEY = "observation.environment_state"
ENV_STATE_NAMES = [
    f"{obj}_{c}" for obj in ("pick", "target") for c in ("x", "y", "z", "qw", "qx", "qy", "qz")
]
"""Names of ``observation.environment_state`` (world frame; m and unit quaternions)."""


def vector(names: list[str]) -> dict[str, Any]:
    """The LeRobot feature of a float32 vector with named columns."""
    return {"dtype": "float32", "shape": (len(names),), "names": list(names)}


def features() -> dict[str, dict[str, Any]]:
    """The task's features other than the cameras', in the dataset's order."""
    return {
        "observation.state": vector(ARM_NAMES),
        "observation.ee_pose": vector(EE_POSE_NAMES),
        ENV_STATE_KEY: vector(ENV_STATE_NAMES),
        "action": vector(ARM_NAMES),
    }


def arrays_of(n_frames: int, action_columns: int = len(ARM_NAMES)) -> dict[str, tuple[int, ...]]:
    """The arrays of an episode (other than the cameras') and their shapes: the arm's
    (``action_columns``: of ``action``; ``env_state``, absent from older stores, is checked when
    read)."""
    n = n_frames
    return {
        "joint_pos": (n, 7),
        "gripper": (n, 1),
        "ee_pose": (n, 7),
        "action": (n, action_columns),
    }


def arm_state(arrays: Any) -> np.ndarray:
    """The arm's ``observation.state`` columns of an episode (F, 8) float32: joints, gripper."""
    return np.concatenate(
        [
            np.asarray(arrays["joint_pos"][:], np.float32),
            np.asarray(arrays["gripper"][:], np.float32),
        ],
        axis=1,
    )


def columns(info: Any, arrays: Any, scene_json: bytes) -> dict[str, np.ndarray]:
    """The values of :func:`features` of one episode, (F, ...) each.

    Args:
        info: its ``EpisodeInfo``.
        arrays: its stored arrays (zarr group).
        scene_json: its scene's ``scene.json`` (stores recorded before ``env_state``).
    """
    return {
        "observation.state": arm_state(arrays),
        "observation.ee_pose": np.asarray(arrays["ee_pose"][:], np.float32),
        ENV_STATE_KEY: environment_state(info, arrays, scene_json),
        "action": np.asarray(arrays["action"][:], np.float32),
    }


def environment_state(info: Any, arrays: Any, scene_json: bytes) -> np.ndarray:
    """``observation.environment_state`` of an episode, (F, 14) float32.

    The recorded ``env_state`` array when the store has it; stores recorded before it get it
    from the MuJoCo states: a free body's qpos is its world position and quaternion, and the
    compiled model gives every movable object of the scene (without the cleared ones) a free
    joint in scene order, ahead of the robot's joints.

    Raises:
        StoreError: neither the array nor usable states (re-record the episode).
    """
    if "env_state" in arrays:
        out = np.asarray(arrays["env_state"][:], np.float32)
        if out.shape != (info.n_frames, 14):
            raise StoreError(
                f"episode {info.episode_id!r}: env_state has shape {out.shape}, expected "
                f"({info.n_frames}, 14) (re-record the episode)"
            )
        return out
    from factory.schema.scene import scene_from_json

    scene = scene_from_json(scene_json.decode(), f"scene of episode {info.episode_id}")
    movable = [o.id for o in scene.objects if not o.is_static and o.id not in info.cleared]
    state = np.asarray(arrays["state"][:], np.float64)
    parts = []
    for oid in (info.pick_id, info.target_id):
        if oid not in movable or 1 + 7 * (movable.index(oid) + 1) > state.shape[1]:
            raise StoreError(
                f"episode {info.episode_id!r} has no env_state and its states do not hold "
                f"{oid!r} as a free body: re-record it with this factory (stage=demos)"
            )
        adr = 1 + 7 * movable.index(oid)  # the state starts with time, then qpos
        pose = state[:, adr : adr + 7].copy()
        pose[:, 3:] /= np.linalg.norm(pose[:, 3:], axis=1, keepdims=True)
        parts.append(pose)
    return np.concatenate(parts, axis=1).astype(np.float32)


def card(meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]) -> tuple[str, list[str]]:
    """The task's part of its dataset card: the opening paragraph and the feature lines.

    Args:
        meta: the dataset's ``meta/factory.json``.
        cameras: its camera names.
        rgb: the RGB codec settings (``codec``, ``pix_fmt``).
    """
    intro = (
        "Franka Panda demonstrations planned and recorded in physically validated MuJoCo "
        f"scenes by factory {meta['factory_version'] or '(unknown version)'}."
    )
    return intro, [
        "- **`observation.state`:** 7 arm joint positions (rad) and the gripper opening (m)",
        "- **`observation.ee_pose`:** tool position (m) and quaternion (w, x, y, z), world frame",
        "- **`observation.environment_state`:** the pick object's position (m) and "
        "quaternion (w, x, y, z), then the target's, world frame (privileged state for "
        "low-dimensional policies)",
        "- **`action`:** the arm joint targets at the end of the frame (rad) and the gripper "
        "command (m; 0.08 open, negative squeezes)",
        f"- **`observation.images.<camera>`** for {', '.join(f'`{c}`' for c in cameras)}: RGB "
        f"video ({rgb.get('codec', 'h264')}, {rgb.get('pix_fmt', 'yuv420p')})",
        "- **`observation.depth.<camera>`:** depth in millimetres, packed into a lossless RGB "
        f"video: {meta['depth_encoding']}. `factory.dataset.unpack_depth_mm` reads it back "
        "exactly.",
        "- **`extras/<episode_id>/`:** `scene.json` (the scene), `model.xml` (the MuJoCo "
        "model; meshes in `extras/assets`), `robot.json` (the robot's base) and `states.npz` "
        "(full MuJoCo states per frame, for exact replay)",
    ]
