"""The content-addressed asset cache (``<run_dir>/assets/<asset_id>/``).

An asset id is a hash of (backend, normalised request, seed), so the same request gives the
same id. A folder is built aside (``.<id>.<random>``) and renamed into place when complete:
two processes building the same asset at once both succeed and leave one intact copy, and a
killed build leaves only a hidden temporary folder, never a half-written asset.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from factory.schema import AssetMeta, SchemaError, load_asset_meta
from factory.schema.asset import asset_meta_to_json
from factory.sim.lit_mesh import obj_lines

log = logging.getLogger(__name__)


def asset_id_for(backend: str, key: dict[str, Any]) -> str:
    """``<backend prefix>-<16 hex>`` from the backend and the normalised request."""
    blob = json.dumps({"backend": backend, "request": key}, sort_keys=True).encode()
    prefix = {"procedural": "proc", "mesh_library": "mlib", "trellis": "trel"}.get(backend, backend)
    return f"{prefix}-{hashlib.sha256(blob).hexdigest()[:16]}"


def cached(assets_dir: Path, asset_id: str) -> AssetMeta | None:
    """The cached asset's meta, or ``None`` if absent or damaged (a damaged one is removed)."""
    folder = assets_dir / asset_id
    if not (folder / "meta.json").is_file():
        return None
    try:
        meta = load_asset_meta(folder)
    except SchemaError:
        log.warning("asset %s is damaged; rebuilding it", asset_id)
        shutil.rmtree(folder, ignore_errors=True)
        return None
    files = [meta.visual, *meta.collision, *(p["file"] for p in meta.visual_parts)]
    files += [p["texture"] for p in meta.visual_parts if p.get("texture")]
    if not all((folder / f).is_file() for f in files):
        log.warning("asset %s misses files; rebuilding it", asset_id)
        shutil.rmtree(folder, ignore_errors=True)
        return None
    return meta


def build(assets_dir: Path, asset_id: str, fill: Callable[[Path], AssetMeta]) -> AssetMeta:
    """Returns the cached asset, or builds it with ``fill(tmp_folder) -> meta`` atomically."""
    meta = cached(assets_dir, asset_id)
    if meta is not None:
        return meta
    assets_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{asset_id}.", dir=assets_dir))
    try:
        meta = fill(tmp)
        (tmp / "meta.json").write_text(asset_meta_to_json(meta))
        try:
            os.rename(tmp, assets_dir / asset_id)
        except OSError:
            existing = cached(assets_dir, asset_id)
            if existing is None:
                raise
            return existing  # another process finished first
        return meta
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def write_obj(mesh: trimesh.Trimesh, path: Path, uv: np.ndarray | None = None) -> None:
    """A mesh as OBJ (9 significant digits): vertices and faces, and with ``uv`` (F, 3, 2)
    texture coordinates per face corner (``vt`` with their own indices, ``f v/vt``; the
    vertices stay shared, so the mesh stays watertight): :func:`factory.sim.lit_mesh.obj_lines`."""
    path.write_text(obj_lines(np.asarray(mesh.vertices), np.asarray(mesh.faces), uv))
