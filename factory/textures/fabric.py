"""Soft materials: woven fabric (plain weave, twill), velvet, leather, carpet, foam.

Detail maps relative to the material's colour (mean luminance about 1). The weave's threads
are finer than a camera pixel at room scale, so each image also carries the larger, visible
variation of real cloth: slubs, dye mottling and soft folds of shade.
"""

from __future__ import annotations

import numpy as np

from factory.textures.noise import cells, fbm, grid, smoothstep, value_noise


def _gray(shade: np.ndarray) -> np.ndarray:
    return np.repeat(shade[..., None], 3, axis=2).astype(np.float32)


def weave(
    rng: np.random.Generator, size: int, threads: int = 64, twill: bool = False
) -> np.ndarray:
    """Woven cloth: ``threads`` warp and weft threads across the texture.

    Plain weave alternates over/under every crossing; ``twill`` steps the pattern by one
    thread per row (diagonal ribs, as denim and upholstery twill).
    """
    x, y = grid(size)
    u, v = x * threads, y * threads
    iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - iu, v - iv
    over = ((iu + iv) % 2 == 0) if not twill else (((iu - iv) % 4) < 2)
    # a thread is brightest along its middle
    warp_shade = 0.80 + 0.20 * np.sin(np.pi * fu)
    weft_shade = 0.78 + 0.22 * np.sin(np.pi * fv)
    shade = np.where(over, warp_shade, weft_shade)
    thread_tone = 1.0 + 0.06 * (2 * rng.random(threads) - 1)
    shade = shade * np.where(over, thread_tone[iu % threads], thread_tone[iv % threads])
    slub = 1.0 + 0.06 * (value_noise(rng, size, (threads // 2, 4)) - 0.5)
    mottle = 1.0 + 0.10 * (fbm(rng, size, 3, octaves=4) - 0.5)
    return _gray(shade * slub * mottle)


def velvet(rng: np.random.Generator, size: int) -> np.ndarray:
    """Velvet: pile that catches light in soft patches (crushed sheen), fine fuzz."""
    sheen = fbm(rng, size, 3, octaves=4)
    crush = smoothstep(0.35, 0.75, fbm(rng, size, (5, 3), octaves=3))
    fuzz = value_noise(rng, size, size // 2) - 0.5
    shade = 0.80 + 0.30 * sheen + 0.12 * crush + 0.05 * fuzz
    img = _gray(shade)
    img[..., 2] *= 1.0 + 0.04 * (sheen - 0.5)  # the sheen is slightly cooler
    return img


def leather(rng: np.random.Generator, size: int, grain: int = 40) -> np.ndarray:
    """Leather: pebbled grain (cells with creases between them) and darker worn patches."""
    f1, f2, _ = cells(rng, size, grain)
    crease = 1.0 - smoothstep(0.0, 0.18, f2 - f1)
    pebble = 1.0 - 0.25 * f1
    patches = fbm(rng, size, 3, octaves=4)
    shade = (0.92 + 0.12 * pebble - 0.22 * crease) * (0.92 + 0.16 * patches)
    return _gray(shade)


def carpet(rng: np.random.Generator, size: int, loops: int = 96) -> np.ndarray:
    """Loop-pile carpet: dense tufts with random heights and a faint tracking pattern."""
    tufts = value_noise(rng, size, loops)
    f1, _, _ = cells(rng, size, loops // 3, jitter=1.0)
    tuft = 0.85 + 0.2 * tufts - 0.12 * f1
    tracks = fbm(rng, size, (2, 6), octaves=3)
    shade = tuft * (0.93 + 0.14 * tracks)
    return _gray(shade)


def foam(rng: np.random.Generator, size: int) -> np.ndarray:
    """Open-cell foam: many small pores."""
    f1, _, _ = cells(rng, size, 48, jitter=1.0)
    pores = 1.0 - 0.35 * (1.0 - smoothstep(0.05, 0.3, f1))
    return _gray(pores * (0.95 + 0.1 * fbm(rng, size, 4, octaves=3)))
