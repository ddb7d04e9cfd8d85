"""How each material looks: its texture generator, the size one texture image covers, and
the finish (MuJoCo's ``specular``, ``shininess``, ``reflectance``) of its material.

Keys are the material words of the asset library (:data:`factory.assets.physics.MATERIALS`)
and of architecture (floors, walls, ceilings: ``hardwood``, ``tile``, ``plaster`` ...).
:func:`look_for` finds the look of any material text by keyword ("light oak hardwood" ->
``hardwood``), and :func:`styled_look` applies the finish words of a request: ``polished``
shines, ``gold`` turns metal into polished brass, ``luxury`` brings brass, marble and velvet.
``metallic`` and ``roughness`` stay those of the material tables (condition words scale
them, :func:`adjust_pbr`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Any

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Finish:
    """MuJoCo material shading of a surface.

    Attributes:
        specular: specular reflection strength (0..1).
        shininess: shininess of the specular highlight (0..1).
        reflectance: mirror reflection (0..1; MuJoCo's OpenGL renderer draws it on planes and
            boxes only, and it costs a pass: kept 0 except on polished floors).
    """

    specular: float
    shininess: float
    reflectance: float = 0.0


@dataclass(frozen=True)
class Look:
    """A material's appearance.

    Attributes:
        family: ``wood``, ``fabric``, ``leather``, ``metal``, ``stone``, ``ceramic``,
            ``glass``, ``plastic``, ``rubber``, ``paper``, ``plaster`` or ``organic``: what
            weathering does to it (:mod:`.weathering`).
        generator: a key of :data:`~.registry.GENERATORS`.
        params: the generator's keyword arguments (sorted pairs, hashable).
        tile: metres covered by one texture image (its UV period).
        finish: the material's shading.
        tinted: the image is a detail map multiplied by the part's colour (else the image holds
            the colours and the material is white, as brick).
        weathering: weathering the material always has (``rusty metal``: rust).
        colour: the colour the look brings when it replaces a material (gold), else ``None``.
    """

    family: str
    generator: str
    params: tuple[tuple[str, Any], ...] = ()
    tile: float = 0.5
    finish: Finish = Finish(0.3, 0.3)
    tinted: bool = True
    weathering: tuple[str, ...] = ()
    colour: RGB | None = None


def _p(**kw: Any) -> tuple[tuple[str, Any], ...]:
    return tuple(sorted(kw.items()))


_WOOD = Finish(0.25, 0.35)
_FLOOR_WOOD = Finish(0.35, 0.5)
_METAL = Finish(0.7, 0.6)
_SHINY_METAL = Finish(0.9, 0.85)
_GLAZE = Finish(0.7, 0.85)
_MATTE = Finish(0.05, 0.1)
_WALL = Finish(0.1, 0.2)
GOLD: RGB = (0.83, 0.66, 0.26)

LOOKS: dict[str, Look] = {
    # wood (furniture): grain along the long side of each board
    "wood": Look("wood", "wood", _p(species="generic"), 0.6, _WOOD),
    "oak": Look("wood", "wood", _p(species="oak"), 0.6, _WOOD),
    "walnut": Look("wood", "wood", _p(species="walnut"), 0.6, _WOOD),
    "pine": Look("wood", "wood", _p(species="pine"), 0.6, _WOOD),
    "maple": Look("wood", "wood", _p(species="maple"), 0.6, _WOOD),
    "mdf": Look("wood", "wood", _p(species="mdf"), 0.8, Finish(0.3, 0.4)),
    # wood floors
    "hardwood": Look("wood", "planks", _p(species="oak", rows=6, per_row=1), 1.2, _FLOOR_WOOD),
    "floorboards": Look("wood", "planks", _p(species="pine", rows=5, per_row=1), 1.2, _FLOOR_WOOD),
    "laminate": Look(
        "wood", "planks", _p(species="maple", rows=6, per_row=1, tone=0.05), 1.2, Finish(0.4, 0.6)
    ),
    "parquet": Look("wood", "parquet", _p(species="oak", blocks=4), 1.2, _FLOOR_WOOD),
    # metals
    "metal": Look("metal", "brushed", (), 0.3, _METAL),
    "steel": Look("metal", "brushed", _p(strength=0.1), 0.3, _METAL),
    "iron": Look("metal", "painted", (), 0.4, Finish(0.4, 0.5)),
    "rusty metal": Look("metal", "brushed", (), 0.3, Finish(0.1, 0.15), weathering=("rust",)),
    "aluminium": Look("metal", "brushed", _p(strength=0.14), 0.3, _METAL),
    "brass": Look("metal", "polished", (), 0.5, _SHINY_METAL),
    "gold": Look("metal", "polished", (), 0.5, _SHINY_METAL, colour=GOLD),
    "chrome": Look("metal", "polished", (), 0.5, _SHINY_METAL),
    # ceramics and glass
    "ceramic": Look("ceramic", "ceramic", (), 0.25, _GLAZE),
    "porcelain": Look("ceramic", "ceramic", _p(speckle=0.1), 0.3, Finish(0.75, 0.9)),
    "glass": Look("glass", "glass", (), 0.3, Finish(0.9, 0.95)),
    # polymers
    "plastic": Look("plastic", "plastic", (), 0.3, Finish(0.45, 0.55)),
    "vinyl": Look(
        "plastic", "tiles", _p(count=2, grout=0.01, grout_shade=0.85), 0.8, Finish(0.4, 0.5)
    ),
    "rubber": Look("rubber", "rubber", (), 0.3, Finish(0.1, 0.1)),
    # soft materials
    "fabric": Look("fabric", "weave", _p(threads=64), 0.25, Finish(0.05, 0.05)),
    "twill": Look("fabric", "weave", _p(threads=64, twill=True), 0.25, Finish(0.05, 0.05)),
    "velvet": Look("fabric", "velvet", (), 0.4, Finish(0.15, 0.2)),
    "leather": Look("leather", "leather", (), 0.3, Finish(0.35, 0.45)),
    "carpet": Look("fabric", "carpet", (), 0.5, Finish(0.03, 0.05)),
    "foam": Look("fabric", "foam", (), 0.2, _MATTE),
    # stone and masonry
    "marble": Look("stone", "marble", (), 0.8, Finish(0.6, 0.85)),
    "stone": Look("stone", "stone", (), 0.6, Finish(0.3, 0.4)),
    "granite": Look("stone", "stone", _p(grains=64), 0.6, Finish(0.5, 0.7)),
    "concrete": Look("stone", "concrete", (), 1.5, Finish(0.1, 0.15)),
    "brick": Look("stone", "brick", (), 0.9, _MATTE, tinted=False),
    "tile": Look("ceramic", "tiles", _p(count=2), 0.6, Finish(0.6, 0.8)),
    "marble tile": Look("stone", "tiles", _p(count=2, surface="marble"), 1.2, Finish(0.6, 0.85)),
    "stone tile": Look("stone", "tiles", _p(count=2, surface="stone"), 0.8, Finish(0.3, 0.4)),
    # walls and ceilings
    "plaster": Look("plaster", "plaster", (), 1.5, _WALL),
    "drywall": Look("plaster", "plaster", _p(stipple=0.6), 1.5, _WALL),
    "paint": Look("plaster", "plaster", _p(stipple=0.8), 1.5, Finish(0.15, 0.25)),
    "wallpaper": Look("paper", "wallpaper", _p(pattern="damask"), 0.6, _WALL),
    "striped wallpaper": Look("paper", "wallpaper", _p(pattern="stripes"), 0.6, _WALL),
    "dotted wallpaper": Look("paper", "wallpaper", _p(pattern="dots"), 0.5, _WALL),
    # paper and organics
    "paper": Look("paper", "paper", (), 0.25, _MATTE),
    "cardboard": Look("paper", "cardboard", (), 0.3, _MATTE),
    "organic": Look("organic", "skin", (), 0.1, Finish(0.5, 0.6)),
    "wax": Look("organic", "wax", (), 0.1, Finish(0.3, 0.4)),
    "soil": Look("organic", "soil", (), 0.2, Finish(0.02, 0.05)),
    "plant": Look("organic", "leaf", (), 0.15, Finish(0.3, 0.4)),
}
"""Material word -> its look."""

SURFACE_LOOKS: dict[str, str] = {
    "marble": "marble tile",
    "stone": "stone tile",
    "oak": "hardwood",
    "walnut": "hardwood",
    "wood": "hardwood",
    "pine": "floorboards",
    "ceramic": "tile",
}
"""Floor material word -> the look of that material as a floor (marble floors are tiled,
an oak floor is planks)."""

_WORDS = sorted(LOOKS, key=len, reverse=True)


def strip_conditions(text: str) -> str:
    """``text`` without its condition words ("velvet carpet" is a carpet, "gold oak" oak)."""
    from factory.textures.conditions import condition_pattern

    return " ".join(condition_pattern().sub(" ", text).split())


def look_for(name: str, default: str = "plastic", floor: bool = False) -> tuple[str, Look]:
    """The look of a material text.

    Args:
        name: a material word or text (``"oak"``, ``"white drywall"``, ``"dusty oak"``).
        default: the key used when no material word occurs in ``name``.
        floor: ``name`` is a floor's material (solid wood and stone become planks and tiles).

    Returns:
        the look's key and the look.
    """
    low = name.lower().replace("_", " ").strip()
    key = default
    if low in LOOKS:
        key = low
    else:
        low = strip_conditions(low)
        for word in _WORDS:
            if re.search(rf"(?<![a-z]){re.escape(word)}(?![a-z])", low):
                key = word
                break
    if floor:
        key = SURFACE_LOOKS.get(key, key)
    return key, LOOKS[key]


def styled_look(key: str, look: Look, kinds: tuple[str, ...]) -> tuple[str, Look]:
    """The look under finish words: ``polished`` (and ``luxury``) shine; ``gold`` and
    ``luxury`` turn clean metal into polished gold; ``luxury`` turns woven fabric into velvet
    and stone and concrete into marble.

    Returns:
        the look's key (the base look's for a finish change) and the look.
    """
    if ("gold" in kinds or "luxury" in kinds) and look.family == "metal" and not look.weathering:
        key, look = "gold", LOOKS["gold"]
    if "luxury" in kinds:
        if look.family == "fabric" and look.generator == "weave":
            key, look = "velvet", LOOKS["velvet"]
        elif look.family == "stone" and look.generator in ("stone", "concrete"):
            key, look = "marble", LOOKS["marble"]
    if "polished" in kinds or "luxury" in kinds:
        f = look.finish
        shine = Finish(min(1.0, f.specular + 0.3), min(1.0, f.shininess + 0.3), f.reflectance)
        look = replace(look, finish=shine)
    return key, look


ROUGH = frozenset({"rust", "dust", "dirt", "mud", "wear", "scratches", "peeling", "mould"})
"""Condition kinds that make a surface rougher and duller."""


def adjust_pbr(
    metallic: float, roughness: float, kinds: tuple[str, ...], look: Look
) -> tuple[float, float]:
    """``(metallic, roughness)`` of a material under condition kinds: weathering roughens and
    dulls metal, ``polished``/``luxury`` halve roughness, a gold look is fully metallic."""
    if look.colour is not None:
        metallic, roughness = 1.0, min(roughness, 0.2)
    if ROUGH & set(kinds) or look.weathering:
        return min(metallic, 0.6), max(roughness, 0.85)
    if "polished" in kinds or "luxury" in kinds:
        return metallic, roughness * 0.5
    return metallic, roughness


def finish_of(look: Look, kinds: tuple[str, ...]) -> Finish:
    """The finish under condition kinds: weathering takes most of the shine away."""
    f = look.finish
    if ROUGH & set(kinds):
        return Finish(f.specular * 0.35, f.shininess * 0.5, 0.0)
    return f
