"""Wood: grain of several species and plank floors (hardwood, laminate, parquet).

Images are detail maps relative to the wood's colour (1.0 = the colour given to the part or
floor, mean luminance about 1): rings and fibres run along the texture's v axis (rows), which
the UV mappings lay along the longer side of a face, so grain follows a board or a leg.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from factory.textures.noise import fbm, grid, smoothstep, value_noise


@dataclass(frozen=True)
class Species:
    """How a wood species looks.

    Attributes:
        rings: growth rings across the texture (along u).
        contrast: darkening of late wood (0..1).
        late: colour factor of late wood (per channel; < 1 darkens and saturates).
        pores: density of dark pore streaks (0: none; oak and walnut have them).
        figure: strength of the ring warp (wavy figure).
    """

    rings: int
    contrast: float
    late: tuple[float, float, float]
    pores: float
    figure: float


SPECIES: dict[str, Species] = {
    "oak": Species(14, 0.30, (0.78, 0.70, 0.60), 0.55, 0.10),
    "walnut": Species(10, 0.38, (0.70, 0.62, 0.58), 0.35, 0.16),
    "pine": Species(7, 0.42, (0.80, 0.66, 0.50), 0.0, 0.07),
    "maple": Species(18, 0.16, (0.88, 0.82, 0.76), 0.05, 0.05),
    "generic": Species(11, 0.30, (0.78, 0.70, 0.62), 0.2, 0.10),
    "mdf": Species(1, 0.0, (1.0, 1.0, 1.0), 0.0, 0.0),
}
"""Species name -> its look."""


def _grain(rng: np.random.Generator, size: int, sp: Species) -> np.ndarray:
    """A (size, size, 3) board of straight grain, rings along v."""
    x, _ = grid(size)
    warp = fbm(rng, size, (2, 1), octaves=4) - 0.5
    phase = x * sp.rings + warp * (sp.figure * sp.rings * 2.0)
    ring = phase - np.floor(phase)
    # early wood (light) ramps into late wood (dark), then a sharp boundary
    late = smoothstep(0.55, 0.95, ring) * sp.contrast
    fibres = value_noise(rng, size, (max(8, size // 3), 6)) - 0.5
    streak = fbm(rng, size, (16, 2), octaves=3) - 0.5
    shade = 1.0 + 0.10 * fibres + 0.10 * streak
    img = np.empty((size, size, 3), np.float32)
    for c in range(3):
        img[..., c] = shade * (1.0 - late * (1.0 - sp.late[c]) * 1.6)
    if sp.pores > 0:
        pore = value_noise(rng, size, (size // 2, size // 16))
        dark = smoothstep(1.0 - 0.12 * sp.pores, 1.0, pore) * 0.35
        img *= (1.0 - dark)[..., None]
    return img


def wood(rng: np.random.Generator, size: int, species: str = "generic") -> np.ndarray:
    """Solid wood (furniture boards, legs); ``species`` is a key of :data:`SPECIES`.

    ``mdf`` is painted board: an even surface with a faint roller texture.
    """
    sp = SPECIES.get(species, SPECIES["generic"])
    if species == "mdf":
        f = fbm(rng, size, 6, octaves=4)
        stipple = value_noise(rng, size, size // 3) - 0.5
        return np.repeat((0.95 + 0.10 * f + 0.04 * stipple)[..., None], 3, axis=2)
    return _grain(rng, size, sp)


def planks(
    rng: np.random.Generator,
    size: int,
    species: str = "oak",
    rows: int = 6,
    per_row: int = 2,
    gap: float = 0.45,
    tone: float = 0.10,
) -> np.ndarray:
    """A plank floor: ``rows`` planks across the texture (along u), ``per_row`` boards along
    v with staggered joints, each board cut from its own place in the grain with its own tone.

    Args:
        species: key of :data:`SPECIES`.
        rows: planks across the texture.
        per_row: boards along each plank row.
        gap: darkening of the joints (0..1).
        tone: per-board brightness spread (fraction).
    """
    sp = SPECIES.get(species, SPECIES["oak"])
    board = _grain(rng, size, sp)
    x, y = grid(size)
    col = np.floor(x * rows).astype(np.int64)
    offsets = rng.random(rows)
    yy = (y + offsets[col]) % 1.0
    seg = np.floor(yy * per_row).astype(np.int64)
    idx = col * per_row + seg
    n = rows * per_row
    shift_r = rng.integers(0, size, n)
    shift_c = rng.integers(0, size, n)
    tones = 1.0 + tone * (rng.random(n) * 2 - 1)
    r = np.arange(size)[:, None]
    c = np.arange(size)[None, :]
    rr = (r + shift_r[idx]) % size
    cc = (c + shift_c[idx]) % size
    img = board[rr, cc] * tones[idx][..., None].astype(np.float32)
    # joints: long edges between rows, short edges between boards (distance in px)
    fx = x * rows - col
    fy = yy * per_row - seg
    edge = np.minimum(
        np.minimum(fx, 1 - fx) * (size / rows), np.minimum(fy, 1 - fy) * (size / per_row)
    )
    joint = 1.0 - gap * (1.0 - smoothstep(0.4, 1.4, edge))
    return (img * joint[..., None]).astype(np.float32)


def parquet(
    rng: np.random.Generator, size: int, species: str = "oak", blocks: int = 4
) -> np.ndarray:
    """Basket-weave parquet: ``blocks`` x ``blocks`` squares of three slats, the grain turning
    by 90 degrees from one square to the next."""
    sp = SPECIES.get(species, SPECIES["oak"])
    board = _grain(rng, size, sp)
    turned = np.ascontiguousarray(np.transpose(_grain(rng, size, sp), (1, 0, 2)))
    x, y = grid(size)
    bx = np.floor(x * blocks).astype(np.int64)
    by = np.floor(y * blocks).astype(np.int64)
    flip = (bx + by) % 2 == 1
    img = np.where(flip[..., None], turned, board)
    slat_u = (x * blocks * 3) % 1.0
    slat_v = (y * blocks * 3) % 1.0
    block_u = (x * blocks) % 1.0
    block_v = (y * blocks) % 1.0
    lines = np.where(flip, slat_v, slat_u)
    d_slat = np.minimum(lines, 1 - lines) * size / (blocks * 3)
    d_block = np.minimum(np.minimum(block_u, 1 - block_u), np.minimum(block_v, 1 - block_v))
    d = np.minimum(d_slat, d_block * size / blocks)
    tone = 1.0 + 0.08 * (2 * rng.random((blocks, blocks)) - 1)[by % blocks, bx % blocks]
    joint = 1.0 - 0.4 * (1.0 - smoothstep(0.3, 1.3, d))
    return (img * (joint * tone)[..., None]).astype(np.float32)
