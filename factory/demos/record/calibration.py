"""The calibration of the recording cameras fixed in a scene: each camera's pose in the robot's
base frame and its vertical field of view, as its images were drawn, and its layout as the
``observation.camera_poses`` vector of a dataset and of the evaluation env.

A real robot's third-person cameras are calibrated: their extrinsics in the robot's base frame
and their intrinsics are known. Here they are placed per scene (the fixed-base task's
:func:`~factory.tasks.pick_place.plan.aim_cameras` turns, raises or pulls one in where the
kitchen blocks its view) and moved per episode by the appearance jitter (``demos.appearance``:
the ``cam_pos`` and ``cam_quat`` of its :class:`~factory.demos.record.appearance.ModelPatch`).
:func:`camera_calibration` computes both on the host from the composed model and the episode's
patch, so the CPU executor (which writes the patch into the model before drawing) and the GPU
executor (which copies it into its world's fields on the device) record the same numbers.

The vector (:func:`calibration_vector`), per camera in the dataset's camera order:
:data:`CALIBRATION_COLUMNS`: position (3, m), the rows of the rotation matrix (9; MuJoCo's
``cam_xmat``: its columns are the camera's x right, y up and z axes, the camera looking along
-z), both in the robot's base frame, then the vertical field of view (deg).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from factory.errors import RenderError, StoreError

__all__ = [
    "CALIBRATION_COLUMNS",
    "CALIBRATION_SIZE",
    "CAMERA_POSES_KEY",
    "calibration_names",
    "calibration_vector",
    "camera_calibration",
    "cameras_of_names",
]

CAMERA_POSES_KEY = "observation.camera_poses"
"""The dataset feature and env observation of the calibration (float32, 13 per camera)."""
CALIBRATION_COLUMNS = (
    "x",
    "y",
    "z",
    *(f"r{i}{j}" for i in range(3) for j in range(3)),
    "fovy",
)
"""One camera's values in :data:`CAMERA_POSES_KEY`: position (m), rotation rows, fovy (deg)."""
CALIBRATION_SIZE = len(CALIBRATION_COLUMNS)
"""Values per camera in :data:`CAMERA_POSES_KEY` (13)."""


def camera_calibration(
    model: Any,
    cameras: Mapping[str, str],
    base_pos: np.ndarray,
    base_rot: np.ndarray,
    patch: Any = None,
) -> tuple[dict[str, list[float]], dict[str, float]]:
    """The pose in the robot's base frame and the vertical field of view of cameras fixed in
    the world, as drawn with an appearance's model fields.

    Args:
        model: the composed ``MjModel`` (left unchanged).
        cameras: recording camera name -> its camera's name in the model.
        base_pos: (3,) the robot base's position (m, world frame).
        base_rot: (3, 3) its orientation (world from base).
        patch: the episode's :class:`~factory.demos.record.appearance.ModelPatch` (its
            ``cam_pos`` and ``cam_quat`` replace the model's), or None: the model's own.

    Returns:
        camera name -> 12 values (position m, then the rotation's rows; base frame), and
        camera name -> vertical field of view (deg).

    Raises:
        RenderError: a camera that moves with a body or tracks one (its pose is no constant of
            the episode): names it.
    """
    import mujoco

    base_pos = np.asarray(base_pos, np.float64)
    base_rot = np.asarray(base_rot, np.float64)
    cam_pos = np.asarray(model.cam_pos if patch is None else patch.cam_pos, np.float64)
    cam_quat = np.asarray(model.cam_quat if patch is None else patch.cam_quat, np.float64)
    data = None
    poses: dict[str, list[float]] = {}
    fovy: dict[str, float] = {}
    for name, model_name in cameras.items():
        i = model.camera(model_name).id
        body = int(model.cam_bodyid[i])
        fixed = model.cam_mode[i] == mujoco.mjtCamLight.mjCAMLIGHT_FIXED
        if int(model.body_weldid[body]) != 0 or not fixed:
            raise RenderError(
                f"camera {name!r} ({model_name}) moves with body {model.body(body).name!r} or "
                "tracks one: only cameras fixed in the world have a calibration; record it "
                "without, or fix the camera to the world"
            )
        body_pos, body_rot = np.zeros(3), np.eye(3)
        if body != 0:
            if data is None:
                data = mujoco.MjData(model)
                mujoco.mj_kinematics(model, data)
            body_pos = np.array(data.xpos[body])
            body_rot = np.array(data.xmat[body]).reshape(3, 3)
        rot = np.empty(9)
        quat = cam_quat[i] / np.linalg.norm(cam_quat[i])
        mujoco.mju_quat2Mat(rot, quat)
        world_pos = body_pos + body_rot @ cam_pos[i]
        world_rot = body_rot @ rot.reshape(3, 3)
        pos_b = base_rot.T @ (world_pos - base_pos)
        rot_b = base_rot.T @ world_rot
        poses[name] = [float(v) for v in (*pos_b, *rot_b.reshape(-1))]
        fovy[name] = float(model.cam_fovy[i])
    return poses, fovy


def calibration_vector(
    poses: Mapping[str, Sequence[float]], fovy: Mapping[str, float], cameras: Sequence[str]
) -> np.ndarray:
    """The :data:`CAMERA_POSES_KEY` vector (13 * len(cameras),) float32 of ``cameras`` in that
    order, from :func:`camera_calibration`'s two maps (or an episode's ``camera_poses`` and
    ``camera_fovy``).

    Raises:
        KeyError: a camera without a calibration.
    """
    parts = [np.array([*poses[c], fovy[c]], np.float32) for c in cameras]
    return np.concatenate(parts) if parts else np.zeros(0, np.float32)


def calibration_names(cameras: Sequence[str]) -> list[str]:
    """Column names of :data:`CAMERA_POSES_KEY` for ``cameras``: ``<camera>_<column>``."""
    return [f"{c}_{col}" for c in cameras for col in CALIBRATION_COLUMNS]


def cameras_of_names(names: Sequence[str]) -> tuple[str, ...]:
    """The cameras of :data:`CAMERA_POSES_KEY` column names (:func:`calibration_names`), in
    order.

    Raises:
        StoreError: names not of that layout.
    """
    first = CALIBRATION_COLUMNS[0]
    cams = tuple(str(n)[: -len(first) - 1] for n in list(names)[::CALIBRATION_SIZE])
    if list(names) != calibration_names(cams):
        raise StoreError(
            f"{CAMERA_POSES_KEY} names {list(names)[:3]}... are not 13 values per camera "
            "(<camera>_x ... <camera>_fovy): re-export the dataset with stage=dataset force=true"
        )
    return cams
