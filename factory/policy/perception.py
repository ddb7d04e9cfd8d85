"""The object poses read from the cameras: the perception network of ``train.vision=perception``.

An image policy trained end to end (``train.vision=end_to_end``: lerobot's diffusion policy
with its ResNet-18 per camera image) must learn from the action loss alone where the pick
object and the target are; on 16 generated kitchens in a GPU session it has not (0-2 % held-
out success, docs/POLICY.md). A state policy, told the poses, learns the task in minutes.
``train.vision=perception`` splits the two:

* this network reads the newest frame's camera images (RGB, and depth as a fourth channel for
  ``rgbd``) and predicts the environment state the state policy reads
  (:func:`factory.policy.inputs.env_features`: both objects' poses in the robot's base frame
  and the tool's offsets to them, 24 values), trained by regression on the dataset's recorded
  poses;
* lerobot's diffusion policy (the state recipe) reads the robot state and that environment
  state; it trains on the recorded poses with Gaussian position noise
  (``train.perception_noise_m``), and acts on the network's predictions.

At evaluation the env gives the policy images, the robot state and (where the network reads
them) the cameras' calibration, never the objects' poses:
:class:`factory.policy.checkpoint.LoadedPolicy` fills ``observation.environment_state`` with
this network's prediction. The network's weights and settings are saved beside lerobot's
``pretrained_model`` files (:data:`WEIGHTS`, :data:`SETTINGS`); the policy alone is a plain
lerobot state policy.

Architecture: a ResNet-18 trunk (torchvision, GroupNorm, up to ``layer3``: stride 16, an 8 x 8
map at 128 px, finer than lerobot's 3 x 3 at 84 px) shared by the cameras, with a first
convolution of 3 (RGB) or 4 (RGB + depth) channels, 3 more where cameras' points are read (below);
a spatial softmax per camera (:data:`KEYPOINTS` expected image positions) and the map's mean
features; an MLP over every camera's to the 24 values scaled to [-1, 1] by their range over the
training frames.

Points (``train.perception_points``, with depth): every camera whose pose the robot knows turns
its pixels into points in the robot's base frame (:func:`pixel_points`: depth along the optical
axis through the camera's field of view), three more input channels of that camera's image, and
each of its keypoints reads the point it attends to. The :data:`XYZ_CAMERA` rides on the hand:
its pose is forward kinematics of the joints (:func:`wrist_poses`). The cameras fixed in the
scene (left, right) are placed per scene and jittered per episode; their pose is known where the
dataset records their calibration (``observation.camera_poses``,
:mod:`factory.demos.record.calibration`), which the evaluation env observes too. The network
reads the poses and fields of view of its point cameras (:func:`camera_poses`: (B, P, 13)) beside
the images.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import PolicyError

SCHEMA_VERSION = 3
"""Version of :data:`SETTINGS` written now (3: ``object_keypoints`` and ``tool_in_wrist``;
2: ``point_cameras`` and ``pose_cameras`` for several cameras' points, where version 1 had
``xyz_camera``, the wrist camera or none)."""
READABLE_VERSIONS = (1, 2, 3)
"""Versions of :data:`SETTINGS` this factory loads (a version-1 network reads the points of
its ``xyz_camera`` alone)."""
WEIGHTS = "perception.safetensors"
"""The network's weights in a ``pretrained_model`` folder."""
SETTINGS = "perception.json"
"""Its settings (cameras, channels, image size, target range, point cameras) beside them."""
KEYPOINTS = 32
"""Spatial-softmax keypoints per camera."""
HIDDEN = 512
"""Width of the MLP's hidden layers."""
XYZ_CAMERA = "wrist"
"""The camera whose pose the robot knows at every frame from its joints (it rides on the hand:
forward kinematics, :func:`wrist_poses`). The left and right cameras are placed per scene: their
pose is known only from the dataset's calibration (``observation.camera_poses``)."""
CAMERA_POSE = "aux.camera_pose"
"""Batch key of the point cameras' poses and fields of view of each sample's frame (B, P, 13)
(:func:`camera_poses`; popped before lerobot's processors)."""
POSE_SIZE = 13
"""Values per camera of :func:`camera_poses`: position (3, m), rotation rows (9), fovy (deg)."""
READOUT = 32
"""Side (px) of the grid at which keypoints read their camera's points."""
POSITIONS = ((0, 3), (9, 12))
"""Columns of the pick object's and the target's positions in the 24 environment values."""
OFFSETS = ((18, 21), (21, 24))
"""Columns of the tool's offsets to them (they move with the positions)."""
HEAT_WEIGHT = 0.1
"""Weight of the object keypoints' heatmap loss (cross-entropy against the objects' projected
pixels) beside the values' mean squared error."""
HEAT_SIGMA = 1.0
"""Standard deviation (cells of the :data:`READOUT` grid) of the Gaussian around an object's
projected pixel that its keypoint learns."""
VISIBLE_M = 0.12
"""An object's centre counts as seen by a camera when the depth at its projected pixel is at
most this much nearer than the centre (m): its own surface, not an occluder."""
FINE = 128
"""Channels of the object keypoints' feature pyramid."""
MIN_SPAN_M = 0.2
"""With object keypoints, the smallest range (m) that scales a position or offset column."""
RESIDUAL_M = 0.05
"""Largest learned correction (m, per axis) of an object's position from its keypoints' points
(the surface a camera sees lies in front of the body's origin)."""


def _torch() -> Any:
    import torch

    return torch


def settings_of(
    cameras: list[str],
    depth: bool,
    image_size: tuple[int, int],
    target: np.ndarray,
    depth_max_m: float = 2.0,
    point_cameras: Sequence[str] = (),
    pose_cameras: Sequence[str] = (),
    object_keypoints: bool = True,
) -> dict[str, Any]:
    """The settings that rebuild a network.

    Args:
        cameras: the cameras read, in order.
        depth: a depth channel per camera.
        image_size: (H, W) px.
        target: (N, 24) the training frames' targets (their range scales the outputs).
        depth_max_m: the depth range (m).
        point_cameras: of ``cameras``, those whose pixels become base-frame points (with
            depth; :func:`point_cameras_of`), in ``cameras`` order.
        pose_cameras: the cameras of the dataset's ``observation.camera_poses``, in its order
            (where the non-wrist point cameras' calibration is read from).
        object_keypoints: with point cameras, the objects' positions are read from the points
            under two keypoints per camera that learn to find the pick object and the target
            (``train.perception_objects``; see :func:`build`).
    """
    points = [c for c in cameras if c in set(point_cameras)] if depth else []
    tool = tool_in_wrist() if XYZ_CAMERA in points else None
    return {
        "schema_version": SCHEMA_VERSION,
        "cameras": list(cameras),
        "depth": bool(depth),
        "image_size": [int(image_size[0]), int(image_size[1])],
        "keypoints": KEYPOINTS,
        "hidden": HIDDEN,
        "low": [float(x) for x in np.asarray(target).min(0)],
        "high": [float(x) for x in np.asarray(target).max(0)],
        "depth_max_m": float(depth_max_m),
        "point_cameras": points,
        "pose_cameras": list(pose_cameras),
        "object_keypoints": bool(object_keypoints and points),
        "tool_in_wrist": None if tool is None else [float(x) for x in tool],
    }


def tool_in_wrist() -> np.ndarray:
    """The tool point (the environment values' tool, ``ee_pose``) in the :data:`XYZ_CAMERA`'s
    frame (3,) m (x right, y up, -z viewing): fixed, both ride on the hand (forward kinematics
    at the zero pose)."""
    from factory.policy.inputs import kinematics

    q = np.zeros((1, 7))
    pos, _ = kinematics().tool_poses(q)
    cam = kinematics().camera_poses(q, XYZ_CAMERA)[0].astype(np.float64)
    return cam[3:12].reshape(3, 3).T @ (pos[0] - cam[:3])


def project(points: Any, pose: Any, size: tuple[int, int]) -> tuple[Any, Any]:
    """Where points in the robot's base frame fall in a camera's image (the inverse of
    :func:`pixel_points`).

    Args:
        points: (B, K, 3) points, base frame (m).
        pose: (B, >= 13) the camera's position, rotation rows and fovy (deg)
            (:func:`camera_poses`).
        size: (H, W) of the image (px).

    Returns:
        (B, K, 2) column and row (px, pixel centres at +0.5) and (B, K) depth along the
        optical axis (m; <= 0 behind the camera).
    """
    torch = _torch()
    h, w = size
    rot = pose[:, 3:12].float().reshape(-1, 3, 3)
    rel = points.float() - pose[:, None, :3].float()
    cam = torch.einsum("bji,bkj->bki", rot, rel)  # R^T (p - c)
    depth = -cam[..., 2]
    f = (h / 2) / torch.tan(torch.deg2rad(pose[:, 12].float()) / 2)  # (B,)
    safe = torch.clamp(depth, min=1e-3)
    col = f[:, None] * cam[..., 0] / safe + w / 2
    row = -f[:, None] * cam[..., 1] / safe + h / 2
    return torch.stack([col, row], -1), depth


def settings_points(settings: dict[str, Any]) -> list[str]:
    """The point cameras of saved settings (a version-1 file: its ``xyz_camera``, or none)."""
    if "point_cameras" in settings:
        return [str(c) for c in settings["point_cameras"]]
    xyz = str(settings.get("xyz_camera", ""))
    return [xyz] if xyz else []


def point_cameras_of(
    cameras: Sequence[str], depth: bool, pose_cameras: Sequence[str], points: bool = True
) -> list[str]:
    """The cameras whose pixels become points (``train.perception_points``): with depth, the
    :data:`XYZ_CAMERA` and every camera with a calibration (``pose_cameras``), in ``cameras``
    order; none without depth or ``points``."""
    if not (depth and points):
        return []
    return [c for c in cameras if c == XYZ_CAMERA or c in set(pose_cameras)]


def wrist_poses(joints: np.ndarray) -> np.ndarray:
    """The :data:`XYZ_CAMERA`'s pose (N, 12) for arm joints (N, 7) (rad): forward kinematics
    (:meth:`factory.policy.inputs.kinematics`), base frame, as :func:`pixel_points` takes it."""
    from factory.policy.inputs import kinematics

    return kinematics().camera_poses(np.asarray(joints, np.float64)[:, :7], XYZ_CAMERA)


def camera_poses(
    point_cameras: Sequence[str],
    state: np.ndarray,
    calibration: np.ndarray | None = None,
    pose_cameras: Sequence[str] = (),
) -> np.ndarray:
    """The network's poses input: each point camera's pose and field of view per frame.

    Args:
        point_cameras: the network's point cameras, in its order.
        state: (N, >= 7) the dataset's or env's ``observation.state`` (arm joints first, rad).
        calibration: (N, 13 * len(pose_cameras)) ``observation.camera_poses`` (None: none).
        pose_cameras: the cameras of ``calibration``, in its order.

    Returns:
        (N, P, 13) float32: per point camera its position (m) and rotation rows in the robot's
        base frame, then its vertical field of view (deg): the :data:`XYZ_CAMERA`'s by forward
        kinematics, the others' from the calibration.

    Raises:
        PolicyError: a point camera without a pose (a dataset or env without its calibration).
    """
    from factory.policy.inputs import kinematics

    state = np.asarray(state)
    n = len(state)
    out = np.zeros((n, len(point_cameras), POSE_SIZE), np.float32)
    for k, cam in enumerate(point_cameras):
        if cam == XYZ_CAMERA:
            out[:, k, :12] = wrist_poses(state)
            out[:, k, 12] = kinematics().camera_fovy(cam)
            continue
        if calibration is None or cam not in pose_cameras:
            raise PolicyError(
                f"the perception network reads the {cam} camera's points, but these "
                "observations lack its calibration (observation.camera_poses): evaluate it "
                "where its dataset came from, or re-export the dataset (stage=dataset "
                "force=true) from episodes recorded with it"
            )
        j = list(pose_cameras).index(cam) * POSE_SIZE
        out[:, k] = np.asarray(calibration, np.float32).reshape(n, -1)[:, j : j + POSE_SIZE]
    return out


def pixel_points(depth_m: Any, pose: Any, fovy_deg: Any) -> Any:
    """The point behind every pixel of a camera, in the robot's base frame (m).

    Args:
        depth_m: (B, H, W) depth along the camera's optical axis (m), row 0 at the top.
        pose: (B, >= 12) the camera's position, then its rotation's rows (MuJoCo's
            ``cam_xmat``: columns x right, y up, -z the viewing direction), base frame.
        fovy_deg: the camera's vertical field of view (deg): one number, or (B,) per sample.

    Returns:
        (B, 3, H, W) x, y, z of each pixel's point.
    """
    torch = _torch()
    b, h, w = depth_m.shape
    dev = depth_m.device
    if isinstance(fovy_deg, int | float):
        f: Any = (h / 2) / float(np.tan(np.radians(fovy_deg) / 2))
    else:
        fov = torch.as_tensor(fovy_deg, device=dev).float().reshape(-1, 1, 1)
        f = (h / 2) / torch.tan(torch.deg2rad(fov) / 2)  # (B, 1, 1)
    u = torch.arange(w, device=dev, dtype=torch.float32) + 0.5 - w / 2
    v = -(torch.arange(h, device=dev, dtype=torch.float32) + 0.5 - h / 2)
    d = depth_m.float()
    cam = torch.stack([d * u[None, None, :] / f, d * v[None, :, None] / f, -d], 1)  # (B,3,H,W)
    rot = pose[:, 3:12].float().reshape(b, 3, 3)
    return torch.einsum("bij,bjhw->bihw", rot, cam) + pose[:, :3].float()[:, :, None, None]


def build(settings: dict[str, Any]) -> Any:
    """The network (a ``torch.nn.Module``, fresh weights) of these settings."""
    import torch
    import torch.nn.functional as F
    import torchvision

    nn = torch.nn

    def expected(logits: Any, values: Any) -> Any:
        """Softmax-weighted mean of ``values`` (B, C, h, w) under each of the ``k`` attention
        maps ``logits`` (B, k, h, w): (B, k, C)."""
        attn = F.softmax(logits.flatten(2).float(), dim=-1)
        return attn @ values.flatten(2).float().transpose(1, 2)

    class SpatialSoftmax(nn.Module):
        """Attention maps of ``k`` learned keypoints and their expected image positions."""

        def __init__(self, channels: int, k: int) -> None:
            super().__init__()
            self.proj = nn.Conv2d(channels, k, 1)

        def forward(self, x: Any) -> tuple[Any, Any]:
            """Logits (B, k, h, w) and expected positions (B, 2k), x, y in [-1, 1]."""
            b, _, h, w = x.shape
            logits = self.proj(x).float()
            ys = torch.linspace(-1, 1, h, device=x.device)
            xs = torch.linspace(-1, 1, w, device=x.device)
            gy, gx = torch.meshgrid(ys, xs, indexing="ij")
            grid = torch.stack([gx, gy], 0).expand(b, 2, h, w)
            return logits, expected(logits, grid).reshape(b, -1)

    class Perception(nn.Module):
        """Camera images of one frame -> the 24 environment values (see the module)."""

        def __init__(self) -> None:
            super().__init__()
            self.settings = dict(settings)
            self.cameras = list(settings["cameras"])
            self.depth = bool(settings["depth"])
            self.point_cameras = settings_points(settings)
            """The cameras whose pixels become points, in :attr:`cameras` order."""
            self.pose_cameras = [str(c) for c in settings.get("pose_cameras", [])]
            """The cameras of the calibration (``observation.camera_poses``) it was trained
            on, in that vector's order."""
            self.point_index = [self.cameras.index(c) for c in self.point_cameras]
            self.depth_max = float(settings.get("depth_max_m", 2.0))
            chans = (4 if self.depth else 3) + (3 if self.point_index else 0)
            net = torchvision.models.resnet18(
                weights=None, norm_layer=lambda c: nn.GroupNorm(max(c // 16, 1), c)
            )
            net.conv1 = nn.Conv2d(chans, 64, kernel_size=7, stride=2, padding=3, bias=False)
            self.trunk = nn.Sequential(
                net.conv1, net.bn1, net.relu, net.maxpool, net.layer1, net.layer2, net.layer3
            )
            k = int(settings["keypoints"])
            self.keypoints = SpatialSoftmax(256, k)
            n = len(self.cameras)
            hidden = int(settings["hidden"])
            dim = len(settings["low"])
            width = n * (2 * k + 256) + 3 * k * len(self.point_index)
            self.objects = bool(settings.get("object_keypoints", False)) and bool(self.point_index)
            """Whether the objects' positions come from their keypoints' points."""
            tool = settings.get("tool_in_wrist")
            self.wrist_slot = (
                self.point_cameras.index(XYZ_CAMERA)
                if self.objects and tool is not None and XYZ_CAMERA in self.point_cameras
                else -1
            )
            """Index among the point cameras of the wrist camera, whose pose gives the tool's
            position (the offsets' columns); -1: the MLP predicts the offsets."""
            n_obj = len(POSITIONS)
            extra_out = 0
            if self.objects:
                n_pts = len(self.point_index)
                # a small feature pyramid down to layer1 (stride 4: 32 x 32 at 128 px)
                self.top = nn.Conv2d(256, FINE, 1)
                self.lateral2 = nn.Conv2d(128, FINE, 1)
                self.lateral1 = nn.Conv2d(64, FINE, 1)
                self.object_heads = nn.Conv2d(FINE, n_obj, 3, padding=1)
                self.trust = nn.Linear(FINE + n_obj, n_obj)
                width += n_pts * n_obj * 4
                extra_out = 3 * n_obj  # the residuals
                self.register_buffer(
                    "tool_in_wrist",
                    torch.as_tensor(tool if tool is not None else [0.0] * 3, dtype=torch.float32),
                )
            self.mlp = nn.Sequential(
                nn.Linear(width, hidden),
                nn.ReLU(),
                nn.Linear(hidden, hidden),
                nn.ReLU(),
                nn.Linear(hidden, dim + extra_out),
            )
            self.dim = dim
            low = torch.as_tensor(settings["low"], dtype=torch.float32)
            high = torch.as_tensor(settings["high"], dtype=torch.float32)
            if self.objects:  # geometric columns: an error in metres, even where the
                # training frames hardly vary (an object always on one table)
                for a, z in (*POSITIONS, *OFFSETS):
                    high[a:z] = torch.maximum(high[a:z], low[a:z] + MIN_SPAN_M)
            self.register_buffer("low", low)
            self.register_buffer("span", torch.clamp(high - low, min=1e-6))

        @property
        def xyz(self) -> bool:
            """Whether the network reads cameras' points (needs their poses:
            :func:`camera_poses`)."""
            return bool(self.point_index)

        def forward(self, images: Any, poses: Any = None, heat: bool = False) -> Any:
            """Predictions scaled to [-1, 1] (B, 24) from ``images`` (B, n_cams, C, H, W),
            values in [0, 1], and (:attr:`xyz`) the point cameras' poses and fields of view
            (B, P, 13) (:func:`camera_poses`; the module's call: what ``torch.compile``
            compiles). With ``heat`` (and :attr:`objects`), also the object keypoints'
            logits (B, P, 2, :data:`READOUT`, :data:`READOUT`), for :meth:`loss`."""
            b, n = images.shape[:2]
            x = (images - 0.5) / 0.25
            points = []
            if self.point_index:
                if poses is None:
                    raise PolicyError(
                        f"the perception network reads the points of the "
                        f"{', '.join(self.point_cameras)} camera(s): give their poses "
                        "(perception.camera_poses: forward kinematics of the joints, the "
                        "observed calibration)"
                    )
                extra = torch.zeros_like(x[:, :, :3])
                for j, c in enumerate(self.point_index):
                    depth_m = images[:, c, 3] * self.depth_max
                    pts = pixel_points(depth_m, poses[:, j], poses[:, j, 12])  # (B, 3, H, W)
                    extra[:, c] = pts / 0.5
                    points.append(pts)
                x = torch.cat([x, extra], 2)
            x = x.flatten(0, 1).contiguous(memory_format=torch.channels_last)
            taps = {}
            for i, layer in enumerate(self.trunk):
                x = layer(x)
                if i in (4, 5):  # layer1, layer2
                    taps[i] = x
            fmap = x  # (B*n, 256, h, w)
            logits, coords = self.keypoints(fmap)
            parts = [coords, fmap.float().mean(dim=(-2, -1))]
            feats = torch.cat(parts, -1).reshape(b, -1)
            reads = [feats]
            found = []  # per point camera: (B, 2, 3) the objects' keypoints' points
            obj_logits = []
            trust = []
            if points:  # each keypoint's point, read at READOUT px
                h, w = logits.shape[-2:]
                per_cam = logits.reshape(b, n, -1, h, w)
                if self.objects:
                    l1, l2 = taps[4], taps[5]
                    f = self.top(fmap)
                    f = F.relu(self.lateral2(l2) + F.interpolate(f, size=l2.shape[-2:]))
                    f = F.relu(self.lateral1(l1) + F.interpolate(f, size=l1.shape[-2:]))
                    heads = self.object_heads(f).float()
                    heads = heads.reshape(b, n, -1, *heads.shape[-2:])
                    pooled = f.float().mean(dim=(-2, -1)).reshape(b, n, -1)
                for pts, c in zip(points, self.point_index, strict=True):
                    grid = F.adaptive_avg_pool2d(pts, READOUT)
                    up = F.interpolate(per_cam[:, c], size=(READOUT, READOUT), mode="bilinear")
                    got = expected(up, grid)  # (B, k, 3)
                    reads.append(got.reshape(b, -1))
                    if self.objects:
                        ol = F.interpolate(heads[:, c], size=(READOUT, READOUT), mode="bilinear")
                        at = expected(ol, grid)  # (B, 2, 3)
                        peak = ol.flatten(2).amax(-1)  # (B, 2)
                        found.append(at)
                        obj_logits.append(ol)
                        trust.append(self.trust(torch.cat([pooled[:, c], peak], -1)))
                        reads.append(torch.cat([at, peak[..., None]], -1).reshape(b, -1))
            out = self.mlp(torch.cat(reads, -1))
            if not self.objects:
                return (out, None) if heat else out
            values = out[:, : self.dim]
            residual = torch.tanh(out[:, self.dim :].reshape(b, -1, 3)) * RESIDUAL_M
            weight = torch.softmax(torch.stack(trust, 1), dim=1)  # (B, P, 2) over cameras
            pos = (torch.stack(found, 1) * weight[..., None]).sum(1) + residual  # (B, 2, 3)
            cols = list(values.unbind(-1))
            for o, (a, _) in enumerate(POSITIONS):
                for ax in range(3):
                    cols[a + ax] = self._scaled(pos[:, o, ax], a + ax)
            if self.wrist_slot >= 0:
                wp = poses[:, self.wrist_slot].float()
                tool = wp[:, :3] + wp[:, 3:12].reshape(b, 3, 3) @ self.tool_in_wrist
                for o, (a, _) in enumerate(OFFSETS):
                    for ax in range(3):
                        cols[a + ax] = self._scaled(pos[:, o, ax] - tool[:, ax], a + ax)
            values = torch.stack(cols, -1)
            if heat:
                return values, torch.stack(obj_logits, 1)
            return values

        def _scaled(self, v: Any, col: int) -> Any:
            """Dataset units -> the [-1, 1] scale of column ``col``."""
            low: Any = self.low
            span: Any = self.span
            return 2 * (v - low[col]) / span[col] - 1

        def predict(self, images: Any, poses: Any = None) -> Any:
            """The 24 environment values (B, 24), in the dataset's units (m, rotations)."""
            return (self(images, poses).float() + 1) * 0.5 * self.span + self.low

        def loss(self, images: Any, target: Any, poses: Any = None) -> tuple[Any, Any]:
            """Mean squared error in the [-1, 1] scale against ``target`` (B, 24, dataset
            units), and the root-mean-square error of the two objects' positions (m), detached.
            """
            want = 2 * (target.float() - self.low) / self.span - 1
            got, heat = self(images, poses, heat=True)
            got = got.float()
            mse = F.mse_loss(got, want)
            if heat is not None:
                mse = mse + HEAT_WEIGHT * self._heat_loss(heat, images, target, poses)
            with torch.no_grad():
                err = (got - want) * 0.5 * self.span
                pos = torch.cat([err[:, a:b] for a, b in POSITIONS], -1)
                rms = pos.square().sum(-1).div(len(POSITIONS)).mean().sqrt()
            return mse, rms

        def _heat_loss(self, heat: Any, images: Any, target: Any, poses: Any) -> Any:
            """Cross-entropy of the object keypoints' maps ``heat`` (B, P, 2, R, R) against a
            Gaussian at each object's projected pixel, over the cameras that see it (in the
            image, in front, and the depth there within :data:`VISIBLE_M` of its centre)."""
            b, r = heat.shape[0], heat.shape[-1]
            h, w = images.shape[-2:]
            centres = torch.stack([target[:, a:z] for a, z in POSITIONS], 1).float()  # (B,2,3)
            cells = torch.arange(r, device=heat.device, dtype=torch.float32) + 0.5
            total = heat.new_zeros(())
            count = heat.new_zeros(())
            for j, c in enumerate(self.point_index):
                px, depth = project(centres, poses[:, j], (h, w))  # (B, 2, 2), (B, 2)
                col, row = px[..., 0], px[..., 1]
                inside = (col >= 0) & (col < w) & (row >= 0) & (row < h) & (depth > 0.05)
                ci = col.clamp(0, w - 1).long()
                ri = row.clamp(0, h - 1).long()
                seen_m = images[:, c, 3].float() * self.depth_max  # (B, H, W)
                at = seen_m[torch.arange(b, device=heat.device)[:, None], ri, ci]  # (B, 2)
                ok = (inside & (at > depth - VISIBLE_M)).float()
                gx = cells[None, None, :] - (col.clamp(0, w) * r / w)[..., None]  # (B, 2, R)
                gy = cells[None, None, :] - (row.clamp(0, h) * r / h)[..., None]
                want = torch.exp(
                    -(gy[..., :, None] ** 2 + gx[..., None, :] ** 2) / (2 * HEAT_SIGMA**2)
                )
                want = want / want.sum((-2, -1), keepdim=True)
                logp = F.log_softmax(heat[:, j].flatten(2), -1)  # (B, 2, R*R)
                ce = -(want.flatten(2) * logp).sum(-1)  # (B, 2)
                total = total + torch.where(ok > 0, ce, torch.zeros_like(ce)).sum()
                count = count + ok.sum()
            return total / count.clamp(min=1.0)

    return Perception()


def camera_stack(batch: dict[str, Any], cameras: list[str], depth: bool) -> Any:
    """The network's input (B, n_cams, C, H, W) from model inputs keyed like the dataset's
    features: ``observation.images.<cam>`` (B, [T,] 3, H, W) in [0, 1] and, with ``depth``,
    ``observation.depth.<cam>`` (three equal channels of depth over its range); the newest
    observation step where there are several."""
    torch = _torch()
    parts = []
    for cam in cameras:
        img = batch[f"observation.images.{cam}"]
        if img.ndim == 5:
            img = img[:, -1]
        chans = [img]
        if depth:
            d = batch[f"observation.depth.{cam}"]
            if d.ndim == 5:
                d = d[:, -1]
            chans.append(d[:, :1])
        parts.append(torch.cat(chans, 1))
    return torch.stack(parts, 1)


def add_noise(env: Any, sigma_m: float, generator: Any = None) -> Any:
    """The environment values ``env`` (B, [T,] 24) with each object's position moved by one
    Gaussian offset per sample (standard deviation ``sigma_m`` per axis, m; the same over the
    sample's observation steps), its tool offset with it: what the state policy trains on, so
    that it acts on a perception's errors."""
    torch = _torch()
    if sigma_m <= 0:
        return env
    out = env.clone()
    b = env.shape[0]
    for (a, z), (oa, oz) in zip(POSITIONS, OFFSETS, strict=True):
        delta = torch.randn((b, 3), generator=generator, device=env.device) * sigma_m
        if env.ndim == 3:
            delta = delta[:, None, :]
        out[..., a:z] += delta
        out[..., oa:oz] += delta
    return out


def save(net: Any, folder: Path) -> None:
    """Writes :data:`WEIGHTS` and :data:`SETTINGS` into ``folder`` (a ``pretrained_model``
    being written aside)."""
    from safetensors.torch import save_file

    plain = getattr(net, "_orig_mod", net)
    state = {k: v.detach().contiguous().cpu() for k, v in plain.state_dict().items()}
    save_file(state, str(folder / WEIGHTS))
    (folder / SETTINGS).write_text(json.dumps(plain.settings, indent=1))


def load(folder: Path, device: str) -> Any:
    """The network saved in ``folder``, on ``device``, in evaluation mode.

    Raises:
        PolicyError: the files are missing, of another schema version, or do not fit.
    """
    from safetensors.torch import load_file

    path = folder / SETTINGS
    if not path.is_file() or not (folder / WEIGHTS).is_file():
        raise PolicyError(
            f"{folder} is a train.vision=perception policy without its {WEIGHTS} and "
            f"{SETTINGS}: retrain it with stage=train force=true"
        )
    settings = json.loads(path.read_text())
    if settings.get("schema_version") not in READABLE_VERSIONS:
        raise PolicyError(
            f"{path}: schema_version {settings.get('schema_version')!r}, this factory reads "
            f"{' or '.join(map(str, READABLE_VERSIONS))}: retrain with stage=train force=true "
            "(or load it with the factory that trained it)"
        )
    net = build(settings)
    try:
        net.load_state_dict(load_file(str(folder / WEIGHTS)))
    except RuntimeError as e:
        raise PolicyError(f"{folder / WEIGHTS} does not fit {SETTINGS}: {e}") from None
    return net.to(device).eval()
