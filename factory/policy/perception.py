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
POSITIONS = ((0, 3), (9, 12))
"""Columns of the pick object's and the target's positions in the 24 environment values."""
OFFSETS = ((18, 21), (21, 24))
"""Columns of the tool's offsets to them (they move with the positions)."""


def _torch() -> Any:
    import torch

    return torch


def settings_of(
    cameras: list[str], depth: bool, image_size: tuple[int, int], target: np.ndarray
) -> dict[str, Any]:
    """The settings that rebuild a network: cameras (in order), depth channel, image size (H, W
    px) and the range of each target column over the training frames (``target``: (N, 24))."""
    return {
        "schema_version": SCHEMA_VERSION,
        "cameras": list(cameras),
        "depth": bool(depth),
        "image_size": [int(image_size[0]), int(image_size[1])],
        "keypoints": KEYPOINTS,
        "hidden": HIDDEN,
        "low": [float(x) for x in np.asarray(target).min(0)],
        "high": [float(x) for x in np.asarray(target).max(0)],
    }


def build(settings: dict[str, Any]) -> Any:
    """The network (a ``torch.nn.Module``, fresh weights) of these settings."""
    import torch
    import torch.nn.functional as F
    import torchvision

    nn = torch.nn

    class SpatialSoftmax(nn.Module):
        """Expected image position (x, y in [-1, 1]) of each of ``k`` learned keypoints."""

        def __init__(self, channels: int, k: int) -> None:
            super().__init__()
            self.proj = nn.Conv2d(channels, k, 1)

        def forward(self, x: Any) -> Any:
            b, _, h, w = x.shape
            logits = self.proj(x).flatten(2).float()  # (B, k, h*w)
            attn = F.softmax(logits, dim=-1)
            ys = torch.linspace(-1, 1, h, device=x.device)
            xs = torch.linspace(-1, 1, w, device=x.device)
            gy, gx = torch.meshgrid(ys, xs, indexing="ij")
            grid = torch.stack([gx.reshape(-1), gy.reshape(-1)], -1)  # (h*w, 2)
            return (attn @ grid).reshape(b, -1)  # (B, 2k)

    class Perception(nn.Module):
        """Camera images of one frame -> the 24 environment values (see the module)."""

        def __init__(self) -> None:
            super().__init__()
            self.settings = dict(settings)
            self.cameras = list(settings["cameras"])
            self.depth = bool(settings["depth"])
            chans = 4 if self.depth else 3
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
            self.mlp = nn.Sequential(
                nn.Linear(n * (2 * k + 256), hidden),
                nn.ReLU(),
                nn.Linear(hidden, hidden),
                nn.ReLU(),
                nn.Linear(hidden, dim),
            )
            low = torch.as_tensor(settings["low"], dtype=torch.float32)
            high = torch.as_tensor(settings["high"], dtype=torch.float32)
            self.register_buffer("low", low)
            self.register_buffer("span", torch.clamp(high - low, min=1e-6))

        def forward(self, images: Any) -> Any:
            """Predictions scaled to [-1, 1] (B, 24) from ``images`` (B, n_cams, C, H, W),
            values in [0, 1] (the module's call: what ``torch.compile`` compiles)."""
            b = images.shape[0]
            x = (images.flatten(0, 1) - 0.5) / 0.25
            x = x.contiguous(memory_format=torch.channels_last)
            fmap = self.trunk(x)  # (B*n, 256, h, w)
            feats = torch.cat([self.keypoints(fmap), fmap.float().mean(dim=(-2, -1))], -1)
            return self.mlp(feats.reshape(b, -1))

        def predict(self, images: Any) -> Any:
            """The 24 environment values (B, 24), in the dataset's units (m, rotations)."""
            return (self(images).float() + 1) * 0.5 * self.span + self.low

        def loss(self, images: Any, target: Any) -> tuple[Any, Any]:
            """Mean squared error in the [-1, 1] scale against ``target`` (B, 24, dataset
            units), and the root-mean-square error of the two objects' positions (m), detached.
            """
            want = 2 * (target.float() - self.low) / self.span - 1
            got = self(images).float()
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
