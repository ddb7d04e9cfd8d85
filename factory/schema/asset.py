"""The asset contract: ``assets/<asset_id>/meta.json`` in a run directory.

An asset folder holds a visual mesh (OBJ, in the object frame: z up, centred in x and y, bottom
at z = 0, metres), an optional texture, and the convex collision parts the compiler uses. With
no collision parts listed, MuJoCo collides with the convex hull of the visual mesh.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from factory.schema.errors import SchemaError, SchemaVersionError
from factory.schema.scene import _from_dict, to_dict

ASSET_SCHEMA_VERSION = 1


@dataclass
class AssetMeta:
    """What an asset folder holds (paths are relative to the folder).

    Attributes:
        asset_id: the folder name (content hash based).
        backend: ``procedural``, ``mesh_library``, ``trellis`` or ``sage``.
        visual: visual mesh file (OBJ).
        texture: texture image (PNG) for the visual mesh's UVs, if any.
        collision: convex collision part files (OBJ); empty means the visual mesh's hull.
        extents: ``(width, length, height)`` of the visual mesh's bounding box (m).
        license: the asset's license (SPDX id or free text).
        provenance: where it came from (source files and their sha256, generator, seed).
        category: what the asset is (``mug``, ``bed`` ...), if known.
        visual_parts: coloured visual pieces ``{file, rgba, metallic, roughness}``; when given,
            they replace ``visual`` in the compiled scene (``visual`` stays the whole mesh).
        supports: upward support surfaces ``{name, z, rect: [x0, y0, x1, y1]}`` (object frame).
        containers: interior volumes ``{name, lo: [x, y, z], hi: [x, y, z]}`` (object frame).
        mass: mass (kg) from volume x density, if known.
        friction: sliding friction of the main material, if known.
        materials: the materials used.
        request: the normalised request the asset was made from.
    """

    asset_id: str
    backend: str
    visual: str
    extents: list[float]
    texture: str | None = None
    collision: list[str] = field(default_factory=list)
    license: str = "unknown"
    provenance: dict[str, Any] = field(default_factory=dict)
    category: str = ""
    visual_parts: list[dict[str, Any]] = field(default_factory=list)
    supports: list[dict[str, Any]] = field(default_factory=list)
    containers: list[dict[str, Any]] = field(default_factory=list)
    mass: float | None = None
    friction: float | None = None
    materials: list[str] = field(default_factory=list)
    request: dict[str, Any] = field(default_factory=dict)
    schema_version: int = ASSET_SCHEMA_VERSION


def asset_meta_from_dict(data: Any, origin: str = "meta.json") -> AssetMeta:
    """Parses an asset's ``meta.json`` dict, checking its ``schema_version``."""
    if not isinstance(data, dict) or data.get("schema_version") != ASSET_SCHEMA_VERSION:
        version = data.get("schema_version") if isinstance(data, dict) else None
        raise SchemaVersionError(
            f"{origin}: asset schema_version is {version!r}, this factory reads "
            f"{ASSET_SCHEMA_VERSION}: delete the asset folder to rebuild it"
        )
    meta: AssetMeta = _from_dict(AssetMeta, data, origin)
    return meta


def load_asset_meta(folder: str | Path) -> AssetMeta:
    """Reads ``<folder>/meta.json``."""
    path = Path(folder) / "meta.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SchemaError(f"asset {Path(folder).name!r} has no meta.json at {path}") from None
    except json.JSONDecodeError as e:
        raise SchemaError(f"{path} is not valid JSON ({e.msg}); delete the asset folder") from None
    return asset_meta_from_dict(data, str(path))


def asset_meta_to_json(meta: AssetMeta) -> str:
    """``meta.json`` text."""
    return json.dumps(to_dict(meta), indent=2) + "\n"
