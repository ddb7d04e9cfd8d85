"""The asset package's errors (re-exported by :mod:`.catalog` and :mod:`.procedural`)."""

from __future__ import annotations

from factory.errors import ConfigError, FactoryError


class CatalogError(ConfigError):
    """A catalogue entry is invalid (unknown template kind, bad field or value)."""


class AssetError(FactoryError):
    """An asset cannot be made (bad request, bad mesh, backend failure)."""


__all__ = ["AssetError", "CatalogError"]
