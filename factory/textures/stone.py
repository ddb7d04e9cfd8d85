"""Stone and masonry: marble, granite-like stone, concrete, tiles and brick.

Marble, stone, concrete and tiles are detail maps relative to the surface's colour; brick is
an absolute-colour image (its mortar is lighter than the brick, which a tint cannot show), so
its look is marked untinted.
"""

from __future__ import annotations

import numpy as np

from factory.textures.noise import cells, fbm, grid, mix, smoothstep, value_noise


def _gray(shade: np.ndarray) -> np.ndarray:
    return np.repeat(shade[..., None], 3, axis=2).astype(np.float32)


def marble(
    rng: np.random.Generator, size: int, veins: int = 2, strength: float = 0.4
) -> np.ndarray:
    """Marble: soft grey veins of varying width, with fine hair veins, through a clouded
    white ground."""
    x, y = grid(size)
    turb = fbm(rng, size, 2, octaves=6)
    k = int(rng.integers(1, 3))
    phase = (x * veins + y * k + turb * 0.9) * np.pi
    vein = np.abs(np.sin(phase)).astype(np.float32)
    width = 0.12 + 0.4 * fbm(rng, size, 3, octaves=3) ** 2
    main = (1.0 - smoothstep(0.0, 1.0, vein / width)) ** 2
    fine_turb = fbm(rng, size, 4, octaves=5)
    fine_phase = (x * (veins * 2) - y * 3 * k + fine_turb * 1.2) * np.pi
    fine = 1.0 - smoothstep(0.0, 0.04, np.abs(np.sin(fine_phase)))
    fine *= smoothstep(0.4, 0.7, fbm(rng, size, 3, octaves=3))
    cloud = fbm(rng, size, 3, octaves=5)
    shade = (1.03 + 0.07 * (cloud - 0.5)) * (1.0 - strength * main) * (1.0 - 0.35 * strength * fine)
    img = _gray(shade)
    img[..., 2] *= (1.0 + 0.06 * main).astype(np.float32)  # grey-blue veins
    img[..., 0] *= (1.0 - 0.02 * main).astype(np.float32)
    return img


def stone(rng: np.random.Generator, size: int, grains: int = 48) -> np.ndarray:
    """Granite-like stone: speckles of dark, light and warm crystals in a mottled ground."""
    _, _, ids = cells(rng, size, grains, jitter=1.0)
    n = grains * grains
    tone = rng.random(n).astype(np.float32)
    crystal = tone[ids]
    dark = (crystal < 0.18).astype(np.float32)
    light = (crystal > 0.88).astype(np.float32)
    ground = 0.95 + 0.12 * (fbm(rng, size, 4, octaves=4) - 0.5)
    shade = ground * (1.0 - 0.32 * dark + 0.12 * light) * (0.96 + 0.08 * crystal)
    img = _gray(shade)
    warm = (crystal > 0.6) & (crystal <= 0.85)
    img[warm] *= np.array([1.06, 0.98, 0.92], np.float32)
    return img


def concrete(rng: np.random.Generator, size: int) -> np.ndarray:
    """Concrete: trowel clouds, fine aggregate and small air pores."""
    clouds = fbm(rng, size, 2, octaves=6)
    grit = value_noise(rng, size, size // 2) - 0.5
    f1, _, _ = cells(rng, size, 24, jitter=1.0)
    pore = 1.0 - 0.5 * (1.0 - smoothstep(0.0, 0.07, f1))
    shade = (0.94 + 0.16 * (clouds - 0.5) + 0.06 * grit) * pore
    return _gray(shade)


def tiles(
    rng: np.random.Generator,
    size: int,
    count: int = 2,
    grout: float = 0.035,
    grout_shade: float = 0.55,
    surface: str = "ceramic",
) -> np.ndarray:
    """Square tiles: ``count`` x ``count`` tiles with grout lines ``grout`` (fraction of a tile)
    wide, each tile a slightly different tone; ``surface`` ``marble`` or ``stone`` puts that
    pattern inside the tiles (tiles are cut from different places of it)."""
    x, y = grid(size)
    u, v = x * count, y * count
    iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - iu, v - iv
    d = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))
    line = 1.0 - smoothstep(grout * 0.5, grout * 0.5 + 1.5 * count / size, d)
    tone = (1.0 + 0.05 * (2 * rng.random((count, count)) - 1)).astype(np.float32)
    body: np.ndarray
    if surface == "marble":
        body = marble(rng, size, veins=2, strength=0.35)
    elif surface == "stone":
        body = stone(rng, size, grains=64)
    else:
        glaze = fbm(rng, size, 4, octaves=3)
        body = _gray(1.0 + 0.04 * (glaze - 0.5))
    img = body * tone[iv % count, iu % count][..., None]
    return mix(img, (grout_shade, grout_shade, grout_shade), line)


def brick(rng: np.random.Generator, size: int, rows: int = 8, per_row: int = 3) -> np.ndarray:
    """Running-bond brick (absolute colours): ``rows`` courses, ``per_row`` bricks each,
    every other course shifted by half a brick, light mortar joints."""
    x, y = grid(size)
    v = y * rows
    row = np.floor(v).astype(np.int64)
    u = x * per_row + 0.5 * (row % 2)
    col = np.floor(u).astype(np.int64)
    fu, fv = u - col, v - row
    du = np.minimum(fu, 1 - fu) * size / per_row
    dv = np.minimum(fv, 1 - fv) * size / rows
    mortar = 1.0 - smoothstep(1.0, 2.2, np.minimum(du, dv))
    idx = (row % rows) * per_row + (col % per_row)
    n = rows * per_row
    hue = rng.random(n).astype(np.float32)[idx]
    base = np.stack([0.58 + 0.14 * hue, 0.28 + 0.06 * hue, 0.20 + 0.04 * hue], axis=-1)
    speck = fbm(rng, size, 16, octaves=3)
    img = base * (0.88 + 0.24 * speck)[..., None]
    burnt = smoothstep(0.7, 0.9, fbm(rng, size, 8, octaves=3))
    img = mix(img, (0.30, 0.16, 0.12), 0.5 * burnt)
    mortar_col = 0.72 + 0.06 * (value_noise(rng, size, 64) - 0.5)
    mortar_img = np.stack([mortar_col, mortar_col * 0.98, mortar_col * 0.93], axis=-1)
    return (img + (mortar_img - img) * mortar[..., None]).astype(np.float32)
