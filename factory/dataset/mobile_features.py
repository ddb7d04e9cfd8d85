"""LeRobot features of mobile pick-and-place episodes (``task=mobile_pick_place``).

A mobile episode (:mod:`factory.demos.mobile_items`) has the fixed task's arrays but an
``action`` of 11 columns, no ``env_state``, and in addition ``base_pose`` (F, 3),
``subtask`` (F,) int8 and ``subtask_done`` (F,) bool; its cameras are the pinhole ones then
``fisheye_front``/``fisheye_back`` (square images of the pinhole width). Exported features:

* ``observation.state`` (11,) float32, in this order: 7 arm joints (rad), the gripper opening
  (m), the base's x, y (m, world frame) and yaw (rad, unwrapped): :data:`MOBILE_STATE_NAMES`;
* ``observation.ee_pose`` (7,) float32: tool position (m) and quaternion wxyz, world frame;
* ``action`` (11,) float32: the arm joint targets (rad), the gripper command (m) and the base
  target x, y (m) and yaw (rad): :data:`MOBILE_ACTION_NAMES`;
* ``subtask_index`` (1,) int64: the frame's sub-task, an index into :data:`MOBILE_SUBTASKS`
  (the names are in ``meta/factory.json`` under ``subtasks`` and on the dataset card);
* ``subtask_done`` (1,) bool: true on the last frame of each sub-task;
* ``observation.images.<camera>``/``observation.depth.<camera>`` for all five cameras, encoded
  as the fixed task's (RGB video; depth as packed millimetres in a lossless RGB video).

There is no ``observation.environment_state``. Per episode, ``meta/factory.json`` holds the
navigation ``route`` the episode drove (``EpisodeInfo.route``, :func:`route_entry`): the
route check's base poses it drove to (``pick_pose``, ``place_pose``: x, y m, yaw rad, world
frame), their indices in the check's pose lists (best first) and the check's summary (pose
counts, grid cell, lattice headings, footprint radius, carry front); :func:`episode_routes`
reads them back by dataset episode index.

:func:`layout_of` tells the two layouts apart and :func:`one_layout` refuses mixing them in
one dataset.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import MixedLayoutError, StoreError

log = logging.getLogger(__name__)

MOBILE_TASK = "mobile_pick_place"
"""``EpisodeInfo.task`` of mobile episodes."""
FIXED = "fixed"
MOBILE = "mobile"
MOBILE_SUBTASKS: tuple[str, ...] = ("navigate_to_pick", "pick", "navigate_to_place", "place")
"""Sub-task names by ``subtask_index`` (``factory.tasks.mobile_pick_place.SUBTASKS``, copied so
that exporting needs no robot or planner imports; a test keeps the two equal)."""
ARM_NAMES = [f"joint{i}" for i in range(1, 8)] + ["gripper"]
MOBILE_STATE_NAMES = [*ARM_NAMES, "base_x", "base_y", "base_yaw"]
"""Columns of ``observation.state`` of mobile episodes."""
MOBILE_ACTION_NAMES = [*ARM_NAMES, "base_x", "base_y", "base_yaw"]
"""Columns of ``action`` of mobile episodes (targets: rad, m, m, m, rad)."""
MOBILE_ROBOT_TYPE = "franka_panda_omron"
"""lerobot's ``robot_type`` of mobile datasets (the fixed ones keep ``franka_panda``)."""
SUBTASK_KEY = "subtask_index"
DONE_KEY = "subtask_done"
ROUTE_KEY = "route"
"""Key of a mobile episode's route in its ``meta/factory.json`` entry."""
ROUTE_POSES = ("pick_pose", "place_pose")
"""The route's base poses (x, y m, yaw rad, world frame)."""


@dataclass(frozen=True)
class EpisodeLayout:
    """The layout of one episode.

    Attributes:
        episode_id: the episode.
        task: its ``EpisodeInfo.task``.
        layout: :data:`FIXED` or :data:`MOBILE`.
    """

    episode_id: str
    task: str
    layout: str


def layout_of(info: Any, group: Any) -> EpisodeLayout:
    """The layout of an episode: mobile when its task is ``mobile_pick_place`` or it has a
    ``base_pose`` array, else fixed-base.

    Args:
        info: its ``EpisodeInfo``.
        group: its zarr arrays.
    """
    mobile = info.task == MOBILE_TASK or "base_pose" in group
    return EpisodeLayout(info.episode_id, info.task, MOBILE if mobile else FIXED)


def one_layout(layouts: Iterable[EpisodeLayout]) -> str:
    """The single layout of a dataset's episodes.

    Raises:
        MixedLayoutError: fixed-base and mobile episodes are mixed (names one of each and the
            fix).
    """
    first: dict[str, EpisodeLayout] = {}
    for lay in layouts:
        first.setdefault(lay.layout, lay)
    if len(first) > 1:
        fixed, mobile = first[FIXED], first[MOBILE]
        raise MixedLayoutError(
            f"episode {fixed.episode_id!r} (task {fixed.task!r}, fixed base) and episode "
            f"{mobile.episode_id!r} (task {mobile.task!r}, mobile base) cannot share one "
            "dataset: their features differ. Record each task in its own run_dir (stage=demos "
            "task=... run_dir=...) and export each with stage=dataset"
        )
    return next(iter(first), FIXED)


def meta_layout(meta: dict[str, Any]) -> str:
    """The layout recorded in a dataset's ``meta/factory.json`` (fixed when absent)."""
    return str(meta.get("layout", FIXED))


def one_meta_layout(metas: list[dict[str, Any]], names: list[str]) -> str:
    """The single layout of datasets to merge (``names``: their folders, for the message).

    Raises:
        MixedLayoutError: fixed-base and mobile datasets are mixed.
    """
    kinds = {meta_layout(m): n for m, n in zip(metas, names, strict=True)}
    if len(kinds) > 1:
        raise MixedLayoutError(
            f"{kinds[FIXED]} holds fixed-base episodes and {kinds[MOBILE]} mobile ones: they "
            "cannot be merged into one dataset. Record each task in its own run_dir and export "
            "each with stage=dataset"
        )
    return next(iter(kinds), FIXED)


def mobile_meta(subtasks: list[str] | None = None) -> dict[str, Any]:
    """The keys mobile exports add to ``meta/factory.json``."""
    return {
        "layout": MOBILE,
        "subtasks": list(subtasks or MOBILE_SUBTASKS),
        "state_names": MOBILE_STATE_NAMES,
        "action_names": MOBILE_ACTION_NAMES,
    }


def mobile_meta_of(meta: dict[str, Any]) -> dict[str, Any]:
    """The mobile keys of a shard's ``meta/factory.json``, to carry into a merge ({} when
    fixed)."""
    if meta_layout(meta) != MOBILE:
        return {}
    return mobile_meta(meta.get("subtasks"))


def route_entry(info: Any) -> dict[str, Any]:
    """A mobile episode's ``route`` for ``meta/factory.json``: a JSON-ready copy of
    ``EpisodeInfo.route`` (:meth:`factory.tasks.mobile_pick_place.plan.MobilePlanner.route_record`).

    Raises:
        StoreError: a route without its base poses (re-record the episode).
    """
    route = json.loads(json.dumps(dict(info.route)))
    for key in ROUTE_POSES:
        pose = route.get(key)
        if not isinstance(pose, list) or len(pose) != 3:
            raise StoreError(
                f"episode {info.episode_id!r}: its route has no {key} (x, y, yaw): {pose!r} "
                "(re-record the episode with stage=demos task=mobile_pick_place)"
            )
    return dict(route)


def episode_routes(root: str | Path) -> dict[int, dict[str, Any]]:
    """The navigation route of every episode of a mobile dataset, by dataset episode index
    (the ``episode_index`` of ``LeRobotDataset``'s frames and of ``meta/episodes``).

    Args:
        root: the dataset folder (``LeRobotDataset.root``).

    Raises:
        StoreError: not a factory dataset, not a mobile one, or exported before routes were
            (names the fix).
    """
    path = Path(root) / "meta" / "factory.json"
    if not path.is_file():
        raise StoreError(f"{root} has no meta/factory.json: export it with stage=dataset")
    meta = json.loads(path.read_text())
    if meta_layout(meta) != MOBILE:
        raise StoreError(
            f"{root} holds fixed-base episodes, which have no route: routes are recorded by "
            "stage=demos task=mobile_pick_place"
        )
    out: dict[int, dict[str, Any]] = {}
    for ep in meta["episodes"]:
        if ROUTE_KEY not in ep:
            raise StoreError(
                f"{root}: episode {ep.get('episode_id')!r} has no route in meta/factory.json "
                "(exported before routes were): re-export with stage=dataset force=true"
            )
        out[int(ep["episode_index"])] = dict(ep[ROUTE_KEY])
    return out


def _camera_hw(info: Any, group: Any, cam: str) -> tuple[int, int]:
    shape = group[f"rgb/{cam}"].shape if f"rgb/{cam}" in group else None
    if shape is None or len(shape) != 4:
        raise StoreError(
            f"episode {info.episode_id!r}: array 'rgb/{cam}' has shape {shape}, expected "
            f"({info.n_frames}, H, W, 3) (re-record the episode)"
        )
    return int(shape[1]), int(shape[2])


def mobile_features(info: Any, group: Any, base: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The LeRobot feature spec of mobile episodes shaped like ``info``.

    Args:
        info: the first episode's ``EpisodeInfo``.
        group: its zarr arrays (camera sizes: the fisheye images are square).
        base: the fixed-base spec of ``info`` (``features_for``), whose camera features are
            kept, resized per camera.
    """
    feats: dict[str, dict[str, Any]] = {
        "observation.state": {
            "dtype": "float32",
            "shape": (len(MOBILE_STATE_NAMES),),
            "names": list(MOBILE_STATE_NAMES),
        },
        "observation.ee_pose": dict(base["observation.ee_pose"]),
        "action": {
            "dtype": "float32",
            "shape": (len(MOBILE_ACTION_NAMES),),
            "names": list(MOBILE_ACTION_NAMES),
        },
        SUBTASK_KEY: {"dtype": "int64", "shape": (1,), "names": None},
        DONE_KEY: {"dtype": "bool", "shape": (1,), "names": None},
    }
    for key, ft in base.items():
        if ft["dtype"] != "video":
            continue
        h, w = _camera_hw(info, group, key.rsplit(".", 1)[1])
        ft = {**ft, "shape": (h, w, 3)}
        if "info" in ft:
            ft["info"] = {**ft["info"], "video.height": h, "video.width": w}
        feats[key] = ft
    return feats


def check_mobile_shapes(info: Any, group: Any, features: dict[str, dict[str, Any]]) -> None:
    """Raises :class:`StoreError` naming an array of a mobile episode with a wrong shape."""
    n = info.n_frames
    expect: dict[str, tuple[int, ...]] = {
        "joint_pos": (n, 7),
        "gripper": (n, 1),
        "ee_pose": (n, 7),
        "action": (n, len(MOBILE_ACTION_NAMES)),
        "base_pose": (n, 3),
        "subtask": (n,),
        "subtask_done": (n,),
    }
    for cam in info.cameras:
        h, w, _ = features[f"observation.images.{cam}"]["shape"]
        expect[f"rgb/{cam}"] = (n, h, w, 3)
        expect[f"depth/{cam}"] = (n, h, w)
    for name, shape in expect.items():
        got = tuple(group[name].shape) if name in group else None
        if got != shape:
            raise StoreError(
                f"episode {info.episode_id!r}: array {name!r} has shape {got}, expected {shape} "
                "(re-record the episode)"
            )


def mobile_columns(info: Any, group: Any) -> dict[str, np.ndarray]:
    """The non-video features of a mobile episode, (F, ...) each, keyed by feature.

    Raises:
        StoreError: a sub-task label outside :data:`MOBILE_SUBTASKS`.
    """
    subtask = np.asarray(group["subtask"][:], np.int64)
    if subtask.size and (subtask.min() < 0 or subtask.max() >= len(MOBILE_SUBTASKS)):
        raise StoreError(
            f"episode {info.episode_id!r}: sub-task labels {sorted(set(subtask.tolist()))} are "
            f"not indices into {list(MOBILE_SUBTASKS)} (re-record the episode)"
        )
    state = np.concatenate(
        [
            np.asarray(group["joint_pos"][:], np.float32),
            np.asarray(group["gripper"][:], np.float32),
            np.asarray(group["base_pose"][:], np.float32),
        ],
        axis=1,
    )
    return {
        "observation.state": state,
        "observation.ee_pose": np.asarray(group["ee_pose"][:], np.float32),
        "action": np.asarray(group["action"][:], np.float32),
        SUBTASK_KEY: subtask[:, None],
        DONE_KEY: np.asarray(group["subtask_done"][:], bool)[:, None],
    }


def scalar_buffer(buffer: dict[str, Any]) -> None:
    """Makes the buffered ``subtask_index``/``subtask_done`` values of an episode scalars.

    ``add_frame`` wants a (1,) array for a (1,) feature, but ``save_episode`` stacks them into
    (F, 1), which the ``datasets`` scalar column cannot take (numpy 2 refuses ``int()`` of a
    1-d array); lerobot's own scalar features (``frame_index``, ``timestamp``) are buffered as
    scalars, so these are made the same before ``save_episode``.

    Args:
        buffer: the dataset's ``episode_buffer`` (changed in place).
    """
    for key in (SUBTASK_KEY, DONE_KEY):
        buffer[key] = [np.asarray(v).reshape(()) for v in buffer[key]]


def mobile_card_lines(meta: dict[str, Any], cams: list[str], rgb: dict[str, Any]) -> list[str]:
    """The feature lines of the dataset card of a mobile dataset (markdown list items).

    Args:
        meta: its ``meta/factory.json``.
        cams: its camera names.
        rgb: the RGB codec settings (``codec``, ``pix_fmt``).
    """
    subtasks = meta.get("subtasks", list(MOBILE_SUBTASKS))
    state_names = ", ".join(f"`{n}`" for n in meta.get("state_names", MOBILE_STATE_NAMES))
    action_names = ", ".join(f"`{n}`" for n in meta.get("action_names", MOBILE_ACTION_NAMES))
    labels = ", ".join(f"{k} = `{name}`" for k, name in enumerate(subtasks))
    return [
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
        f"- **`observation.images.<camera>`** for {', '.join(f'`{c}`' for c in cams)}: RGB "
        f"video ({rgb.get('codec', 'h264')}, {rgb.get('pix_fmt', 'yuv420p')}); the fisheye "
        "cameras are square",
        "- **`observation.depth.<camera>`:** depth in millimetres (pinhole cameras: along the "
        "optical axis; fisheye cameras: along the ray), packed into a lossless RGB video: "
        f"{meta['depth_encoding']}. `factory.dataset.unpack_depth_mm` reads it back exactly.",
        "- No `observation.environment_state` (object poses are in `extras/.../states.npz`)",
        f"- **`{ROUTE_KEY}`** (per episode, in `meta/factory.json` under `episodes[i].route`; "
        "`factory.dataset.episode_routes` reads them by episode index): the navigation route "
        "check's base poses the episode drove to, `pick_pose` and `place_pose` (x, y in m, "
        "yaw in rad, world frame), their indices `pick_index`/`place_index` in the check's "
        "pose lists (best first), and the check's summary: `pick_poses`/`place_poses` (free "
        "base poses within reach), `route_pick_poses`/`route_place_poses` (those connected "
        "by a route), `resolution` (occupancy grid cell, m), `headings` (yaw lattice), "
        "`footprint_radius` and `carry_front` (m), `reason` (empty: a route exists). The "
        "spawn pose is the first frame's base pose in `observation.state`",
    ]
