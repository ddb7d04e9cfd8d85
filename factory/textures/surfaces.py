"""Smooth and fibrous surfaces: glazed ceramic, glass, plastic, rubber, paper, cardboard,
painted plaster, wallpaper, fruit skin, wax, soil and leaves.

Detail maps relative to the surface's colour (mean luminance about 1) unless a docstring says
the image is in absolute colours.
"""

from __future__ import annotations

import numpy as np

from factory.textures.noise import cells, fbm, grid, smoothstep, value_noise


def _gray(shade: np.ndarray) -> np.ndarray:
    return np.repeat(shade[..., None], 3, axis=2).astype(np.float32)


def ceramic(rng: np.random.Generator, size: int, speckle: float = 0.5) -> np.ndarray:
    """Glazed ceramic: a smooth glaze pooling in soft clouds, with a few iron speckles."""
    pool = fbm(rng, size, 3, octaves=4)
    spots = value_noise(rng, size, size // 2)
    speck = smoothstep(0.93, 0.99, spots) * speckle
    return _gray((1.0 + 0.08 * (pool - 0.5)) * (1.0 - 0.4 * speck))


def glass(rng: np.random.Generator, size: int) -> np.ndarray:
    """Glass: faint ripples and the odd reflection streak."""
    ripple = fbm(rng, size, (2, 8), octaves=3)
    streak = smoothstep(0.75, 0.95, value_noise(rng, size, (1, 6)))
    return _gray(0.96 + 0.06 * ripple + 0.08 * streak)


def plastic(rng: np.random.Generator, size: int) -> np.ndarray:
    """Moulded plastic: a fine stipple and faint flow lines."""
    stipple = value_noise(rng, size, size // 3) - 0.5
    flow = fbm(rng, size, (3, 1), octaves=3) - 0.5
    return _gray(1.0 + 0.05 * stipple + 0.06 * flow)


def rubber(rng: np.random.Generator, size: int) -> np.ndarray:
    """Rubber: a matte, granular surface."""
    grain = value_noise(rng, size, size // 2) - 0.5
    blot = fbm(rng, size, 4, octaves=3) - 0.5
    return _gray(1.0 + 0.14 * grain + 0.16 * blot)


def paper(rng: np.random.Generator, size: int) -> np.ndarray:
    """Paper: short fibres in every direction and a cloudy formation."""
    fib_a = value_noise(rng, size, (size // 2, size // 8)) - 0.5
    fib_b = value_noise(rng, size, (size // 8, size // 2)) - 0.5
    cloud = fbm(rng, size, 6, octaves=4) - 0.5
    return _gray(1.0 + 0.04 * (fib_a + fib_b) + 0.06 * cloud)


def cardboard(rng: np.random.Generator, size: int, flutes: int = 40) -> np.ndarray:
    """Cardboard: faint corrugation ridges, long fibres and darker recycled specks."""
    x, _ = grid(size)
    ridge = 0.03 * np.cos(2 * np.pi * x * flutes)
    fibre = value_noise(rng, size, (size // 2, size // 10)) - 0.5
    speck = smoothstep(0.9, 0.98, value_noise(rng, size, size // 2))
    cloud = fbm(rng, size, 4, octaves=4) - 0.5
    return _gray((1.0 + ridge + 0.08 * fibre + 0.10 * cloud) * (1.0 - 0.3 * speck))


def plaster(rng: np.random.Generator, size: int, stipple: float = 1.0) -> np.ndarray:
    """Painted plaster: trowel clouds under paint and a roller stipple (``stipple`` scales it)."""
    clouds = fbm(rng, size, 2, octaves=5) - 0.5
    roller = value_noise(rng, size, size // 3) - 0.5
    return _gray(1.0 + 0.07 * clouds + 0.04 * stipple * roller)


def wallpaper(rng: np.random.Generator, size: int, pattern: str = "damask") -> np.ndarray:
    """Wallpaper: ``stripes`` (two-tone bands), ``damask`` (a repeating ornament of lobes on a
    diamond lattice) or ``dots``; printed on faintly textured paper."""
    x, y = grid(size)
    if pattern == "stripes":
        bands = 6
        s = np.cos(2 * np.pi * x * bands)
        fine = np.cos(2 * np.pi * x * bands * 4)
        motif = 0.85 + 0.12 * smoothstep(-0.2, 0.2, s) + 0.03 * fine
    elif pattern == "dots":
        f1, _, _ = cells(rng, size, 8, jitter=0.0)
        motif = 1.0 - 0.18 * (1.0 - smoothstep(0.12, 0.16, f1))
    else:
        motif = 0.86 + 0.14 * (1.0 - _damask(x, y, 3))
    paper_tex = 1.0 + 0.03 * (fbm(rng, size, 8, octaves=3) - 0.5)
    return _gray(motif * paper_tex)


def skin(rng: np.random.Generator, size: int) -> np.ndarray:
    """Fruit and vegetable skin: pores, a blush and faint streaks."""
    f1, _, _ = cells(rng, size, 40, jitter=1.0)
    pores = 1.0 - 0.10 * (1.0 - smoothstep(0.0, 0.2, f1))
    blush = fbm(rng, size, 2, octaves=3)
    streak = value_noise(rng, size, (3, 24)) - 0.5
    img = _gray(pores * (1.0 + 0.06 * streak))
    img[..., 0] *= 1.0 + 0.10 * (blush - 0.5)
    img[..., 1] *= 1.0 - 0.08 * (blush - 0.5)
    return img


def wax(rng: np.random.Generator, size: int) -> np.ndarray:
    """Candle wax: soft translucency clouds."""
    return _gray(1.0 + 0.06 * (fbm(rng, size, 3, octaves=4) - 0.5))


def soil(rng: np.random.Generator, size: int) -> np.ndarray:
    """Potting soil: crumbs and grains of different darkness."""
    _, _, ids = cells(rng, size, 64, jitter=1.0)
    crumbs = rng.random(64 * 64).astype(np.float32)[ids]
    return _gray(0.75 + 0.5 * crumbs * (0.8 + 0.4 * fbm(rng, size, 6, octaves=3)))


def leaf(rng: np.random.Generator, size: int) -> np.ndarray:
    """Leaves: veins along v and a mottled, slightly yellow-green blade."""
    x, _ = grid(size)
    veins = 1.0 - 0.12 * (1.0 - smoothstep(0.0, 0.06, np.abs(np.sin(np.pi * x * 8))))
    mottle = fbm(rng, size, 4, octaves=4)
    img = _gray(veins * (0.92 + 0.16 * mottle))
    img[..., 0] *= 1.0 + 0.08 * (mottle - 0.5)
    return img


def _damask(x: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """A damask-like ornament (1 on the ornament, 0 on the ground): ``k`` x ``k`` half-drop
    repeats of a four-petal flower with a ring and a small diamond between."""
    v = y * k
    row = np.floor(v)
    u = x * k + 0.5 * (row % 2)
    lu = u - np.floor(u) - 0.5
    lv = v - row - 0.5
    r = np.hypot(lu * 1.25, lv)
    theta = np.arctan2(lv, lu)
    petals = 1.0 - smoothstep(0.0, 0.02, r - (0.2 + 0.1 * np.cos(4 * theta)))
    ring = 1.0 - smoothstep(0.012, 0.03, np.abs(r - 0.36))
    centre = 1.0 - smoothstep(0.03, 0.05, r)
    diamond = 1.0 - smoothstep(0.0, 0.03, np.abs(lu) + np.abs(lv) - 0.5 + 0.42)
    shape = np.maximum(np.maximum(petals - 0.6 * centre, ring), diamond)
    return np.clip(shape, 0.0, 1.0).astype(np.float32)
