"""What the evaluation env observes and how fast it steps: :class:`ObsSpec`, from a LeRobot
dataset's features (:func:`obs_spec_of_dataset`) or from the demos' settings
(:func:`obs_spec_of_demos`).

The observations are keyed like the dataset's features: the task's low-dimensional ones
(:meth:`~factory.tasks.base.Task.env_observations`: ``observation.state``,
``observation.ee_pose``, the mobile task's ``subtask_index``), ``observation.
environment_state`` where the task has one (:meth:`~factory.tasks.base.Task.env_state_dim`)
and it is asked for, ``observation.camera_poses`` where the dataset has it (the calibration of
the task's cameras fixed in the scene, :meth:`~factory.tasks.base.Task.calibrated_cameras`: 13
float32 values per camera, :mod:`factory.demos.record.calibration`; a constant of the scene),
then per camera ``observation.images.<cam>`` (uint8 RGB) and ``observation.depth.<cam>`` (uint16
millimetres); the task's fisheye cameras (:meth:`~factory.tasks.base.Task.fisheye_cameras`)
draw ``width`` square images.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from factory.demos.record.calibration import (
    CALIBRATION_SIZE,
    CAMERA_POSES_KEY,
    cameras_of_names,
)
from factory.errors import StoreError
from factory.tasks import DEFAULT_TASK, get_task

ENV_STATE_KEY = "observation.environment_state"


@dataclass(frozen=True)
class ObsSpec:
    """What the env of a task observes and how fast it steps.

    Attributes:
        fps: frames (actions) per second (Hz); the dataset's fps.
        cameras: cameras rendered as ``observation.images.<cam>``, from the task's
            (:meth:`~factory.tasks.base.Task.env_cameras`); empty for no images.
        width, height: image size (px); the fisheye cameras' images are ``width`` square.
        depth: also ``observation.depth.<cam>`` (uint16 mm; fisheye: ray length).
        env_state: also ``observation.environment_state`` (tasks that have one).
        task: the task (a registered name).
        pose_cameras: the cameras whose calibration ``observation.camera_poses`` holds, in
            its order (the dataset's); empty: not observed.
    """

    fps: float = 20.0
    cameras: tuple[str, ...] = ("left", "right", "wrist")
    width: int = 128
    height: int = 128
    depth: bool = True
    env_state: bool = False
    task: str = DEFAULT_TASK
    pose_cameras: tuple[str, ...] = ()

    def image_shape(self, camera: str) -> tuple[int, int]:
        """(H, W) of a camera's images (px)."""
        if camera in get_task(self.task).fisheye_cameras():
            return (self.width, self.width)
        return (self.height, self.width)

    def keys(self) -> list[str]:
        """Observation keys, as the dataset's feature names."""
        return list(self.shapes())

    def shapes(self) -> dict[str, tuple[tuple[int, ...], str]]:
        """Key -> (shape, dtype) of one env's observation."""
        task = get_task(self.task)
        out = dict(task.env_observations())
        if self.env_state and task.env_state_dim():
            out[ENV_STATE_KEY] = ((task.env_state_dim(),), "float32")
        if self.pose_cameras:
            out[CAMERA_POSES_KEY] = ((CALIBRATION_SIZE * len(self.pose_cameras),), "float32")
        for c in self.cameras:
            out[f"observation.images.{c}"] = ((*self.image_shape(c), 3), "uint8")
        if self.depth:
            for c in self.cameras:
                out[f"observation.depth.{c}"] = (self.image_shape(c), "uint16")
        return out


def dataset_features(root: str | Path) -> dict[str, Any]:
    """``features`` and ``fps`` of a LeRobot dataset (``meta/info.json``), without lerobot.

    Raises:
        StoreError: the folder holds no LeRobot dataset.
    """
    path = Path(root) / "meta" / "info.json"
    if not path.is_file():
        raise StoreError(f"{root} is not a LeRobot dataset (no meta/info.json): run stage=dataset")
    info = json.loads(path.read_text())
    return {"fps": info["fps"], "features": info["features"]}


def dataset_task(root: str | Path) -> str:
    """The task whose features a dataset holds: the layout in its ``meta/factory.json`` (the
    default task's without one)."""
    from factory.dataset.layout import meta_task

    path = Path(root) / "meta" / "factory.json"
    meta = json.loads(path.read_text()) if path.is_file() else {}
    return meta_task(meta).name


def obs_spec_of_dataset(
    root: str | Path, env_state: bool | None = None, task: str | None = None
) -> ObsSpec:
    """The observation spec matching a dataset's features (fps, cameras, image size, depth).

    Args:
        root: the dataset folder (``dataset/merged``).
        env_state: observe ``observation.environment_state``; None: when the dataset has it.
        task: the task (default: the dataset's, :func:`dataset_task`).
    """
    name = task or dataset_task(root)
    t = get_task(name)
    meta = dataset_features(root)
    feats = meta["features"]
    cams = tuple(c for c in t.env_cameras() if f"observation.images.{c}" in feats)
    h = w = 128
    pinhole = [c for c in cams if c not in t.fisheye_cameras()]
    fisheye = [c for c in cams if c in t.fisheye_cameras()]
    if pinhole:
        h, w = (int(x) for x in feats[f"observation.images.{pinhole[0]}"]["shape"][:2])
    elif fisheye:
        w = h = int(feats[f"observation.images.{fisheye[0]}"]["shape"][1])
    has_env = ENV_STATE_KEY in feats
    calib = feats.get(CAMERA_POSES_KEY)
    return ObsSpec(
        fps=float(meta["fps"]),
        cameras=cams,
        width=w,
        height=h,
        depth=any(f"observation.depth.{c}" in feats for c in cams),
        env_state=has_env if env_state is None else env_state,
        task=name,
        pose_cameras=cameras_of_names(calib["names"]) if calib else (),
    )


def obs_spec_of_demos(dc: Any, env_state: bool = False, task: str = DEFAULT_TASK) -> ObsSpec:
    """The observation spec of what ``stage=demos task=<task>`` records with the demos
    settings ``dc``: ``demos.cameras`` and the task's fisheye cameras, and the calibration of
    its cameras fixed in the scene."""
    t = get_task(task)
    cams = (*dc.cameras, *t.fisheye_cameras()) if dc.render else ()
    return ObsSpec(
        fps=dc.fps,
        cameras=tuple(cams),
        width=dc.width,
        height=dc.height,
        depth=bool(dc.render),
        env_state=env_state,
        task=task,
        pose_cameras=t.calibrated_cameras(cams),
    )
