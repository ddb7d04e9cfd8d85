"""Training batches gathered where the model trains (``train.loader=device``).

The DataLoader path (:class:`factory.policy.train.TrainSet`) builds every sample in Python,
one frame window at a time, and collates them: on a GPU the model then waits for the CPU. Here
the converted low-dimensional features of every frame (:class:`~factory.policy.train.LowDimFrames`:
model state, environment state, model actions) and the decoded camera frames (uint8 RGB, uint16
depth in millimetres) are put once into device memory, or, where the frames do not fit, into
pinned host memory from which each batch's frames are copied asynchronously (the decision is
logged); a batch is then a handful of tensor gathers by index: observation and action windows
clamped to their episode, the ``*_is_pad`` masks, the actions made relative to the window's
frame (``tool_rel``, the mobile base), RGB scaled to [0, 1] and depth to metres over
``depth_max_m`` on three channels, as the DataLoader path gives them (``tests/policy``
compares both). Image augmentation (``train.augment_images``) is done on the batch: a random
shift of up to :data:`SHIFT` of the image (border pixels repeated) and brightness and contrast
factors in ``1 +- JITTER``, drawn per sample and camera, the same over a sample's observation
steps; a camera's depth image gets its RGB image's shift (no colour change), so that each depth
pixel stays under its colour (the DataLoader path uses lerobot's ``ImageTransforms`` per sample
instead, without its affine transform when depth is read).

Samples are drawn without replacement, epoch after epoch, from the frames the sampler allows
(lerobot's ``EpisodeAwareSampler``: the episodes trained on, without the frames the policy
drops at episode ends), with a generator seeded by ``train.seed``; every batch is full (an
epoch's last samples are topped up from the next epoch's order), so that a compiled model
sees one shape.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import Any

import numpy as np

from factory.errors import PolicyError
from factory.policy.inputs import (
    ACTION,
    BASE_DIM,
    DEPTH_PREFIX,
    STATE,
    TOOL_POS,
    depth_image,
)
from factory.policy.shading import shade

log = logging.getLogger(__name__)

LOADERS = ("auto", "device", "dataloader")
"""``train.loader`` settings: ``device`` (this module), ``dataloader`` (torch's DataLoader over
the converted dataset), ``auto`` (``device`` on CUDA when the frames are in memory)."""
DEVICE_SHARE = 0.5
"""The frames go to device memory when they take less than this share of its free memory."""
SHIFT = 0.06
"""Largest random shift of an augmented image, as a share of its size (about 8 px at 128)."""
JITTER = 0.2
"""Brightness and contrast factors of an augmented image are drawn from ``1 +- JITTER``."""


def resolve_loader(setting: str, device: str, frames_in_memory: bool) -> str:
    """``device`` or ``dataloader`` for ``train.loader`` on ``device``.

    Raises:
        PolicyError: ``device`` asked for while the videos are decoded per sample.
    """
    if setting not in LOADERS:
        raise PolicyError(f"train.loader must be one of {', '.join(LOADERS)}, got {setting!r}")
    if setting == "auto":
        return "device" if device.startswith("cuda") and frames_in_memory else "dataloader"
    if setting == "device" and not frames_in_memory:
        raise PolicyError(
            "train.loader=device needs the camera frames in memory: set train.video_cache=memory "
            "(or free memory for train.video_cache=auto), or use train.loader=dataloader"
        )
    return setting


def frames_place(frame_bytes: int, device: str) -> str:
    """Where the decoded frames live: ``device`` memory, ``pinned`` host memory (CUDA, frames
    over :data:`DEVICE_SHARE` of the free device memory) or ``host`` (a CPU device)."""
    import torch

    if not device.startswith("cuda"):
        return "host"
    free, _ = torch.cuda.mem_get_info(torch.device(device))
    return "device" if frame_bytes < DEVICE_SHARE * free else "pinned"


def base_relative_t(target: Any, now: Any) -> Any:
    """:func:`factory.policy.inputs.base_relative` on tensors: (B, H, 3) world base targets
    relative to the base poses ``now`` (B, 3), in float64 as the numpy version computes."""
    import torch

    target = target.to(torch.float64)
    now = now.to(torch.float64)[:, None, :]
    c, s = torch.cos(now[..., 2]), torch.sin(now[..., 2])
    dx, dy = target[..., 0] - now[..., 0], target[..., 1] - now[..., 1]
    out = torch.stack([c * dx + s * dy, -s * dx + c * dy, target[..., 2] - now[..., 2]], -1)
    return out.to(torch.float32)


class DeviceBatches:
    """Endless training batches gathered on ``device`` (see the module docstring).

    Args:
        frames: the converted features and decoded frames of every dataset frame (a
            :class:`factory.policy.train.LowDimFrames`, which imports this module).
        device: the torch device the model trains on (``cpu``, ``cuda``, ``cuda:1``).
        batch_size: samples per batch.
        indices: the frames samples are drawn from (the sampler's); None: every frame.
        seed: seed of the sample order and of the augmentation.
        augment: augment the images (colour: RGB only; the shift: a camera's RGB and depth
            alike).
        shift: with ``augment``, shift the images too (off where a camera's pixels become
            points through its calibration: a shifted pixel's ray no longer meets what it
            shows).
        shading: strength of the shading augmentation of the RGB images
            (``train.augment_shading``, :func:`factory.policy.shading.shade`; 0: off), drawn
            whether or not ``augment`` is on.
    """

    def __init__(
        self,
        frames: Any,
        device: str,
        batch_size: int,
        indices: np.ndarray | None = None,
        seed: int = 0,
        augment: bool = False,
        shift: bool = True,
        shading: float = 0.0,
    ) -> None:
        import torch

        self.spec = frames.spec
        self.device = torch.device(device)
        self.batch_size = batch_size
        self.augment = augment
        self.shift = augment and shift
        self.shading = shading

        def put(a: np.ndarray) -> Any:
            return torch.from_numpy(np.ascontiguousarray(a)).to(self.device)

        self.values = {k: put(v) for k, v in frames.values.items()}
        ep = frames.episode
        self.start = put(np.array([frames.start[int(e)] for e in ep], np.int64))
        self.end = put(np.array([frames.end[int(e)] for e in ep], np.int64))
        self.delta = {k: put(np.asarray(d, np.int64)) for k, d in frames.delta.items()}
        self.base_pose = None if frames.base_pose is None else put(frames.base_pose)
        self.raw_keys = list(frames.raw_keys)
        nbytes = sum(v.nbytes for v in frames.videos.values())
        self.place = frames_place(nbytes, str(self.device))
        self.videos: dict[str, Any] = {}
        for key, arr in frames.videos.items():
            if key.startswith(DEPTH_PREFIX):  # uint16 mm -> int16, clipped to the range read
                top = int(self.spec.depth_max_m * 1000) + 1
                arr = np.minimum(arr, top).astype(np.int16)
            t = torch.from_numpy(np.ascontiguousarray(arr))
            self.videos[key] = t.to(self.device) if self.place == "device" else t
            if self.place == "pinned":
                self.videos[key] = t.pin_memory()
        if frames.videos:
            log.info(
                "train: %d camera streams (%.2f GB) in %s memory; batches gathered on %s",
                len(frames.videos),
                nbytes / 1e9,
                {"device": str(self.device), "pinned": "pinned host", "host": "host"}[self.place],
                self.device,
            )
        pool = np.arange(len(frames)) if indices is None else np.asarray(indices, np.int64)
        if pool.size == 0:
            raise PolicyError("no frames to train on (the sampler allows none)")
        self.pool = put(pool)
        self.gen = torch.Generator(device=self.device).manual_seed(seed)
        self._order: Any = None
        self._pos = 0

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return self

    def __next__(self) -> dict[str, Any]:
        """The next batch: the next ``batch_size`` frames of the epochs' orders. Every batch
        has ``batch_size`` samples: an epoch's last frames are topped up with the first of the
        next epoch's order (unlike the DataLoader, whose last batch is smaller). A compiled
        model is built for one batch shape: a smaller batch at each epoch's end made
        ``torch.compile`` build it again, for dynamic shapes (about 100 s at the first epoch's
        end on one H200)."""
        return self.gather(self._take(self.batch_size))

    def _take(self, n: int) -> Any:
        """The next ``n`` frame indices of the epochs' orders ((n,) int64 on the device); a new
        order (a permutation of the pool) starts where the last one ends."""
        import torch

        parts = []
        while n > 0:
            if self._order is None or self._pos >= len(self._order):
                perm = torch.randperm(len(self.pool), generator=self.gen, device=self.device)
                self._order = self.pool[perm]
                self._pos = 0
            part = self._order[self._pos : self._pos + n]
            self._pos += len(part)
            n -= len(part)
            parts.append(part)
        return parts[0] if len(parts) == 1 else torch.cat(parts)

    def _window(self, idx: Any, key: str, start: Any, end: Any) -> Any | None:
        """Frame indices (B, T) of ``key``'s window around each sample, clamped to the sample's
        episode (``start``, ``end``: (B, 1) its first and past-the-last frame); None: the key
        has no window (one frame)."""
        import torch

        delta = self.delta.get(key)
        if delta is None:
            return None
        q = idx[:, None] + delta[None, :]
        return torch.minimum(torch.maximum(q, start), end - 1)

    def gather(self, idx: Any) -> dict[str, Any]:
        """The batch of the samples at dataset frames ``idx`` ((B,) int64 on the device):
        what stacking :meth:`LowDimFrames.item` of each gives, on the device."""
        import torch

        idx = idx.to(self.device)
        start, end = self.start[idx][:, None], self.end[idx][:, None]
        out: dict[str, Any] = {}
        for key, values in self.values.items():
            at = self._window(idx, key, start, end)
            out[key] = values[idx if at is None else at]
        if self.spec.action == "tool_rel" or self.spec.mobile:
            act = out[ACTION].clone()
            if self.spec.action == "tool_rel":
                act[..., :3] -= self.values[STATE][idx][:, None, TOOL_POS]
            if self.spec.mobile:
                assert self.base_pose is not None
                act[..., -BASE_DIM:] = base_relative_t(act[..., -BASE_DIM:], self.base_pose[idx])
            out[ACTION] = act
        shifts: dict[str, Any] = {}  # camera -> (B, 2): its RGB and depth move together
        for key, frames in self.videos.items():
            at = self._window(idx, key, start, end)
            where = (idx if at is None else at).to(frames.device)
            pix = frames[where].to(self.device, non_blocking=True)
            if key.startswith(DEPTH_PREFIX):
                out[key] = depth_image(pix.to(torch.int32), self.spec.depth_max_m)
            else:
                out[key] = pix.movedim(-1, -3).to(torch.float32) / 255.0
                if self.augment:
                    out[key] = self._jitter(out[key])
                if self.shading > 0:
                    out[key] = shade(out[key], self.shading, self.gen)
            if self.shift:
                cam = key.rsplit(".", 1)[-1]
                if cam not in shifts:
                    shifts[cam] = (
                        torch.rand((len(idx), 2), generator=self.gen, device=self.device) * 2 - 1
                    ) * (2 * SHIFT)
                out[key] = _shift(out[key], shifts[cam])
        for key in [*self.raw_keys, ACTION]:
            delta = self.delta.get(key)
            if delta is not None:
                q = idx[:, None] + delta[None, :]
                out[f"{key}_is_pad"] = (q < start) | (q >= end)
        return out

    def _jitter(self, img: Any) -> Any:
        """Random brightness and contrast of RGB images (B, [T,] 3, H, W) in [0, 1], drawn per
        sample and the same over its observation steps."""
        import torch

        shape = img.shape
        b = shape[0]
        t = img.reshape(b, -1, *shape[-3:]).shape[1]
        x = img.reshape(b * t, *shape[-3:])
        rand = torch.rand((b, 2), generator=self.gen, device=self.device)
        bright = (1 + (rand[:, 0] * 2 - 1) * JITTER).repeat_interleave(t)[:, None, None, None]
        contrast = (1 + (rand[:, 1] * 2 - 1) * JITTER).repeat_interleave(t)[:, None, None, None]
        mean = x.mean(dim=(-3, -2, -1), keepdim=True)
        x = ((x * bright - mean * bright) * contrast + mean * bright).clamp(0.0, 1.0)
        return x.reshape(shape)


def _shift(img: Any, shift: Any) -> Any:
    """Images (B, [T,] C, H, W) moved by ``shift`` ((B, 2), x and y as shares of twice the
    size: ``affine_grid``'s [-1, 1] span), the same over a sample's observation steps; the
    uncovered border repeats the edge pixels. A camera's RGB and depth get the same shift, so
    that a depth pixel stays under its colour (the perception's points read both)."""
    import torch
    import torch.nn.functional as F

    shape = img.shape
    b = shape[0]
    t = img.reshape(b, -1, *shape[-3:]).shape[1]
    theta = torch.zeros((b, 2, 3), device=img.device, dtype=img.dtype)
    theta[:, 0, 0] = theta[:, 1, 1] = 1.0
    theta[:, :, 2] = shift.to(img.dtype)
    theta = theta.repeat_interleave(t, 0)
    x = img.reshape(b * t, *shape[-3:])
    grid = F.affine_grid(theta, list(x.shape), align_corners=False)
    x = F.grid_sample(x, grid, mode="nearest", padding_mode="border", align_corners=False)
    return x.reshape(shape)
