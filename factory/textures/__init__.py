"""Procedural textures: every material of the asset library and of floors, walls and ceilings.

One module per family of images (:mod:`.wood`: grain of several species, plank and parquet
floors; :mod:`.fabric`: weaves, velvet, leather, carpet, foam; :mod:`.stone`: marble, stone,
concrete, tiles, brick; :mod:`.metal`: brushed, polished, painted; :mod:`.surfaces`: glazed
ceramic, glass, plastic, rubber, paper, cardboard, painted plaster, wallpaper, fruit skin,
wax, soil, leaves), all built from the tileable noise of :mod:`.noise` with numpy, so every
image is a pure function of its seed and repeats without a seam. :mod:`.weathering` adds the
layers that condition words ask for (rust, dust, dirt, mud, stains, scratches, peeling, ...),
:mod:`.conditions` holds those words, :mod:`.looks` says which generator, scale and finish each
material has, :mod:`.cache` makes and caches the PNG files by content, and
:mod:`.appearance` puts it together for one surface.

Floor 2, next to ``sim/``: the compiler textures floors and walls, and the asset library
(floor 3) textures the parts of assets. Nothing heavy is imported here.
"""

from factory.textures.registry import GENERATORS, VERSION, TextureError

__all__ = ["GENERATORS", "VERSION", "TextureError"]
