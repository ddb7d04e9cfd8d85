"""The exception hierarchy of factory.

Every error that factory raises on purpose derives from :class:`FactoryError`, so a caller
(the CLI above all) can tell a user mistake from a bug. Messages name the problem and the fix.
This module sits on the ground floor (``schema/``) so that every layer can use it.
"""

from __future__ import annotations


class FactoryError(Exception):
    """Base class of every error factory raises deliberately."""


class SchemaError(FactoryError, ValueError):
    """A scene (or other persisted artifact) is malformed or inconsistent."""


class SchemaVersionError(SchemaError):
    """A persisted file carries a ``schema_version`` this factory cannot read."""


class UnsafePathError(SchemaError):
    """An id or archive member would escape its directory (``../x``, absolute paths)."""


class PolicyError(FactoryError):
    """A policy cannot be trained, loaded or evaluated as asked (unknown policy, missing
    inputs, a checkpoint whose features do not match the data or the env)."""
