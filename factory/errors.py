"""All of factory's error types (the base lives in :mod:`factory.schema.errors`)."""

from __future__ import annotations

from factory.schema.errors import (
    FactoryError,
    PolicyError,
    SchemaError,
    SchemaVersionError,
    UnsafePathError,
)


class ConfigError(FactoryError):
    """The configuration is invalid (unknown stage or key, missing ``run_dir``, bad shard)."""


class RoomDataError(ConfigError):
    """A room type of the room-type data file is invalid (it names the room type, the field
    and the allowed values)."""


class StoreError(FactoryError):
    """The run directory is unusable (wrong manifest version, unwritable, missing inputs)."""


class MixedLayoutError(StoreError):
    """Fixed-base and mobile episodes were asked for in one dataset (their features differ)."""


class CompileError(FactoryError):
    """A scene cannot be compiled into a MuJoCo model."""


class StageFailed(FactoryError):
    """Some work items of a stage failed (the others are complete)."""


class RenderError(FactoryError):
    """No OpenGL backend could render offscreen."""


class TaskError(FactoryError):
    """A scene cannot host its task (objects missing, unreachable, not graspable)."""


__all__ = [
    "AppearanceError",
    "CompileError",
    "ConfigError",
    "FactoryError",
    "MixedLayoutError",
    "PolicyError",
    "RenderError",
    "RoomDataError",
    "SchemaError",
    "SchemaVersionError",
    "StageFailed",
    "StoreError",
    "TaskError",
    "UnsafePathError",
]


class AppearanceError(FactoryError):
    """Episode appearances do not fit the episodes they were given with (one per episode)."""
