"""Deprecated location of :mod:`factory.assets` (moved in 0.1.0; removed in the next release).

``from factory.scenes.assets import AssetLibrary`` and ``python -m factory.scenes.assets`` keep
working for one release and warn; use ``factory.assets`` instead.
"""

import warnings

from factory.assets import (
    BACKENDS,
    CATEGORIES,
    AssetError,
    AssetLibrary,
    AssetSpec,
    Category,
    Resolution,
    TrellisConfig,
    generate,
    resolve,
)

warnings.warn(
    "factory.scenes.assets moved to factory.assets; import that instead "
    "(the old path goes away in the next release)",
    DeprecationWarning,
    stacklevel=2,
)

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
