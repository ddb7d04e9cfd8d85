"""``factory.policy.perception``: the cameras' pixels as points in the robot's base frame,
checked against the recorded object poses of a real recorded dataset (the wrist camera by
forward kinematics, the left camera by its recorded calibration), and the network over several
point cameras."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from robot_models import require_robot_models

pytest.importorskip("lerobot")
if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()


def _dataset_frames(dataset: Path, camera: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A camera's depth (N, H, W) m and the first data file's columns (N rows each)."""
    import pyarrow.parquet as pq
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.policy.video_frames import decode_videos

    base = LeRobotDataset("factory/demos", root=dataset, video_backend="pyav")
    depth_mm = decode_videos(base, [f"observation.depth.{camera}"], workers=1)
    depth = depth_mm[f"observation.depth.{camera}"].astype(np.float32) / 1000.0
    table = pq.read_table(sorted((dataset / "data").glob("*/*.parquet"))[0]).to_pydict()
    n = min(len(table["index"]), len(depth))
    cols = {k: np.asarray(v[:n], np.float64) for k, v in table.items() if k.startswith("obs")}
    cols["episode_index"] = np.asarray(table["episode_index"][:n])
    return depth[:n], cols


def _pick_errors(
    depth: np.ndarray, pose: np.ndarray, fovy: np.ndarray, cols: dict[str, np.ndarray]
) -> list[float]:
    """Per frame where the pick object's recorded position projects into the camera (pose
    (N, 12), fovy (N,) deg): the distance (m) from it to the nearest point of the 3 x 3 pixels
    around its projection (:func:`~factory.policy.perception.pixel_points`)."""
    import torch

    from factory.policy.inputs import base_poses
    from factory.policy.perception import pixel_points

    n, h, w = depth.shape
    fov = torch.from_numpy(np.asarray(fovy, np.float32))
    points = pixel_points(torch.from_numpy(depth), torch.from_numpy(pose), fov).numpy()
    state, ee = cols["observation.state"], cols["observation.ee_pose"]
    base_pos, base_rot = base_poses(state[:, :8], ee)
    env = cols["observation.environment_state"]
    pick = np.einsum("nji,nj->ni", base_rot, env[:, :3] - base_pos)  # base frame
    errors = []
    for i in range(n):
        f = (h / 2) / np.tan(np.radians(fovy[i]) / 2)
        rot = pose[i, 3:12].reshape(3, 3)
        cam = rot.T @ (pick[i] - pose[i, :3])  # camera frame: x right, y up, -z ahead
        if cam[2] > -0.05:
            continue
        col = int(np.floor(cam[0] / -cam[2] * f + w / 2))
        row = int(np.floor(-cam[1] / -cam[2] * f + h / 2))
        if 1 <= row < h - 1 and 1 <= col < w - 1:
            near = points[i, :, row - 1 : row + 2, col - 1 : col + 2].reshape(3, -1).T
            errors.append(float(np.linalg.norm(near - pick[i], axis=1).min()))
    return errors


def test_wrist_pixels_land_on_the_recorded_pick_object(policy_run: Path) -> None:
    """Forward kinematics of the recorded joints gives the wrist camera's pose; the pick
    object's recorded position, projected into the camera with its field of view, falls on a
    pixel whose point (depth along the optical axis, unprojected) lies within a few
    centimetres of it: the camera model, the pixel order and the depth agree with the
    renderer's."""
    from factory.policy.inputs import kinematics
    from factory.policy.perception import XYZ_CAMERA

    depth, cols = _dataset_frames(policy_run / "dataset" / "merged", XYZ_CAMERA)
    kin = kinematics()
    pose = kin.camera_poses(cols["observation.state"][:, :7], XYZ_CAMERA)
    fovy = np.full(len(pose), kin.camera_fovy(XYZ_CAMERA))
    errors = _pick_errors(depth, pose, fovy, cols)
    assert len(errors) >= 20, len(errors)
    assert float(np.median(errors)) < 0.03, np.percentile(errors, [10, 50, 90])


def test_left_camera_calibration_lands_on_the_recorded_pick_object(policy_run: Path) -> None:
    """The left camera's recorded calibration (``observation.camera_poses``: its pose in the
    base frame after the scene's placement and the episode's appearance jitter, and its field of
    view) projects the pick object's recorded position onto pixels whose points lie within a
    few centimetres of it; it is constant within an episode and moves between episodes."""
    from factory.demos.record.calibration import CAMERA_POSES_KEY, cameras_of_names

    dataset = policy_run / "dataset" / "merged"
    feats = json.loads((dataset / "meta" / "info.json").read_text())["features"]
    assert cameras_of_names(feats[CAMERA_POSES_KEY]["names"]) == ("left",)  # not the wrist
    depth, cols = _dataset_frames(dataset, "left")
    calib = cols[CAMERA_POSES_KEY]
    assert calib.shape == (len(depth), 13)
    per_episode = [calib[cols["episode_index"] == e] for e in np.unique(cols["episode_index"])]
    assert all(np.ptp(c, axis=0).max() == 0 for c in per_episode)
    if len(per_episode) > 1:  # the appearance jitter moves the camera per episode
        assert np.abs(per_episode[0][0] - per_episode[1][0]).max() > 1e-4
    errors = _pick_errors(depth, calib[:, :12], calib[:, 12], cols)
    assert len(errors) >= 20, len(errors)
    assert float(np.median(errors)) < 0.05, np.percentile(errors, [10, 50, 90])


def test_network_reads_the_points_of_several_cameras(tmp_path: Path) -> None:
    """Points of the left camera (its calibration) and the wrist camera (kinematics) enter the
    network; its settings name them, so a loaded network predicts the same; a version-1
    network (the wrist camera's points alone) still loads and predicts; a point camera without
    its calibration is refused with the fix."""
    import torch

    from factory.errors import PolicyError
    from factory.policy import perception as P
    from factory.policy.inputs import kinematics

    torch.manual_seed(0)
    target = np.random.default_rng(0).normal(size=(10, 24))
    cams = ["left", "right", "wrist"]
    points = P.point_cameras_of(cams, True, ["left", "right"])
    assert points == cams and P.point_cameras_of(cams, True, [], points=False) == []
    settings = P.settings_of(
        cams, True, (32, 32), target, 2.0, ["left", "wrist"], ["left", "right"]
    )
    net = P.build(settings).eval()
    assert net.point_cameras == ["left", "wrist"] and net.xyz
    state = np.zeros((2, 8))
    look = np.r_[0.5, 0.7, 0.6, np.eye(3).ravel(), 50.0]
    calib = np.tile(np.r_[look, look + 0.1], (2, 1)).astype(np.float32)  # left, right
    poses = P.camera_poses(net.point_cameras, state, calib, ["left", "right"])
    assert poses.shape == (2, 2, 13)
    np.testing.assert_array_equal(poses[:, 0], calib[:, :13])
    assert poses[0, 1, 12] == pytest.approx(kinematics().camera_fovy("wrist"))
    images = torch.rand(2, 3, 4, 32, 32)
    with torch.no_grad():
        out = net(images, torch.from_numpy(poses))
        moved = poses.copy()
        moved[:, 0, 0] += 0.3  # the left camera elsewhere: its points move
        assert out.shape == (2, 24)
        assert not torch.allclose(out, net(images, torch.from_numpy(moved)))
    P.save(net, tmp_path)
    again = P.load(tmp_path, "cpu")
    assert again.point_cameras == ["left", "wrist"] and again.pose_cameras == ["left", "right"]
    with torch.no_grad():
        torch.testing.assert_close(again(images, torch.from_numpy(poses)), out)
    with pytest.raises(PolicyError, match=r"observation\.camera_poses"):
        P.camera_poses(net.point_cameras, state, None, ())
    # a network saved before several cameras' points: the wrist camera's, by xyz_camera
    old = {k: v for k, v in settings.items() if k not in ("point_cameras", "pose_cameras")}
    old.update(schema_version=1, xyz_camera="wrist", xyz_fovy_deg=75.0)
    (tmp_path / "v1").mkdir()
    P.save(P.build(old), tmp_path / "v1")
    v1 = P.load(tmp_path / "v1", "cpu")
    assert v1.point_cameras == ["wrist"] and v1.pose_cameras == []
    with torch.no_grad():
        wrist = torch.from_numpy(P.camera_poses(v1.point_cameras, state))
        assert v1(images, wrist).shape == (2, 24)
    # one field of view for the batch or one per sample: the same points
    depth = torch.rand(2, 8, 8) + 0.5
    pose = torch.from_numpy(calib[:, :12])
    torch.testing.assert_close(
        P.pixel_points(depth, pose, 50.0), P.pixel_points(depth, pose, torch.full((2,), 50.0))
    )


def test_projection_inverts_the_pixel_points() -> None:
    """:func:`~factory.policy.perception.project` sends every pixel's point back to that
    pixel's centre at its depth, for a tilted camera."""
    import torch

    from factory.policy import perception as P

    rng = np.random.default_rng(1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    pose = torch.from_numpy(np.r_[0.4, -0.2, 0.9, q.ravel(), 55.0].astype(np.float32))
    pose = pose.expand(2, 13)
    depth = torch.from_numpy(rng.uniform(0.3, 1.8, size=(2, 12, 16)).astype(np.float32))
    pts = P.pixel_points(depth, pose, pose[:, 12])  # (2, 3, 12, 16)
    px, got = P.project(pts.flatten(2).transpose(1, 2), pose, (12, 16))
    rows, cols = np.meshgrid(np.arange(12) + 0.5, np.arange(16) + 0.5, indexing="ij")
    want = np.stack([cols.ravel(), rows.ravel()], -1)
    np.testing.assert_allclose(px[1].numpy(), want, atol=1e-3)
    np.testing.assert_allclose(got.numpy(), depth.flatten(1).numpy(), rtol=1e-4)


def test_wrist_camera_pose_gives_the_recorded_tool_offsets(policy_run: Path) -> None:
    """The tool point fixed in the wrist camera's frame (``tool_in_wrist``) and the camera's
    pose by forward kinematics give the tool offsets of the recorded environment values: what
    an object-keypoint network computes them from."""
    from factory.policy import perception as P
    from factory.policy.inputs import env_features

    _, cols = _dataset_frames(policy_run / "dataset" / "merged", P.XYZ_CAMERA)
    state = cols["observation.state"][:, :8]
    env = env_features(state, cols["observation.ee_pose"], cols["observation.environment_state"])
    cam = P.wrist_poses(state).astype(np.float64)
    tool = cam[:, :3] + np.einsum("nij,j->ni", cam[:, 3:12].reshape(-1, 3, 3), P.tool_in_wrist())
    for (a, z), (oa, oz) in zip(P.POSITIONS, P.OFFSETS, strict=True):
        np.testing.assert_allclose(env[:, a:z] - tool, env[:, oa:oz], atol=2e-3)


def test_object_keypoints_find_the_objects_and_give_their_positions(tmp_path: Path) -> None:
    """With ``object_keypoints`` the network's position columns are the points under its
    objects' keypoints (plus a correction of at most ``RESIDUAL_M``) and the offsets follow
    from the wrist camera's pose; its heatmap loss is finite and trains the keypoint heads;
    trained briefly on one synthetic view (a box on a plane seen from above) its keypoint
    lands on the box; it saves and loads; a version-2 network (no object keypoints) loads."""
    import torch

    from factory.policy import perception as P

    torch.manual_seed(0)
    cams = ["left", "wrist"]
    rng = np.random.default_rng(0)
    n, size = 4, 48
    # a camera 1 m above the origin looking down (-z of the camera = -z of the base)
    look = np.r_[0.0, 0.0, 1.0, np.eye(3).ravel(), 60.0].astype(np.float32)
    depth = np.ones((n, size, size), np.float32)
    target = rng.normal(scale=0.05, size=(n, 24)).astype(np.float32)
    f = (size / 2) / np.tan(np.radians(30.0))
    where = []
    for i in range(n):  # a box 20 cm tall whose top holds the pick object's centre
        r, c = rng.integers(10, size - 10, size=2)
        where.append((r, c))
        depth[i, r - 3 : r + 3, c - 3 : c + 3] = 0.8
        target[i, 0:3] = [(c - size / 2) / f * 0.8, -(r - size / 2) / f * 0.8, 0.2]
    settings = P.settings_of(cams, True, (size, size), target, 2.0, cams, ["left"])
    assert settings["object_keypoints"] and settings["tool_in_wrist"] is not None
    net = P.build(settings)
    assert net.objects and net.wrist_slot == 1
    images = torch.rand(n, 2, 4, size, size)
    images[:, 0, 3] = torch.from_numpy(depth) / 2.0
    poses = torch.from_numpy(
        P.camera_poses(net.point_cameras, np.zeros((n, 8)), look[None].repeat(n, 0), ["left"])
    )
    values, heat = net(images, poses, heat=True)
    assert values.shape == (n, 24) and heat.shape == (n, 2, 2, P.READOUT, P.READOUT)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    losses = []
    for _ in range(40):
        loss, _ = net.loss(images, torch.from_numpy(target), poses)
        losses.append(float(loss.detach()))
        opt.zero_grad()
        loss.backward()
        assert net.object_heads.weight.grad is not None
        opt.step()
    assert np.mean(losses[-10:]) < 0.7 * np.mean(losses[:5]), losses
    with torch.no_grad():
        got = net.predict(images, poses)
        _, heat = net(images, poses, heat=True)
    peak = heat[:, 0, 0].flatten(1).argmax(1).numpy()  # the left camera's pick keypoint
    cell = size / P.READOUT
    found = np.stack([peak // P.READOUT, peak % P.READOUT], 1) * cell + cell / 2
    miss = np.abs(found - np.array(where)).max(1)  # px, the box spans 6
    assert (miss <= 4).sum() >= 3, (found, where)
    moved = got[:, 0:3].numpy()
    assert np.median(np.linalg.norm(moved - target[:, 0:3], axis=1)) < 0.15
    P.save(net, tmp_path)
    again = P.load(tmp_path, "cpu")
    with torch.no_grad():
        torch.testing.assert_close(again.predict(images, poses), got)
    old = P.settings_of(cams, True, (size, size), target, 2.0, cams, ["left"], False)
    old = {k: v for k, v in old.items() if k not in ("object_keypoints", "tool_in_wrist")}
    old["schema_version"] = 2
    (tmp_path / "v2").mkdir()
    P.save(P.build(old), tmp_path / "v2")
    v2 = P.load(tmp_path / "v2", "cpu")
    assert not v2.objects
    with torch.no_grad():
        assert v2(images, poses).shape == (n, 24)
