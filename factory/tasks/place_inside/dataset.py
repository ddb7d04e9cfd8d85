"""What ``task=place_inside`` writes into its LeRobot datasets.

Features of every frame (the export adds the cameras' videos and the instruction, "put the
can in the drawer of the base cabinet"):

* ``observation.state`` (8,) float32: arm joints (rad) and the gripper opening (m);
* ``observation.ee_pose`` (7,) float32: tool position (m) and quaternion wxyz, world frame;
* ``observation.environment_state`` (9,) float32: the part's joint position (m for a drawer's
  slide, rad for a hinge; 0 closed), its share of the joint's range (0 closed, 1 at the
  limit), the object's position (m) and quaternion (wxyz), world frame;
* ``action`` (8,) float32: desired arm joints (rad) and the gripper command (m).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.errors import StoreError
from factory.tasks.pick_place.dataset import ARM_NAMES, EE_POSE_NAMES, arm_state, vector

__all__ = ["ENV_STATE_NAMES", "LAYOUT", "ROBOT_TYPE", "arrays_of", "card", "columns", "features"]

LAYOUT = "place_inside"
"""The layout of the task's datasets (``meta/factory.json``'s ``layout``)."""
ROBOT_TYPE = "franka_panda"
"""lerobot's ``robot_type`` of the task's datasets."""
ENV_STATE_KEY = "observation.environment_state"
ENV_STATE_NAMES = [
    "joint",
    "joint_fraction",
    "object_x",
    "object_y",
    "object_z",
    "object_qw",
    "object_qx",
    "object_qy",
    "object_qz",
]
"""Names of ``observation.environment_state``."""


def features() -> dict[str, dict[str, Any]]:
    """The task's features other than the cameras', in the dataset's order."""
    return {
        "observation.state": vector(ARM_NAMES),
        "observation.ee_pose": vector(EE_POSE_NAMES),
        ENV_STATE_KEY: vector(ENV_STATE_NAMES),
        "action": vector(ARM_NAMES),
    }


def arrays_of(n_frames: int) -> dict[str, tuple[int, ...]]:
    """The arrays of an episode (other than the cameras') and their shapes."""
    n = n_frames
    return {
        "joint_pos": (n, 7),
        "gripper": (n, 1),
        "ee_pose": (n, 7),
        "action": (n, len(ARM_NAMES)),
        "env_state": (n, len(ENV_STATE_NAMES)),
    }


def columns(info: Any, arrays: Any, scene_json: bytes) -> dict[str, np.ndarray]:
    """The values of :func:`features` of one episode, (F, ...) each.

    Raises:
        StoreError: the episode has no ``env_state`` of the right shape (re-record it).
    """
    env = np.asarray(arrays["env_state"][:], np.float32) if "env_state" in arrays else None
    if env is None or env.shape != (info.n_frames, len(ENV_STATE_NAMES)):
        raise StoreError(
            f"episode {info.episode_id!r}: env_state has shape "
            f"{None if env is None else env.shape}, expected ({info.n_frames}, "
            f"{len(ENV_STATE_NAMES)}) (re-record the episode with stage=demos)"
        )
    return {
        "observation.state": arm_state(arrays),
        "observation.ee_pose": np.asarray(arrays["ee_pose"][:], np.float32),
        ENV_STATE_KEY: env,
        "action": np.asarray(arrays["action"][:], np.float32),
    }


def card(meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]) -> tuple[str, list[str]]:
    """The task's part of the dataset card: the opening paragraph and the feature lines."""
    intro = (
        "Franka Panda demonstrations of putting an object away in a drawer (open the drawer by "
        "its handle, pick the object, place it on the drawer's floor, close the drawer) "
        "planned and recorded in physically validated MuJoCo scenes by factory "
        f"{meta['factory_version'] or '(unknown version)'}."
    )
    return intro, [
        "- **`observation.state`:** 7 arm joint positions (rad) and the gripper opening (m)",
        "- **`observation.ee_pose`:** tool position (m) and quaternion (w, x, y, z), world frame",
        "- **`observation.environment_state`:** the part's joint position (m or rad, 0 closed), "
        "its share of the joint's range, the object's position (m) and quaternion (w, x, y, z), "
        "world frame",
        "- **`action`:** the arm joint targets at the end of the frame (rad) and the gripper "
        "command (m; 0.08 open, negative squeezes)",
        f"- **`observation.images.<camera>`** for {', '.join(f'`{c}`' for c in cameras)}: RGB "
        f"video ({rgb.get('codec', 'h264')}, {rgb.get('pix_fmt', 'yuv420p')})",
        "- **`observation.depth.<camera>`:** depth in millimetres, packed into a lossless RGB "
        f"video: {meta['depth_encoding']}. `factory.dataset.unpack_depth_mm` reads it back "
        "exactly.",
        "- **`extras/<episode_id>/`:** `scene.json`, `model.xml`, `robot.json` and "
        "`states.npz` (full MuJoCo states per frame, for exact replay)",
    ]
