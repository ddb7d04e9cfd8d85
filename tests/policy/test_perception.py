"""``factory.policy.perception``: the wrist camera's pixels as points in the robot's base frame,
checked against the recorded object poses of a real recorded dataset."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    pytest.importorskip("robosuite")


def test_wrist_pixels_land_on_the_recorded_pick_object(policy_run: Path) -> None:
    """Forward kinematics of the recorded joints gives the wrist camera's pose; the pick
    object's recorded position, projected into the camera with its field of view, falls on a
    pixel whose point (depth along the optical axis, unprojected) lies within a few
    centimetres of it: the camera model, the pixel order and the depth agree with the
    renderer's."""
    import pyarrow.parquet as pq
    import torch
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.policy.inputs import base_poses, kinematics
    from factory.policy.perception import XYZ_CAMERA, pixel_points
    from factory.policy.video_frames import decode_videos

    dataset = policy_run / "dataset" / "merged"
    base = LeRobotDataset("factory/demos", root=dataset, video_backend="pyav")
    depth_mm = decode_videos(base, [f"observation.depth.{XYZ_CAMERA}"], workers=1)
    depth = depth_mm[f"observation.depth.{XYZ_CAMERA}"].astype(np.float32) / 1000.0
    table = pq.read_table(sorted((dataset / "data").glob("*/*.parquet"))[0]).to_pydict()
    state = np.asarray(table["observation.state"], np.float64)
    ee = np.asarray(table["observation.ee_pose"], np.float64)
    env = np.asarray(table["observation.environment_state"], np.float64)
    n = min(len(state), len(depth))
    kin = kinematics()
    pose = kin.camera_poses(state[:n, :7], XYZ_CAMERA)
    fovy = kin.camera_fovy(XYZ_CAMERA)
    points = pixel_points(torch.from_numpy(depth[:n]), torch.from_numpy(pose), fovy).numpy()
    base_pos, base_rot = base_poses(state[:n, :8], ee[:n])
    pick = np.einsum("nji,nj->ni", base_rot, env[:n, :3] - base_pos)  # base frame
    h, w = depth.shape[1:]
    f = (h / 2) / np.tan(np.radians(fovy) / 2)
    errors = []
    for i in range(n):
        rot = pose[i, 3:].reshape(3, 3)
        cam = rot.T @ (pick[i] - pose[i, :3])  # camera frame: x right, y up, -z ahead
        if cam[2] > -0.05:
            continue
        col = int(np.floor(cam[0] / -cam[2] * f + w / 2))
        row = int(np.floor(-cam[1] / -cam[2] * f + h / 2))
        if 1 <= row < h - 1 and 1 <= col < w - 1:
            near = points[i, :, row - 1 : row + 2, col - 1 : col + 2].reshape(3, -1).T
            errors.append(np.linalg.norm(near - pick[i], axis=1).min())
    assert len(errors) >= 20, len(errors)
    assert float(np.median(errors)) < 0.03, np.percentile(errors, [10, 50, 90])
