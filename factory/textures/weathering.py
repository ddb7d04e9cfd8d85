"""Weathering layers: what condition words (rusty, dusty, muddy, worn, scratched, stained,
peeling, ...) do to a surface.

Each layer blends a colour into the texture through a mask made of the noise fields of
:mod:`.noise`; it works on absolute colours (the texture times the surface's colour), so rust
is rust-coloured on any metal and dust is light on dark wood. Layers apply in the order of
:data:`LAYERS`, whatever the order of the words. Which layers make sense depends on the
surface's family (:data:`APPLIES`): paint peels, stone cracks, fabric does neither.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from factory.textures.noise import cells, fbm, grid, luma, mix, smoothstep, value_noise

Layer = Callable[[np.ndarray, np.random.Generator, str], np.ndarray]

HARD = frozenset({"wood", "metal", "plastic", "ceramic", "glass", "stone", "leather", "rubber"})
"""Families whose surface scratches."""

PAINTED = frozenset({"plaster", "metal", "wood"})
"""Families that can carry a coat of paint that peels."""

BRITTLE = frozenset({"stone", "ceramic", "plaster", "leather"})
"""Families that crack."""


def _rust(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    if family != "metal":  # "a rusty garage": its metal rusts, not its walls and sofas
        return a
    size = a.shape[0]
    patches = 0.8 * fbm(rng, size, 3, octaves=6) + 0.2 * value_noise(rng, size, size // 4)
    m = smoothstep(0.40, 0.62, patches) * 0.95
    hue = fbm(rng, size, 6, octaves=4)
    dark = np.array([0.36, 0.16, 0.07], np.float32)
    light = np.array([0.66, 0.34, 0.13], np.float32)
    rust = dark + (light - dark) * hue[..., None]
    pits = smoothstep(0.85, 0.97, value_noise(rng, size, size // 2))
    rust = rust * (1.0 - 0.4 * pits)[..., None]
    return a + (rust - a) * m[..., None]


def _dust(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    film = smoothstep(0.2, 0.8, fbm(rng, size, 2, octaves=5))
    speck = smoothstep(0.8, 0.95, value_noise(rng, size, size // 2))
    m = np.clip(0.30 + 0.40 * film + 0.2 * speck, 0.0, 0.85)
    return mix(a, (0.70, 0.67, 0.62), m)


def _dirt(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    blot = smoothstep(0.5, 0.8, fbm(rng, size, 3, octaves=5))
    grime = 0.15 * fbm(rng, size, 8, octaves=3)
    return mix(a, (0.22, 0.18, 0.13), np.clip(0.6 * blot + grime, 0.0, 0.8))


def _mud(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    f1, _, ids = cells(rng, size, 5, jitter=1.0)
    radius = (0.12 + 0.3 * rng.random(25).astype(np.float32))[ids]
    rough = 0.45 * (fbm(rng, size, 10, octaves=4) - 0.5)
    blob = 1.0 - smoothstep(radius - 0.03, radius + 0.02, f1 + rough)
    blob *= (rng.random(25) < 0.55).astype(np.float32)[ids]
    spots = smoothstep(0.88, 0.94, fbm(rng, size, 48, octaves=2))
    m = np.clip(blob + spots, 0.0, 1.0) * 0.9
    mud = (
        np.array([0.33, 0.25, 0.16], np.float32)
        * (0.85 + 0.3 * fbm(rng, size, 16, octaves=3))[..., None]
    )
    return a + (mud - a) * m[..., None]


def _stains(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    x, y = grid(size)
    m = np.zeros((size, size), np.float32)
    for _ in range(4):
        cx, cy = rng.random(2)
        r = 0.06 + 0.12 * float(rng.random())
        dx = np.abs(x - cx)
        dy = np.abs(y - cy)
        d = np.hypot(np.minimum(dx, 1 - dx), np.minimum(dy, 1 - dy))
        ring = np.exp(-(((d - r) / 0.008) ** 2))
        fill = 0.25 * (1.0 - smoothstep(r - 0.01, r, d))
        m = np.maximum(m, (ring * 0.55 + fill).astype(np.float32))
    return mix(a, (0.42, 0.30, 0.18), np.clip(m, 0.0, 0.8))


def _wear(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    worn = smoothstep(0.45, 0.85, fbm(rng, size, 3, octaves=5))
    gray = luma(a)[..., None] * np.ones(3, np.float32)
    faded = 0.7 * a + 0.3 * (gray * 1.15 + 0.05)
    return a + (faded - a) * (0.35 + 0.65 * worn)[..., None]


def _scratches(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    if family not in HARD:
        return _wear(a, rng, family)
    size = a.shape[0]
    m = np.zeros(size * size, np.float32)
    main = float(rng.random()) * np.pi
    for _ in range(70):
        ang = main + float(rng.normal(0, 0.5))
        length = (0.04 + 0.25 * float(rng.random())) * size
        n = int(length * 1.5) + 2
        t = np.linspace(0.0, length, n)
        x0, y0 = rng.random(2) * size
        px = (np.round(x0 + np.cos(ang) * t).astype(np.int64)) % size
        py = (np.round(y0 + np.sin(ang) * t).astype(np.int64)) % size
        m[py * size + px] = 0.5 + 0.5 * float(rng.random())
    mask = m.reshape(size, size)
    light = float(luma(a).mean()) < 0.55
    colour = np.minimum(a * 1.0 + 0.35, 1.0) if light else a * 0.55
    return a + (colour - a) * mask[..., None]


def _peeling(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    if family not in PAINTED:
        return _wear(a, rng, family)
    size = a.shape[0]
    f = 0.85 * fbm(rng, size, 4, octaves=6) + 0.15 * value_noise(rng, size, 32)
    bare = smoothstep(0.60, 0.615, f)
    edge = np.exp(-(((f - 0.6) / 0.012) ** 2)).astype(np.float32)
    under = {
        "plaster": (0.60, 0.58, 0.54),
        "metal": (0.34, 0.22, 0.15),
        "wood": (0.70, 0.58, 0.42),
    }[family]
    grain = (0.9 + 0.2 * fbm(rng, size, 12, octaves=3))[..., None]
    out = a + (np.asarray(under, np.float32) * grain - a) * bare[..., None]
    return out * (1.0 - 0.35 * edge * (1.0 - bare))[..., None]


def _mould(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    size = a.shape[0]
    cluster = smoothstep(0.55, 0.75, fbm(rng, size, 3, octaves=4))
    spots = smoothstep(0.5, 0.8, fbm(rng, size, size // 8, octaves=3))
    return mix(a, (0.12, 0.16, 0.10), np.clip(cluster * spots * 1.3, 0.0, 0.85))


def _cracks(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    if family not in BRITTLE:
        return a
    size = a.shape[0]
    f1, f2, _ = cells(rng, size, 5)
    line = 1.0 - smoothstep(0.0, 0.03, f2 - f1)
    where = smoothstep(0.45, 0.6, fbm(rng, size, 2, octaves=3))
    return a * (1.0 - 0.65 * line * where)[..., None]


def _faded(a: np.ndarray, rng: np.random.Generator, family: str) -> np.ndarray:
    gray = luma(a)[..., None] * np.ones(3, np.float32)
    sun = 0.4 + 0.2 * fbm(rng, a.shape[0], 2, octaves=3)
    return a + (gray * 1.1 + 0.08 - a) * sun[..., None]


LAYERS: dict[str, Layer] = {
    "faded": _faded,
    "wear": _wear,
    "peeling": _peeling,
    "cracks": _cracks,
    "rust": _rust,
    "scratches": _scratches,
    "stains": _stains,
    "mould": _mould,
    "dirt": _dirt,
    "dust": _dust,
    "mud": _mud,
}
"""Weathering kind -> its layer, in the order they are applied (dust settles on rust)."""

FINISHES = frozenset({"clean", "polished", "gold", "luxury"})
"""Condition kinds that change the material or its finish, not the texture."""


def weather(
    image: np.ndarray, kinds: tuple[str, ...], family: str, rng: np.random.Generator
) -> np.ndarray:
    """Applies the weathering layers named in ``kinds`` to an absolute-colour image.

    Args:
        image: (size, size, 3) float32 colours (0..1).
        kinds: condition kinds (unknown ones and finishes are skipped).
        family: the surface's family (``metal``, ``wood``, ``fabric``, ...).
        rng: the random stream of the texture.

    Returns:
        the weathered image, clipped to 0..1.
    """
    out = image.astype(np.float32, copy=True)
    for kind, layer in LAYERS.items():
        if kind in kinds:
            out = layer(out, rng, family)
    return np.clip(out, 0.0, 1.0)
