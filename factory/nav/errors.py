"""The error type of base navigation."""

from __future__ import annotations

from factory.errors import FactoryError


class NavError(FactoryError):
    """A navigation input is unusable (an empty grid, a bad resolution, limits that are not
    positive, a path with fewer than one point). A search that finds no path does not raise:
    it returns a result whose ``reason`` is ``nav_failed``."""
