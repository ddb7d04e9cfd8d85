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

from factory.tasks.articulated import dataset as articulated

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
    """The task's features other than the cameras', in the dataset's order (the articulated
    tasks', :func:`factory.tasks.articulated.dataset.features`, with this environment state)."""
    return articulated.features(ENV_STATE_NAMES)


def arrays_of(n_frames: int) -> dict[str, tuple[int, ...]]:
    """The arrays of an episode (other than the cameras') and their shapes."""
    return articulated.arrays_of(n_frames, ENV_STATE_NAMES)


def columns(info: Any, arrays: Any, scene_json: bytes) -> dict[str, np.ndarray]:
    """The values of :func:`features` of one episode, (F, ...) each.

    Raises:
        StoreError: the episode has no ``env_state`` of the right shape (re-record it).
    """
    return articulated.columns(info, arrays, scene_json, ENV_STATE_NAMES)


def card(meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]) -> tuple[str, list[str]]:
    """The task's part of the dataset card: the opening paragraph and the feature lines."""
    return articulated.card(
        meta,
        cameras,
        rgb,
        what="putting an object away in a drawer (open the drawer by its handle, pick the "
        "object, place it on the drawer's floor, close the drawer)",
        env_state="the part's joint position (m or rad, 0 closed), its share of the joint's "
        "range, the object's position (m) and quaternion (w, x, y, z), world frame",
    )
