"""A surface's whole appearance: the look of its material text, the condition words on it,
its texture file and the MuJoCo material values that go with it.

Both the asset library (each part of an asset) and the compiler (floors, walls, ceilings) call
:func:`appearance`, so a "dusty oak" floor and a dusty oak table look alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from factory.textures.cache import (
    DEFAULT_SIZE,
    VARIANTS,
    Texture,
    TextureSpec,
    quantise,
    texture_file,
)
from factory.textures.conditions import kinds_in
from factory.textures.looks import Finish, Look, adjust_pbr, finish_of, look_for, styled_look
from factory.textures.weathering import LAYERS

RGBA = tuple[float, float, float, float]


@dataclass(frozen=True)
class Appearance:
    """What a textured surface needs in MuJoCo.

    Attributes:
        look: the look's key in :data:`~.looks.LOOKS` (after finish words).
        texture: the texture file.
        rgba: the material colour (the surface colour times the texture's gain per channel,
            clipped; the gain alone for untinted looks), alpha kept.
        colour: the surface colour the texture was made for: a look such as gold replaces it,
            and weathering is composed on the colour rounded to ``COLOUR_STEP``.
        tile: metres one texture image covers (UVs are metres / tile).
        finish: specular, shininess and reflectance.
        metallic: PBR metallic (0..1).
        roughness: PBR roughness (0..1).
        weathering: the weathering layers in the texture.
        tinted: the texture is a detail map for the colour (the material colour is the
            surface colour times the gain); else it holds the colours (the material is white).
    """

    look: str
    texture: Texture
    rgba: RGBA
    colour: RGBA
    tile: float
    finish: Finish
    metallic: float
    roughness: float
    weathering: tuple[str, ...]
    tinted: bool = True


def spec_for(
    look: Look,
    colour: RGBA,
    kinds: tuple[str, ...],
    seed: int,
    size: int = DEFAULT_SIZE,
) -> TextureSpec:
    """The texture spec of a look on a surface of ``colour`` under condition ``kinds``."""
    weathering = tuple(sorted(set(look.weathering) | {k for k in kinds if k in LAYERS}))
    base = quantise(colour[:3]) if (weathering and look.tinted) else (1.0, 1.0, 1.0)
    return TextureSpec(
        generator=look.generator,
        params=look.params,
        seed=int(seed) % VARIANTS,
        size=size,
        weathering=weathering,
        family=look.family,
        base=base,
        normalise=look.tinted,
    )


def appearance(
    material: str,
    colour: RGBA,
    folder: str | Path,
    seed: int = 0,
    kinds: tuple[str, ...] = (),
    size: int = DEFAULT_SIZE,
    default: str = "plastic",
    floor: bool = False,
    metallic: float = 0.0,
    roughness: float = 0.5,
) -> Appearance:
    """The appearance of a surface.

    Args:
        material: the material text (``"oak"``, ``"rusty metal"``, ``"dusty oak"``); condition
            words in it count as ``kinds`` too.
        colour: the surface's colour (rgba, 0..1).
        folder: the texture cache folder.
        seed: picks the texture variant (``seed % VARIANTS``).
        kinds: condition kinds on the surface (``rust``, ``dust``, ``polished``, ...).
        size: texture size (px).
        default: the look when ``material`` names none.
        floor: the surface is a floor (wood becomes planks, stone tiles).
        metallic, roughness: the material table's PBR values, adjusted for the conditions.

    Returns:
        the look, texture and material values.

    Raises:
        TextureError: the texture cannot be made.
    """
    all_kinds = tuple(dict.fromkeys((*kinds, *kinds_in(material))))
    key, look = styled_look(*look_for(material, default, floor=floor), all_kinds)
    col: RGBA = (
        (look.colour[0], look.colour[1], look.colour[2], colour[3])
        if look.colour is not None
        else colour
    )
    spec = spec_for(look, col, all_kinds, seed, size)
    if spec.weathering and look.tinted:  # the texture was composed on the rounded colour
        col = (*spec.base, col[3])
    tex = texture_file(spec, folder)
    rgb = material_rgb(col, tex.gain, look.tinted)
    met, rough = adjust_pbr(metallic, roughness, all_kinds, look)
    return Appearance(
        look=key,
        texture=tex,
        rgba=(rgb[0], rgb[1], rgb[2], float(col[3])),
        colour=col,
        tile=look.tile,
        finish=finish_of(look, all_kinds),
        metallic=met,
        roughness=rough,
        weathering=tuple(sorted(set(look.weathering) | {k for k in all_kinds if k in LAYERS})),
        tinted=look.tinted,
    )


def material_rgb(
    colour: tuple[float, ...], gain: Sequence[float] | float, tinted: bool = True
) -> list[float]:
    """The MuJoCo material colour (RGB) that shows a texture of ``gain`` (per channel, or one
    number for all) on a surface of ``colour``: the colour times the gain (clipped to 1), or
    the gain alone for untinted textures (their images hold the colours)."""
    g = [float(gain)] * 3 if isinstance(gain, int | float) else [float(v) for v in gain]
    if not tinted:
        return [min(1.0, v) for v in g]
    return [min(1.0, float(c) * v) for c, v in zip(colour[:3], g, strict=True)]
