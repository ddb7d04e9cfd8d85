"""Named surface materials for architecture (floors, walls) and a fallback object palette.

Names are matched case-insensitively by keyword (``"light oak hardwood"`` -> ``hardwood``);
unknown names get a neutral colour.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass


@dataclass(frozen=True)
class Surface:
    """Colour (linear rgba, 0..1) and PBR-ish parameters of a surface."""

    rgba: tuple[float, float, float, float]
    roughness: float = 0.7
    metallic: float = 0.0
    checker: bool = False


SURFACES: dict[str, Surface] = {
    "hardwood": Surface((0.55, 0.38, 0.24, 1), 0.6, checker=True),
    "wood": Surface((0.58, 0.42, 0.28, 1), 0.6, checker=True),
    "oak": Surface((0.66, 0.50, 0.33, 1), 0.6, checker=True),
    "parquet": Surface((0.60, 0.43, 0.27, 1), 0.6, checker=True),
    "laminate": Surface((0.70, 0.58, 0.44, 1), 0.5, checker=True),
    "tile": Surface((0.85, 0.85, 0.82, 1), 0.3, checker=True),
    "ceramic": Surface((0.88, 0.88, 0.86, 1), 0.3, checker=True),
    "marble": Surface((0.92, 0.91, 0.89, 1), 0.2, checker=True),
    "stone": Surface((0.62, 0.61, 0.58, 1), 0.8, checker=True),
    "concrete": Surface((0.60, 0.60, 0.60, 1), 0.9, checker=True),
    "carpet": Surface((0.45, 0.47, 0.55, 1), 1.0, checker=True),
    "rubber": Surface((0.20, 0.20, 0.22, 1), 0.9, checker=True),
    "vinyl": Surface((0.75, 0.73, 0.70, 1), 0.5, checker=True),
    "drywall": Surface((0.90, 0.89, 0.86, 1), 0.9),
    "plaster": Surface((0.93, 0.91, 0.87, 1), 0.9),
    "paint": Surface((0.88, 0.87, 0.83, 1), 0.8),
    "brick": Surface((0.64, 0.33, 0.25, 1), 0.9),
    "glass": Surface((0.70, 0.85, 0.95, 0.25), 0.05),
    "metal": Surface((0.70, 0.72, 0.75, 1), 0.3, metallic=1.0),
}

DEFAULT_FLOOR = SURFACES["hardwood"]
DEFAULT_WALL = SURFACES["drywall"]


def surface(name: str, default: Surface) -> Surface:
    """The surface whose key occurs in ``name`` (longest key first), else ``default``."""
    low = name.lower()
    for key in sorted(SURFACES, key=len, reverse=True):
        if key in low:
            return SURFACES[key]
    return default


def object_rgba(key: str) -> tuple[float, float, float, float]:
    """A stable, pleasant colour for an object without appearance (hash of ``key``)."""
    import colorsys

    h = int(hashlib.sha1(key.encode()).hexdigest()[:8], 16)
    hue = (h % 360) / 360.0
    r, g, b = colorsys.hls_to_rgb(hue, 0.55, 0.45)
    return (r, g, b, 1.0)
