"""What the mobile pick-and-place task writes into its LeRobot datasets.

A mobile episode (:mod:`factory.tasks.mobile_pick_place.demos`) has the fixed task's arrays but an
``action`` of 11 columns (``env_state``: the place support is the target), and in addition
``base_pose`` (F, 3), ``subtask`` (F,) int8 and ``subtask_done`` (F,) bool; its cameras are the
pinhole ones then ``fisheye_front``/``fisheye_back`` (square images of the pinhole width,
exported at their own size). Features of every frame (the export adds the cameras' videos and
the instruction):

* ``observation.state`` (11,) float32, in this order: 7 arm joints (rad), the gripper opening
  (m), the base's x, y (m, world frame) and yaw (rad, unwrapped): :data:`STATE_NAMES`;
* ``observation.ee_pose`` (7,) float32: tool position (m) and quaternion wxyz, world frame;
* ``observation.environment_state`` (14,) float32: the fixed task's (same names and meaning):
  the pick object's position (m) and quaternion wxyz, then the place support's, world frame
  (body frames): the recorded ``env_state``, or for episodes recorded before it the free
  bodies' poses in the MuJoCo states
  (:func:`factory.tasks.pick_place.dataset.environment_state`). The policies read them in the
  frame of the arm's base, which rides on the mobile base
  (:func:`factory.policy.inputs.env_features`); datasets exported before it lack the feature
  and still load (``stage=dataset force=true`` adds it);
* ``action`` (11,) float32: the arm joint targets (rad), the gripper command (m) and the base
  target x, y (m) and yaw (rad): :data:`ACTION_NAMES`;
* ``subtask_index`` (1,) int64: the frame's sub-task, an index into
  :data:`~factory.tasks.mobile_pick_place.scene.SUBTASKS` (the names are in
  ``meta/factory.json`` under ``subtasks`` and on the dataset card);
* ``subtask_done`` (1,) bool: true on the last frame of each sub-task.

Per episode, ``meta/factory.json`` holds the navigation ``route`` the episode drove
(``EpisodeInfo.route``: :mod:`factory.dataset.routes`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.errors import StoreError
from factory.tasks.mobile_pick_place.scene import SUBTASKS
from factory.tasks.pick_place import dataset as fixed

LAYOUT = "mobile"
"""``layout`` of the task's datasets in ``meta/factory.json``."""
ROBOT_TYPE = "franka_panda_omron"
"""lerobot's ``robot_type`` of the task's datasets (the fixed ones keep ``franka_panda``)."""
TAGS = ("mobile-manipulation",)
"""Tags the task's dataset cards add."""
BASE_NAMES = ["base_x", "base_y", "base_yaw"]
STATE_NAMES = [*fixed.ARM_NAMES, *BASE_NAMES]
"""Columns of ``observation.state``."""
ACTION_NAMES = [*fixed.ARM_NAMES, *BASE_NAMES]
"""Columns of ``action`` (targets: rad, m, m, m, rad)."""
SUBTASK_KEY = "subtask_index"
DONE_KEY = "subtask_done"


def features() -> dict[str, dict[str, Any]]:
    """The task's features other than the cameras', in the dataset's order."""
    return {
        "observation.state": fixed.vector(STATE_NAMES),
        "observation.ee_pose": fixed.vector(fixed.EE_POSE_NAMES),
        fixed.ENV_STATE_KEY: fixed.vector(fixed.ENV_STATE_NAMES),
        "action": fixed.vector(ACTION_NAMES),
        SUBTASK_KEY: {"dtype": "int64", "shape": (1,), "names": None},
        DONE_KEY: {"dtype": "bool", "shape": (1,), "names": None},
    }


def arrays_of(n_frames: int) -> dict[str, tuple[int, ...]]:
    """The arrays of an episode (other than the cameras') and their shapes: the fixed task's
    with 11 action columns, the base pose and the sub-task labels."""
    n = n_frames
    return {
        **fixed.arrays_of(n, len(ACTION_NAMES)),
        "base_pose": (n, 3),
        "subtask": (n,),
        "subtask_done": (n,),
    }


def meta() -> dict[str, Any]:
    """The keys the task adds to ``meta/factory.json``."""
    return {
        "layout": LAYOUT,
        "subtasks": list(SUBTASKS),
        "state_names": STATE_NAMES,
        "action_names": ACTION_NAMES,
    }


def columns(info: Any, arrays: Any, scene_json: bytes) -> dict[str, np.ndarray]:
    """The values of :func:`features` of one episode, (F, ...) each.

    Args:
        info: its ``EpisodeInfo`` (``pick_id``, ``target_id``: the place support, ``cleared``).
        arrays: its stored arrays (zarr group).
        scene_json: its scene's ``scene.json`` (where the objects' poses sit in the states).

    Raises:
        StoreError: a sub-task label outside :data:`SUBTASKS`, or states that do not hold the
            objects' poses.
    """
    subtask = np.asarray(arrays["subtask"][:], np.int64)
    if subtask.size and (subtask.min() < 0 or subtask.max() >= len(SUBTASKS)):
        raise StoreError(
            f"episode {info.episode_id!r}: sub-task labels {sorted(set(subtask.tolist()))} are "
            f"not indices into {list(SUBTASKS)} (re-record the episode)"
        )
    state = np.concatenate(
        [fixed.arm_state(arrays), np.asarray(arrays["base_pose"][:], np.float32)], 1
    )
    return {
        "observation.state": state,
        "observation.ee_pose": np.asarray(arrays["ee_pose"][:], np.float32),
        fixed.ENV_STATE_KEY: fixed.environment_state(info, arrays, scene_json),
        "action": np.asarray(arrays["action"][:], np.float32),
        SUBTASK_KEY: subtask[:, None],
        DONE_KEY: np.asarray(arrays["subtask_done"][:], bool)[:, None],
    }


def card(meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]) -> tuple[str, list[str]]:
    """The task's part of its dataset card: the opening paragraph and the feature lines.

    Args:
        meta: the dataset's ``meta/factory.json``.
        cameras: its camera names.
        rgb: the RGB codec settings (``codec``, ``pix_fmt``).
    """
    intro = (
        "Mobile manipulation demonstrations (a Franka Panda on an Omron mobile base) "
        "planned and recorded in physically validated MuJoCo scenes by factory "
        f"{meta['factory_version'] or '(unknown version)'}. Each episode runs the "
        "sub-tasks " + ", ".join(f"`{t}`" for t in meta.get("subtasks", [])) + " in order."
    )
    subtasks = meta.get("subtasks", list(SUBTASKS))
    state_names = ", ".join(f"`{n}`" for n in meta.get("state_names", STATE_NAMES))
    action_names = ", ".join(f"`{n}`" for n in meta.get("action_names", ACTION_NAMES))
    labels = ", ".join(f"{k} = `{name}`" for k, name in enumerate(subtasks))
    return intro, [
        "- **Robot:** a Franka Panda on an Omron mobile base (holonomic base joints x, y, yaw)",
        "- **`observation.state`:** 7 arm joint positions (rad), the gripper opening (m), then "
        f"the base pose: x, y (m, world frame) and yaw (rad, unwrapped); names {state_names}",
        "- **`observation.ee_pose`:** tool position (m) and quaternion (w, x, y, z), world frame",
        "- **`action`:** the arm joint targets at the end of the frame (rad), the gripper "
        "command (m; 0.08 open, negative squeezes), then the base target x, y (m) and yaw "
        f"(rad); names {action_names}",
        f"- **`{SUBTASK_KEY}`:** the frame's sub-task (int): {labels}; the sub-tasks run in "
        "this order (names also in `meta/factory.json` under `subtasks`)",
        f"- **`{DONE_KEY}`:** true on the last frame of each sub-task (one per sub-task)",
        f"- **`observation.images.<camera>`** for {', '.join(f'`{c}`' for c in cameras)}: RGB "
        f"video ({rgb.get('codec', 'h264')}, {rgb.get('pix_fmt', 'yuv420p')}); the fisheye "
        "cameras are square",
        "- **`observation.depth.<camera>`:** depth in millimetres (pinhole cameras: along the "
        "optical axis; fisheye cameras: along the ray), packed into a lossless RGB video: "
        f"{meta['depth_encoding']}. `factory.dataset.unpack_depth_mm` reads it back exactly.",
        "- **`observation.environment_state`:** the pick object's position (m) and "
        "quaternion (w, x, y, z), then the place support's, world frame (privileged state "
        "for low-dimensional policies and perception training; the fixed-base datasets' "
        "layout)",
        "- **`route`** (per episode, in `meta/factory.json` under `episodes[i].route`; "
        "`factory.dataset.episode_routes` reads them by episode index): the navigation route "
        "check's base poses the episode drove to, `pick_pose` and `place_pose` (x, y in m, "
        "yaw in rad, world frame), their indices `pick_index`/`place_index` in the check's "
        "pose lists (best first), and the check's summary: `pick_poses`/`place_poses` (free "
        "base poses within reach), `route_pick_poses`/`route_place_poses` (those connected "
        "by a route), `resolution` (occupancy grid cell, m), `headings` (yaw lattice), "
        "`footprint_radius` and `carry_front` (m), `reason` (empty: a route exists). The "
        "spawn pose is the first frame's base pose in `observation.state`",
        "- **`extras/<episode_id>/`:** `scene.json` (the scene), `model.xml` (the MuJoCo "
        "model of the scene; meshes in `extras/assets`), `robot.json` (the base's spawn "
        "pose) and `states.npz` (full MuJoCo states per frame, for exact replay)",
    ]
