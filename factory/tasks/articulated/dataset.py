"""What the articulated tasks (``task=open``, ``task=close``) write into their LeRobot
datasets.

Features of every frame (the export adds the cameras' videos and the instruction, which names
the part: "open the drawer of the base cabinet"):

* ``observation.state`` (8,) float32: arm joints (rad) and the gripper opening (m);
* ``observation.ee_pose`` (7,) float32: tool position (m) and quaternion wxyz, world frame;
* ``observation.environment_state`` (11,) float32: the manipulated part's joint position
  (rad for a hinge, m for a slide; 0 closed) and its share of the joint's range (0 closed, 1
  at the limit); then, in the robot's base frame, the handle's centre (m), its outward normal
  (unit) and the handle's centre minus the tool site (m)
  (:func:`factory.tasks.articulated.execute.env_state`);
* ``action`` (8,) float32: desired arm joints (rad) and the gripper command (m).

The two tasks share the features; each has its own layout (``meta/factory.json``'s
``layout``: :attr:`~factory.tasks.articulated.task.ArticulatedTask.layout`), so that an
``open`` and a ``close`` dataset are not merged by mistake.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.errors import StoreError
from factory.tasks.pick_place.dataset import ARM_NAMES, EE_POSE_NAMES, arm_state, vector

ROBOT_TYPE = "franka_panda"
"""lerobot's ``robot_type`` of the tasks' datasets."""
ENV_STATE_KEY = "observation.environment_state"
ENV_STATE_NAMES = [
    "joint",
    "joint_fraction",
    *(f"handle_{a}" for a in "xyz"),
    *(f"handle_normal_{a}" for a in "xyz"),
    *(f"tool_to_handle_{a}" for a in "xyz"),
]
"""Names of ``observation.environment_state``: the part's joint position (rad or m) and its
share of the range; the handle's centre, outward normal and offset from the tool in the
robot's base frame."""


def features(env_names: list[str] = ENV_STATE_NAMES) -> dict[str, dict[str, Any]]:
    """The tasks' features other than the cameras', in the dataset's order (``env_names``:
    the columns of ``observation.environment_state``; ``task=place_inside`` gives its own)."""
    return {
        "observation.state": vector(ARM_NAMES),
        "observation.ee_pose": vector(EE_POSE_NAMES),
        ENV_STATE_KEY: vector(env_names),
        "action": vector(ARM_NAMES),
    }


def arrays_of(n_frames: int, env_names: list[str] = ENV_STATE_NAMES) -> dict[str, tuple[int, ...]]:
    """The arrays of an episode (other than the cameras') and their shapes."""
    n = n_frames
    return {
        "joint_pos": (n, 7),
        "gripper": (n, 1),
        "ee_pose": (n, 7),
        "action": (n, len(ARM_NAMES)),
        "env_state": (n, len(env_names)),
    }


def columns(
    info: Any, arrays: Any, scene_json: bytes, env_names: list[str] = ENV_STATE_NAMES
) -> dict[str, np.ndarray]:
    """The values of :func:`features` of one episode, (F, ...) each.

    Raises:
        StoreError: the episode has no ``env_state`` of the right shape (re-record it).
    """
    env = np.asarray(arrays["env_state"][:], np.float32) if "env_state" in arrays else None
    if env is None or env.shape != (info.n_frames, len(env_names)):
        raise StoreError(
            f"episode {info.episode_id!r}: env_state has shape "
            f"{None if env is None else env.shape}, expected ({info.n_frames}, "
            f"{len(env_names)}) (re-record the episode with stage=demos)"
        )
    return {
        "observation.state": arm_state(arrays),
        "observation.ee_pose": np.asarray(arrays["ee_pose"][:], np.float32),
        ENV_STATE_KEY: env,
        "action": np.asarray(arrays["action"][:], np.float32),
    }


CARD_WHAT = (
    "opening or closing a drawer or door (a handle grasped and pulled or pushed along the joint)"
)
"""What the tasks' demonstrations show (the dataset card's opening sentence)."""
CARD_ENV_STATE = (
    "the manipulated part's joint position (rad or m, 0 closed) and its share of the joint's "
    "range; the handle's centre (m), outward normal and offset from the tool (m), in the "
    "robot's base frame"
)
"""The dataset card's line on ``observation.environment_state``."""


def card(
    meta: dict[str, Any],
    cameras: list[str],
    rgb: dict[str, Any],
    what: str = CARD_WHAT,
    env_state: str = CARD_ENV_STATE,
) -> tuple[str, list[str]]:
    """The tasks' part of the dataset card: the opening paragraph and the feature lines
    (``what`` the demonstrations show and the ``env_state`` line: ``task=place_inside``
    gives its own)."""
    intro = (
        f"Franka Panda demonstrations of {what} planned and recorded in physically validated "
        f"MuJoCo scenes by factory {meta['factory_version'] or '(unknown version)'}."
    )
    return intro, [
        "- **`observation.state`:** 7 arm joint positions (rad) and the gripper opening (m)",
        "- **`observation.ee_pose`:** tool position (m) and quaternion (w, x, y, z), world frame",
        f"- **`observation.environment_state`:** {env_state}",
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
