"""Physical and visual properties of materials.

Mass is volume x density x fill (the part's solid fraction); friction and PBR parameters come
from the material. Densities are typical handbook values (kg/m³).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Material:
    """density (kg/m³), sliding friction, PBR metallic/roughness, default colour (rgba)."""

    density: float
    friction: float
    metallic: float
    roughness: float
    rgba: tuple[float, float, float, float]


MATERIALS: dict[str, Material] = {
    "wood": Material(700, 0.5, 0.0, 0.6, (0.55, 0.38, 0.22, 1)),
    "oak": Material(750, 0.5, 0.0, 0.6, (0.66, 0.49, 0.30, 1)),
    "walnut": Material(650, 0.5, 0.0, 0.55, (0.36, 0.24, 0.15, 1)),
    "pine": Material(500, 0.5, 0.0, 0.65, (0.80, 0.66, 0.45, 1)),
    "mdf": Material(750, 0.5, 0.0, 0.5, (0.93, 0.92, 0.90, 1)),
    "metal": Material(7850, 0.4, 1.0, 0.35, (0.70, 0.71, 0.73, 1)),
    "steel": Material(7850, 0.4, 1.0, 0.3, (0.75, 0.76, 0.78, 1)),
    "rusty metal": Material(7850, 0.6, 0.6, 0.85, (0.50, 0.28, 0.16, 1)),
    "aluminium": Material(2700, 0.4, 1.0, 0.35, (0.80, 0.81, 0.83, 1)),
    "brass": Material(8500, 0.4, 1.0, 0.3, (0.78, 0.62, 0.30, 1)),
    "ceramic": Material(2400, 0.6, 0.0, 0.25, (0.95, 0.95, 0.93, 1)),
    "porcelain": Material(2400, 0.6, 0.0, 0.2, (0.97, 0.97, 0.97, 1)),
    "glass": Material(2500, 0.5, 0.0, 0.05, (0.75, 0.88, 0.92, 0.6)),
    "plastic": Material(950, 0.5, 0.0, 0.45, (0.85, 0.85, 0.85, 1)),
    "rubber": Material(1100, 0.9, 0.0, 0.9, (0.15, 0.15, 0.15, 1)),
    "fabric": Material(300, 0.7, 0.0, 0.95, (0.45, 0.50, 0.58, 1)),
    "leather": Material(900, 0.6, 0.0, 0.6, (0.35, 0.20, 0.12, 1)),
    "foam": Material(60, 0.8, 0.0, 1.0, (0.92, 0.92, 0.90, 1)),
    "marble": Material(2700, 0.5, 0.0, 0.2, (0.92, 0.91, 0.89, 1)),
    "stone": Material(2500, 0.6, 0.0, 0.8, (0.55, 0.54, 0.52, 1)),
    "concrete": Material(2300, 0.7, 0.0, 0.9, (0.60, 0.60, 0.60, 1)),
    "paper": Material(700, 0.5, 0.0, 0.9, (0.92, 0.90, 0.84, 1)),
    "cardboard": Material(300, 0.6, 0.0, 0.9, (0.68, 0.52, 0.34, 1)),
    "organic": Material(850, 0.6, 0.0, 0.6, (0.80, 0.20, 0.15, 1)),
    "wax": Material(900, 0.5, 0.0, 0.5, (0.96, 0.94, 0.86, 1)),
    "soil": Material(1200, 0.9, 0.0, 1.0, (0.30, 0.22, 0.14, 1)),
    "plant": Material(400, 0.7, 0.0, 0.8, (0.22, 0.52, 0.22, 1)),
}
"""Material name -> properties; text like "rusty metal" or "oak" selects them."""

ALIASES: dict[str, str] = {
    "wooden": "wood",
    "timber": "wood",
    "bamboo": "pine",
    "iron": "metal",
    "metallic": "metal",
    "chrome": "steel",
    "stainless": "steel",
    "copper": "brass",
    "gold": "brass",
    "golden": "brass",
    "silver": "aluminium",
    "clay": "ceramic",
    "terracotta": "ceramic",
    "stoneware": "ceramic",
    "crystal": "glass",
    "acrylic": "plastic",
    "vinyl": "plastic",
    "cloth": "fabric",
    "velvet": "fabric",
    "wool": "fabric",
    "linen": "fabric",
    "cotton": "fabric",
    "granite": "stone",
    "rusty": "rusty metal",
    "rust": "rusty metal",
}


def material(name: str) -> Material:
    """The material called ``name`` (or an alias); unknown names fall back to plastic."""
    key = ALIASES.get(name, name)
    return MATERIALS.get(key, MATERIALS["plastic"])
