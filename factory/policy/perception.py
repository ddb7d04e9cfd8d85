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

At evaluation the env gives the policy images and the robot state only (no recorded poses):
:class:`factory.policy.checkpoint.LoadedPolicy` fills ``observation.environment_state`` with
this network's prediction. The network's weights and settings are saved beside lerobot's
``pretrained_model`` files (:data:`WEIGHTS`, :data:`SETTINGS`); the policy alone is a plain
lerobot state policy.

Architecture: a ResNet-18 trunk (torchvision, GroupNorm, up to ``layer3``: stride 16, an 8 x 8
map at 128 px, finer than lerobot's 3 x 3 at 84 px) shared by the cameras, with a first
convolution of 3 (RGB) or 4 (RGB + depth) channels; a spatial softmax per camera
(:data:`KEYPOINTS` expected image positions) and the map's mean features; an MLP over every
camera's to the 24 values scaled to [-1, 1] by their range over the training frames.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import PolicyError

SCHEMA_VERSION = 1
WEIGHTS = "perception.safetensors"
"""The network's weights in a ``pretrained_model`` folder."""
SETTINGS = "perception.json"
"""Its settings (cameras, channels, image size, target range) beside them."""
KEYPOINTS = 32
"""Spatial-softmax keypoints per camera."""
HIDDEN = 512
"""Width of the MLP's hidden layers."""
XYZ_CAMERA = "wrist"
"""The camera whose pose the robot knows at every frame (it rides on the hand: forward
kinematics of the joints): its pixels' points in the base frame are inputs, and each keypoint
reads the point it attends to. The left and right cameras are placed per scene and their pose
is not observed."""
CAMERA_POSE = "aux.camera_pose"
"""Batch key of the :data:`XYZ_CAMERA`'s pose of each sample's frame (B, 12) (popped before
lerobot's processors)."""
READOUT = 32
"""Side (px) of the grid at which keypoints read the :data:`XYZ_CAMERA`'s points."""
POSITIONS = ((0, 3), (9, 12))
"""Columns of the pick object's and the target's positions in the 24 environment values."""
OFFSETS = ((18, 21), (21, 24))
"""Columns of the tool's offsets to them (they move with the positions)."""


def _torch() -> Any:
    import torch

    return torch


def settings_of(
    cameras: list[str],
    depth: bool,
    image_size: tuple[int, int],
    target: np.ndarray,
    depth_max_m: float = 2.0,
    xyz_fovy_deg: float = 0.0,
) -> dict[str, Any]:
    """The settings that rebuild a network: cameras (in order), depth channel, image size (H, W
    px), the range of each target column over the training frames (``target``: (N, 24)), the
    depth range (m) and, with depth and the :data:`XYZ_CAMERA` among the cameras, that
    camera's vertical field of view (deg; ``xyz_fovy_deg`` > 0) for the points behind its
    pixels."""
    xyz = bool(depth) and XYZ_CAMERA in cameras and xyz_fovy_deg > 0
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
        "xyz_camera": XYZ_CAMERA if xyz else "",
        "xyz_fovy_deg": float(xyz_fovy_deg) if xyz else 0.0,
    }


def wrist_poses(joints: np.ndarray) -> np.ndarray:
    """The :data:`XYZ_CAMERA`'s pose (N, 12) for arm joints (N, 7) (rad): forward kinematics
    (:meth:`factory.policy.inputs.kinematics`), base frame, as :func:`pixel_points` takes it."""
    from factory.policy.inputs import kinematics

    return kinematics().camera_poses(np.asarray(joints, np.float64)[:, :7], XYZ_CAMERA)


def pixel_points(depth_m: Any, pose: Any, fovy_deg: float) -> Any:
    """The point behind every pixel of a camera, in the robot's base frame (m).

    Args:
        depth_m: (B, H, W) depth along the camera's optical axis (m), row 0 at the top.
        pose: (B, 12) the camera's position, then its rotation's rows (MuJoCo's
            ``cam_xmat``: columns x right, y up, -z the viewing direction), base frame.
        fovy_deg: the camera's vertical field of view (deg).

    Returns:
        (B, 3, H, W) x, y, z of each pixel's point.
    """
    torch = _torch()
    b, h, w = depth_m.shape
    f = (h / 2) / float(np.tan(np.radians(fovy_deg) / 2))
    dev = depth_m.device
    u = (torch.arange(w, device=dev, dtype=torch.float32) + 0.5 - w / 2) / f
    v = -(torch.arange(h, device=dev, dtype=torch.float32) + 0.5 - h / 2) / f
    d = depth_m.float()
    cam = torch.stack([d * u[None, None, :], d * v[None, :, None], -d], 1)  # (B, 3, H, W)
    rot = pose[:, 3:].float().reshape(b, 3, 3)
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
            xyz_cam = str(settings.get("xyz_camera", ""))
            self.xyz_index = self.cameras.index(xyz_cam) if xyz_cam else -1
            self.xyz_fovy = float(settings.get("xyz_fovy_deg", 0.0))
            self.depth_max = float(settings.get("depth_max_m", 2.0))
            chans = (4 if self.depth else 3) + (3 if self.xyz_index >= 0 else 0)
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
            width = n * (2 * k + 256) + (3 * k if self.xyz_index >= 0 else 0)
            self.mlp = nn.Sequential(
                nn.Linear(width, hidden),
                nn.ReLU(),
                nn.Linear(hidden, hidden),
                nn.ReLU(),
                nn.Linear(hidden, dim),
            )
            low = torch.as_tensor(settings["low"], dtype=torch.float32)
            high = torch.as_tensor(settings["high"], dtype=torch.float32)
            self.register_buffer("low", low)
            self.register_buffer("span", torch.clamp(high - low, min=1e-6))

        @property
        def xyz(self) -> bool:
            """Whether the network reads the :data:`XYZ_CAMERA`'s points (needs its pose)."""
            return self.xyz_index >= 0

        def forward(self, images: Any, pose: Any = None) -> Any:
            """Predictions scaled to [-1, 1] (B, 24) from ``images`` (B, n_cams, C, H, W),
            values in [0, 1], and (:attr:`xyz`) the :data:`XYZ_CAMERA`'s pose (B, 12) (the
            module's call: what ``torch.compile`` compiles)."""
            b, n = images.shape[:2]
            x = (images - 0.5) / 0.25
            points = None
            if self.xyz:
                if pose is None:
                    raise PolicyError(
                        f"the perception network reads the {XYZ_CAMERA} camera's points: give "
                        "its pose (forward kinematics of the joints)"
                    )
                depth_m = images[:, self.xyz_index, 3] * self.depth_max
                points = pixel_points(depth_m, pose, self.xyz_fovy)  # (B, 3, H, W)
                extra = torch.zeros_like(x[:, :, :3])
                extra[:, self.xyz_index] = points / 0.5
                x = torch.cat([x, extra], 2)
            x = x.flatten(0, 1).contiguous(memory_format=torch.channels_last)
            fmap = self.trunk(x)  # (B*n, 256, h, w)
            logits, coords = self.keypoints(fmap)
            parts = [coords, fmap.float().mean(dim=(-2, -1))]
            feats = torch.cat(parts, -1).reshape(b, -1)
            if points is not None:  # each keypoint's point, read at READOUT px
                h, w = logits.shape[-2:]
                mine = logits.reshape(b, n, -1, h, w)[:, self.xyz_index]
                up = F.interpolate(mine, size=(READOUT, READOUT), mode="bilinear")
                pts = expected(up, F.adaptive_avg_pool2d(points, READOUT))  # (B, k, 3)
                feats = torch.cat([feats, pts.reshape(b, -1)], -1)
            return self.mlp(feats)

        def predict(self, images: Any, pose: Any = None) -> Any:
            """The 24 environment values (B, 24), in the dataset's units (m, rotations)."""
            return (self(images, pose).float() + 1) * 0.5 * self.span + self.low

        def loss(self, images: Any, target: Any, pose: Any = None) -> tuple[Any, Any]:
            """Mean squared error in the [-1, 1] scale against ``target`` (B, 24, dataset
            units), and the root-mean-square error of the two objects' positions (m), detached.
            """
            want = 2 * (target.float() - self.low) / self.span - 1
            got = self(images, pose).float()
            mse = F.mse_loss(got, want)
            with torch.no_grad():
                err = (got - want) * 0.5 * self.span
                pos = torch.cat([err[:, a:b] for a, b in POSITIONS], -1)
                rms = pos.square().sum(-1).div(len(POSITIONS)).mean().sqrt()
            return mse, rms

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
    if settings.get("schema_version") != SCHEMA_VERSION:
        raise PolicyError(
            f"{path}: schema_version {settings.get('schema_version')!r}, this factory reads "
            f"{SCHEMA_VERSION}: retrain with stage=train force=true"
        )
    net = build(settings)
    try:
        net.load_state_dict(load_file(str(folder / WEIGHTS)))
    except RuntimeError as e:
        raise PolicyError(f"{folder / WEIGHTS} does not fit {SETTINGS}: {e}") from None
    return net.to(device).eval()
