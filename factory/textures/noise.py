"""Tileable noise fields on a square texture (the building blocks of every texture family).

Every field here is periodic over the texture: pixel ``(row, col)`` of a ``size`` x ``size``
image is the point ``(x, y) = (col / size, row / size)`` of the unit torus, so a texture made
from these fields repeats without a seam. Lattice sizes (cells) are integers for that reason.
All randomness comes from the caller's ``numpy.random.Generator``, so a texture is a pure
function of its seed.
"""

from __future__ import annotations

import numpy as np

Field = np.ndarray
"""A float32 ``(size, size)`` array (values documented per function)."""


def grid(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-torus coordinates ``x`` (columns) and ``y`` (rows) of every pixel, each (size, size)."""
    t = np.arange(size, dtype=np.float32) / np.float32(size)
    return np.broadcast_to(t[None, :], (size, size)), np.broadcast_to(t[:, None], (size, size))


def _smooth(t: np.ndarray) -> np.ndarray:
    return t * t * (3.0 - 2.0 * t)


def _axis(size: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lattice indices (i0, i1) and smooth weights of ``size`` pixels over ``n`` cells."""
    f = np.arange(size, dtype=np.float32) * np.float32(n / size)
    i0 = np.floor(f).astype(np.intp)
    return i0 % n, (i0 + 1) % n, _smooth(f - i0)


def value_noise(rng: np.random.Generator, size: int, cells: int | tuple[int, int]) -> Field:
    """Smooth value noise in [0, 1] with ``cells`` lattice cells across the texture.

    Args:
        rng: the random stream.
        size: texture size (px).
        cells: lattice cells across the texture, or ``(across x, across y)`` for stretched
            (anisotropic) noise: ``(2, 64)`` gives streaks that run along x.
    """
    cx, cy = (cells, cells) if isinstance(cells, int) else cells
    cx, cy = max(1, int(cx)), max(1, int(cy))
    lattice = rng.random((cy, cx), dtype=np.float32)
    x0, x1, tx = _axis(size, cx)
    y0, y1, ty = _axis(size, cy)
    rows = lattice[:, x0] + (lattice[:, x1] - lattice[:, x0]) * tx[None, :]  # (cy, size)
    a = rows[y0]
    return (a + (rows[y1] - a) * ty[:, None]).astype(np.float32)


def fbm(
    rng: np.random.Generator,
    size: int,
    cells: int | tuple[int, int] = 4,
    octaves: int = 5,
    gain: float = 0.5,
) -> Field:
    """Fractal sum of value noise (octaves double the lattice), normalised to [0, 1]."""
    cx, cy = (cells, cells) if isinstance(cells, int) else cells
    total = np.zeros((size, size), np.float32)
    amp, norm = 1.0, 0.0
    for k in range(octaves):
        f = 2**k
        if min(cx, cy) * f > size:
            break
        total += np.float32(amp) * value_noise(rng, size, (cx * f, cy * f))
        norm += amp
        amp *= gain
    return normalise(total / np.float32(norm))


def normalise(f: np.ndarray) -> np.ndarray:
    """``f`` stretched linearly onto [0, 1] (a constant field becomes 0.5)."""
    lo, hi = float(f.min()), float(f.max())
    if hi - lo < 1e-9:
        return np.full_like(f, 0.5, dtype=np.float32)
    return ((f - lo) / (hi - lo)).astype(np.float32)


def cells(
    rng: np.random.Generator, size: int, n: int, jitter: float = 0.9
) -> tuple[Field, Field, np.ndarray]:
    """Tileable cellular (Worley) noise with ``n`` x ``n`` jittered feature points.

    Returns:
        ``f1`` and ``f2``: distances to the nearest and second-nearest feature point, in cell
        widths (``f2 - f1`` is small along cell borders: cracks, leather creases, grout);
        ``ids``: the index of the nearest cell per pixel (for per-cell colours).
    """
    pts = (0.5 + jitter * (rng.random((2, n, n), dtype=np.float32) - 0.5)).astype(np.float32)
    f = np.arange(size, dtype=np.float32) * np.float32(n / size)
    c = np.floor(f).astype(np.intp)
    frac = f - c  # position inside the cell, per column (x) and per row (y)
    big = np.float32(9.0)
    f1 = np.full((size, size), big, np.float32)
    f2 = np.full((size, size), big, np.float32)
    ids = np.zeros((size, size), np.intp)
    for dy in (-1, 0, 1):
        wy = (c + dy) % n
        for dx in (-1, 0, 1):
            wx = (c + dx) % n
            px = pts[0][wy][:, wx] + np.float32(dx) - frac[None, :]
            py = pts[1][wy][:, wx] + np.float32(dy) - frac[:, None]
            d = px * px + py * py
            closer = d < f1
            np.minimum(f2, np.where(closer, f1, d), out=f2)
            ids[closer] = (wy[:, None] * n + wx[None, :])[closer]
            np.minimum(f1, d, out=f1)
    return np.sqrt(f1), np.sqrt(f2), ids


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """0 below ``e0``, 1 above ``e1``, a smooth ramp between."""
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return (t * t * (3.0 - 2.0 * t)).astype(np.float32)


def luma(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of an (..., 3) image."""
    return (rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722).astype(np.float32)


def tint(shade: np.ndarray, rgb: tuple[float, float, float]) -> np.ndarray:
    """An (size, size, 3) image: a scalar ``shade`` field times a colour."""
    return shade[..., None] * np.asarray(rgb, np.float32)[None, None, :]


def mix(a: np.ndarray, b: np.ndarray | tuple[float, ...], t: np.ndarray) -> np.ndarray:
    """Per-pixel blend of images ``a`` and ``b`` (an image or a colour) by ``t`` (size, size)."""
    bb = np.asarray(b, np.float32)
    return (a + (bb - a) * t[..., None]).astype(np.float32)
