"""Upgrades of older ``scene.json`` dicts to the current scene schema version.

:data:`MIGRATIONS` maps a version ``k`` to a function that turns a version-``k`` scene dict into a
version-``k + 1`` one; :func:`upgrade` applies them in turn before
:func:`factory.schema.scene.scene_from_dict` checks the version, so a scene written by an older
factory still loads (and is written back as the current version). A new scene schema version
adds its step here (and a test that the step's output loads).

This module imports nothing else of factory (the scene module imports it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


def _v1_to_v2(data: dict[str, Any]) -> dict[str, Any]:
    """Version 2 added ``SceneObject.joint_states`` (default empty: every joint closed) and
    ``SceneObject.task_joint`` (default ``None``); a version-1 scene has neither."""
    return {**data, "schema_version": 2}


MIGRATIONS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: _v1_to_v2}
"""Scene schema version -> the step from it to the next version."""


def upgrade(data: Any) -> Any:
    """Upgrades a scene dict of an older ``schema_version`` to the current one.

    Args:
        data: a parsed ``scene.json``; it is not modified.

    Returns:
        the upgraded dict (a new one when some step ran), or ``data`` itself when it is not a
        dict or its version has no step (the current version, or one this factory cannot read,
        which the version check then reports).
    """
    if not isinstance(data, dict):
        return data
    version = data.get("schema_version")
    while isinstance(version, int) and not isinstance(version, bool) and version in MIGRATIONS:
        data = MIGRATIONS[version](data)
        after = data.get("schema_version")
        if not isinstance(after, int) or after <= version:  # pragma: no cover - a bad step
            raise RuntimeError(f"scene migration from version {version} did not raise it")
        version = after
    return data
