"""Shading augmentation of RGB training images (``train.augment_shading``): what the factory's
two renderers disagree on, drawn at random so that a policy does not learn one renderer's light.

The CPU executor and the CPU env draw with MuJoCo's OpenGL renderer, the GPU executor and the
Warp env with MuJoCo Warp's ray tracer. With the same scene, state, cameras, lights and near
plane their images still differ by 7-11 (of 255) in mean absolute RGB, Warp's about 7 brighter
(``scripts/bench_env_images.py``; docs/POLICY.md): the ceiling spot lights fall off differently
towards the edges of their cones (each light alone 1-5 apart), and glossy objects (mugs and
bowls, specular 0.7) carry brighter highlights on Warp (22-26 apart on their pixels). A global
brightness and contrast jitter (``train.augment_images``) does not cover a difference that
varies across the image and between objects. This augmentation multiplies each image by

* a smooth gain field: :data:`GRID` x :data:`GRID` factors drawn from ``1 +- strength``,
  upsampled bilinearly to the image (light that falls off differently across it), and
* a gain per colour channel drawn from ``1 +- strength / 4`` (the lights' warmth),

plus, with probability :data:`HIGHLIGHT_P` per image, one soft highlight (a Gaussian of
:data:`HIGHLIGHT_SIGMA` of the image's size, adding up to ``strength`` of white) where the
renderers' specular terms differ. The draws are per sample and the same over its observation
steps (one camera's frames of one moment look alike); each camera of a sample draws its own.
Depth images are never touched.

Measured since (docs/POLICY.md, "Results measured", 2026-11-30): the renderers' difference is
mostly OpenGL's per-vertex lighting of coarse meshes against Warp's per-hit lighting, and these
draws at 0.15 move a trained perception's readings far less than the switch of renderer does
(0.27 against 2.4 cm): the option stays, not yet shown to close that gap.
"""

from __future__ import annotations

from typing import Any

__all__ = ["GRID", "HIGHLIGHT_P", "HIGHLIGHT_SIGMA", "MAX_STRENGTH", "SampleShading", "shade"]

GRID = 3
"""Gain factors per side of the smooth field (3 x 3 over the image)."""
HIGHLIGHT_P = 0.5
"""Probability that an image gets a soft highlight."""
HIGHLIGHT_SIGMA = 0.08
"""A highlight's Gaussian width, as a share of the image's size."""
MAX_STRENGTH = 0.5
"""The largest ``train.augment_shading`` accepted."""


def shade(img: Any, strength: float, generator: Any = None) -> Any:
    """``img`` with random shading (module docstring).

    Args:
        img: RGB images in [0, 1], (B, [T,] 3, H, W) float (a torch tensor on any device).
        strength: the largest relative change of the field (0: ``img`` unchanged).
        generator: torch generator on ``img``'s device (None: torch's default).

    Returns:
        the shaded images, same shape and dtype, clamped to [0, 1].
    """
    import torch
    import torch.nn.functional as F

    if strength <= 0:
        return img
    shape = img.shape
    b = shape[0]
    h, w = shape[-2], shape[-1]
    t = img.reshape(b, -1, *shape[-3:]).shape[1]
    dev, dt = img.device, img.dtype

    def rand(*size: int) -> Any:
        return torch.rand(size, generator=generator, device=dev, dtype=torch.float32)

    grid = 1 + (rand(b, 1, GRID, GRID) * 2 - 1) * strength
    field = F.interpolate(grid, size=(h, w), mode="bilinear", align_corners=True)  # (B,1,H,W)
    channel = 1 + (rand(b, 3, 1, 1) * 2 - 1) * (strength / 4)
    gain = field * channel  # (B, 3, H, W)
    centre = rand(b, 2)
    on = (rand(b) < HIGHLIGHT_P).float() * rand(b) * strength
    ys = (torch.arange(h, device=dev, dtype=torch.float32) + 0.5) / h
    xs = (torch.arange(w, device=dev, dtype=torch.float32) + 0.5) / w
    d2 = (ys[None, :, None] - centre[:, 0, None, None]) ** 2 + (
        xs[None, None, :] - centre[:, 1, None, None]
    ) ** 2
    glow = on[:, None, None] * torch.exp(-d2 / (2 * HIGHLIGHT_SIGMA**2))  # (B, H, W)
    x = img.reshape(b, t, *shape[-3:]).float()
    x = x * gain[:, None] + glow[:, None, None]
    return x.clamp(0.0, 1.0).to(dt).reshape(shape)


class SampleShading:
    """One sample's RGB transform for torch's DataLoader path: ``then`` (lerobot's image
    transforms, or None) and the shading of :func:`shade` at ``strength``, on a sample's
    (T, 3, H, W) or (3, H, W) images."""

    def __init__(self, strength: float, then: Any = None) -> None:
        self.strength = strength
        self.then = then

    def __call__(self, img: Any) -> Any:
        if self.then is not None:
            img = self.then(img)
        return shade(img[None], self.strength)[0]
