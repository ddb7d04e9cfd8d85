"""The literal registry of texture generators: name -> ``"module:function"``, resolved lazily.

A generator is ``fn(rng, size, **params) -> (size, size, 3) float32`` (a detail map relative
to the surface's colour, or absolute colours for untinted looks). Nothing registers itself by
import; a new generator is one line here (and a look in :mod:`.looks` that uses it).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from factory.errors import FactoryError

GENERATORS: dict[str, str] = {
    "wood": "factory.textures.wood:wood",
    "planks": "factory.textures.wood:planks",
    "parquet": "factory.textures.wood:parquet",
    "weave": "factory.textures.fabric:weave",
    "velvet": "factory.textures.fabric:velvet",
    "leather": "factory.textures.fabric:leather",
    "carpet": "factory.textures.fabric:carpet",
    "foam": "factory.textures.fabric:foam",
    "marble": "factory.textures.stone:marble",
    "stone": "factory.textures.stone:stone",
    "concrete": "factory.textures.stone:concrete",
    "tiles": "factory.textures.stone:tiles",
    "brick": "factory.textures.stone:brick",
    "brushed": "factory.textures.metal:brushed",
    "polished": "factory.textures.metal:polished",
    "painted": "factory.textures.metal:painted",
    "ceramic": "factory.textures.surfaces:ceramic",
    "glass": "factory.textures.surfaces:glass",
    "plastic": "factory.textures.surfaces:plastic",
    "rubber": "factory.textures.surfaces:rubber",
    "paper": "factory.textures.surfaces:paper",
    "cardboard": "factory.textures.surfaces:cardboard",
    "plaster": "factory.textures.surfaces:plaster",
    "wallpaper": "factory.textures.surfaces:wallpaper",
    "skin": "factory.textures.surfaces:skin",
    "wax": "factory.textures.surfaces:wax",
    "soil": "factory.textures.surfaces:soil",
    "leaf": "factory.textures.surfaces:leaf",
}
"""Generator name -> ``"module:function"``."""

VERSION = 1
"""Version of the generators and weathering layers: part of every texture's cache key, so a
change to any image means a new key (bump it with such a change)."""

Generator = Callable[..., np.ndarray]


class TextureError(FactoryError):
    """A texture cannot be made (unknown generator, bad size, unreadable cached file)."""


@cache
def generator(name: str) -> Generator:
    """The generator function called ``name``.

    Raises:
        TextureError: ``name`` is not in :data:`GENERATORS`.
    """
    target = GENERATORS.get(name)
    if target is None:
        raise TextureError(
            f"unknown texture generator {name!r}: use one of {', '.join(sorted(GENERATORS))}"
        )
    module, _, func = target.partition(":")
    fn: Any = getattr(importlib.import_module(module), func)
    return fn
