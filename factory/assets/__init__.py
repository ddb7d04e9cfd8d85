"""Open-vocabulary 3-D assets with physical properties.

``AssetLibrary(run_dir/"assets").from_text("small blue ceramic bowl")`` resolves the text to a
category and parameters (:mod:`.resolver`), builds the asset with the configured backend
(procedural generators by default; a mesh library or a text-to-3D server otherwise) and
caches it by content hash. Each asset has a watertight visual mesh (coloured parts), exact
convex collision parts (<= 64 vertices each), support surfaces, interiors, mass, friction,
license and provenance in ``meta.json``.
"""

from factory.assets.catalog import CATEGORIES, Category
from factory.assets.library import BACKENDS, AssetLibrary, TrellisConfig
from factory.assets.procedural import AssetError, AssetSpec, generate
from factory.assets.resolver import Resolution, resolve

__all__ = [
    "BACKENDS",
    "CATEGORIES",
    "AssetError",
    "AssetLibrary",
    "AssetSpec",
    "Category",
    "Resolution",
    "TrellisConfig",
    "generate",
    "resolve",
]
