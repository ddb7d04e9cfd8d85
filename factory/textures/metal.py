"""Metals: brushed, polished and painted metal (detail maps relative to the metal's colour)."""

from __future__ import annotations

import numpy as np

from factory.textures.noise import cells, fbm, smoothstep, value_noise


def _gray(shade: np.ndarray) -> np.ndarray:
    return np.repeat(shade[..., None], 3, axis=2).astype(np.float32)


def brushed(rng: np.random.Generator, size: int, strength: float = 0.12) -> np.ndarray:
    """Brushed metal: fine streaks along u, broad sheen variation."""
    streaks = value_noise(rng, size, (2, size)) - 0.5
    fine = value_noise(rng, size, (8, size // 2)) - 0.5
    sheen = fbm(rng, size, 2, octaves=3) - 0.5
    return _gray(1.0 + strength * streaks + 0.5 * strength * fine + 0.08 * sheen)


def polished(rng: np.random.Generator, size: int) -> np.ndarray:
    """Polished metal (brass, chrome): soft reflections of the room as broad light and dark."""
    sheen = fbm(rng, size, 2, octaves=4)
    band = smoothstep(0.4, 0.8, fbm(rng, size, (1, 3), octaves=2))
    return _gray(0.88 + 0.22 * sheen + 0.10 * band)


def painted(rng: np.random.Generator, size: int) -> np.ndarray:
    """Painted or powder-coated metal: orange-peel texture and faint runs."""
    peel = value_noise(rng, size, size // 4) - 0.5
    f1, _, _ = cells(rng, size, 40)
    dimple = 0.03 * (f1 - 0.5)
    runs = 0.04 * (fbm(rng, size, (6, 1), octaves=3) - 0.5)
    return _gray(1.0 + 0.05 * peel + dimple + runs)
