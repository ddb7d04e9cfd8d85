"""The LeRobot features of a dataset: its task's, then a video of each camera.

The task declares its features (:meth:`~factory.tasks.base.Task.dataset_features`: the state,
tool pose and action, and what else it records) and reads their values from an episode's
arrays (:meth:`~factory.tasks.base.Task.episode_columns`); every task's episodes get, after
them:

* ``observation.camera_poses`` float32 (13 per camera), where every episode records the
  calibration of the same cameras (:attr:`~factory.schema.episode.EpisodeInfo.camera_poses`:
  the fixed-base task's left and right cameras, placed per scene): per camera, in the
  episodes' camera order, its position (3, m) and rotation rows (9) in the robot's base frame
  and its vertical field of view (deg), the same at every frame of an episode
  (:mod:`factory.demos.record.calibration`); absent otherwise (datasets of episodes recorded
  before it, the mobile task);

and for each of their cameras:

* ``observation.images.<camera>`` video (H, W, 3), h264, the camera's own size (the mobile
  robot's fisheye cameras are square);
* ``observation.depth.<camera>`` video (H, W, 3), lossless RGB h264 packing uint16 millimetres
  as (high byte, low byte, 0): :data:`DEPTH_ENCODING`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from factory.demos.record.calibration import CAMERA_POSES_KEY, calibration_names
from factory.errors import StoreError

if TYPE_CHECKING:
    from factory.tasks.base import Task

log = logging.getLogger(__name__)

DEPTH_ENCODING = "mm = 256 * R + G (uint8 channels of a lossless RGB video)"


def calibrated_cameras(infos: Sequence[Any]) -> tuple[str, ...]:
    """The cameras whose calibration ``observation.camera_poses`` holds for these episodes
    (their ``EpisodeInfo``), in the episodes' camera order: those every episode records the
    calibration of; none (the feature left out, with a warning) where the episodes differ.
    """
    if not infos:
        return ()
    first = infos[0]
    cams = tuple(c for c in first.cameras if c in first.camera_poses)
    for info in infos[1:]:
        have = tuple(c for c in info.cameras if c in info.camera_poses)
        if have != cams:
            log.warning(
                "episodes %r and %r record the calibration of different cameras (%s; %s): the "
                "dataset is written without %s (re-record the older episodes with stage=demos "
                "force=true to have it)",
                first.episode_id,
                info.episode_id,
                ", ".join(cams) or "none",
                ", ".join(have) or "none",
                CAMERA_POSES_KEY,
            )
            return ()
    return cams


def camera_size(info: Any, arrays: Any, camera: str) -> tuple[int, int]:
    """A camera's image (height, width) in an episode's arrays.

    Raises:
        StoreError: the episode has no images of that camera.
    """
    shape = arrays[f"rgb/{camera}"].shape if f"rgb/{camera}" in arrays else None
    if shape is None or len(shape) != 4:
        raise StoreError(
            f"episode {info.episode_id!r}: array 'rgb/{camera}' has shape {shape}, expected "
            f"({info.n_frames}, H, W, 3) (re-record the episode)"
        )
    return int(shape[1]), int(shape[2])


def features_for(
    task: Task, info: Any, arrays: Any, calibrated: Sequence[str] = ()
) -> dict[str, dict[str, Any]]:
    """The LeRobot feature spec of ``task``'s episodes shaped like one of them.

    Args:
        task: the episodes' task.
        info: the episode's ``EpisodeInfo`` (cameras, fps).
        arrays: its stored arrays (the cameras' image sizes).
        calibrated: the cameras of ``observation.camera_poses`` (:func:`calibrated_cameras`;
            none: no such feature).
    """
    feats = task.dataset_features()
    if calibrated:
        names = calibration_names(calibrated)
        feats[CAMERA_POSES_KEY] = {"dtype": "float32", "shape": (len(names),), "names": names}
    for cam in info.cameras:
        h, w = camera_size(info, arrays, cam)
        feats[f"observation.images.{cam}"] = {
            "dtype": "video",
            "shape": (h, w, 3),
            "names": ["height", "width", "channels"],
        }
        # Millimetres packed into a lossless RGB video (high byte, low byte, 0): exact, and
        # as cheap to write and to decode as the camera streams. unpack_depth_mm() reads it.
        # lerobot cannot describe a gbrp stream itself, so the video info is given here.
        feats[f"observation.depth.{cam}"] = {
            "dtype": "video",
            "shape": (h, w, 3),
            "names": ["height", "width", "channels"],
            "info": {
                "video.height": h,
                "video.width": w,
                "video.codec": "h264",
                "video.pix_fmt": "gbrp",
                "video.is_depth_map": True,
                "video.fps": round(info.fps),
                "video.channels": 3,
                "has_audio": False,
                "depth_encoding": DEPTH_ENCODING,
            },
        }
    return feats


def check_arrays(task: Task, info: Any, arrays: Any, features: dict[str, dict[str, Any]]) -> None:
    """Checks the shapes of an episode's arrays: the task's
    (:meth:`~factory.tasks.base.Task.episode_arrays`), then each camera's images and depth at
    the size of ``features``.

    Raises:
        StoreError: an array has a wrong shape or is missing (names it; re-record the episode).
    """
    n = info.n_frames
    expect = task.episode_arrays(n)
    for cam in info.cameras:
        h, w, _ = features[f"observation.images.{cam}"]["shape"]
        expect[f"rgb/{cam}"] = (n, h, w, 3)
        expect[f"depth/{cam}"] = (n, h, w)
    for name, shape in expect.items():
        got = tuple(arrays[name].shape) if name in arrays else None
        if got != shape:
            raise StoreError(
                f"episode {info.episode_id!r}: array {name!r} has shape {got}, expected {shape} "
                "(re-record the episode)"
            )


def scalar_buffer(buffer: dict[str, Any], features: dict[str, dict[str, Any]]) -> None:
    """Makes the buffered values of an episode's (1,) features scalars.

    ``add_frame`` wants a (1,) array for a (1,) feature, but ``save_episode`` stacks them into
    (F, 1), which the ``datasets`` scalar column cannot take (numpy 2 refuses ``int()`` of a
    1-d array); lerobot's own scalar features (``frame_index``, ``timestamp``) are buffered as
    scalars, so these are made the same before ``save_episode``.

    Args:
        buffer: the dataset's ``episode_buffer`` (changed in place).
        features: the dataset's features (those of shape (1,) are changed).
    """
    for key, ft in features.items():
        if tuple(ft["shape"]) == (1,):
            buffer[key] = [np.asarray(v).reshape(()) for v in buffer[key]]
