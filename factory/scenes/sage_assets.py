"""SAGE's per-object meshes in the run's asset cache, and SAGE packages written back out.

A SAGE mesh is a PLY file (``vertex``: x, y, z; ``face``: ``vertex_indices``; UVs either per
vertex as ``u``/``v`` or ``s``/``t``, or as a separate ``texcoord`` element with per-face
``texcoord_indices``) plus ``<source_id>_texture.png``. Import stores the original bytes
(``source.ply``, ``texture.png``) and a MuJoCo-loadable ``visual.obj`` under
``assets/sage-<sha256 prefix>/``; the folder is built aside and renamed into place, so two
processes importing the same mesh leave one intact copy.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import StoreError
from factory.schema import AssetMeta, Scene, SchemaError
from factory.schema.asset import asset_meta_to_json, load_asset_meta
from factory.schema.sage import scene_to_sage
from factory.store import RunStore, atomic_copy, atomic_write_text, sha256_bytes

log = logging.getLogger(__name__)

ARTICULATION_SUFFIX = ".articulation.json"
"""Name ending of the side file :func:`export_sage` writes beside ``<id>.json`` for a scene with
joint states (SAGE's layout has no place for them)."""

ARTICULATION_SCHEMA_VERSION = 1
"""``schema_version`` of that side file."""


def read_ply(
    path: str | Path,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Reads a (SAGE) PLY mesh.

    Returns:
        ``(vertices (n, 3) float, faces (m, 3) int, uv (k, 2) float or None,
        face_uv (m, 3) int or None)``; polygons are fan-triangulated.

    Raises:
        SchemaError: not a PLY file, or no vertices/faces.
    """
    from plyfile import PlyData, PlyHeaderParseError

    try:
        ply = PlyData.read(str(path))
    except (PlyHeaderParseError, ValueError, OSError, IndexError) as e:
        raise SchemaError(f"{path} is not a readable PLY mesh ({e})") from None
    names = {el.name for el in ply.elements}
    if "vertex" not in names or "face" not in names or ply["face"].count == 0:
        raise SchemaError(f"{path}: a mesh needs 'vertex' and non-empty 'face' elements")
    vert = ply["vertex"].data
    vertices = np.stack([vert["x"], vert["y"], vert["z"]], axis=1).astype(np.float64)
    face = ply["face"].data
    fprops = face.dtype.names or ()
    vi_name = "vertex_indices" if "vertex_indices" in fprops else "vertex_index"
    polys = face[vi_name]
    tc_polys = face["texcoord_indices"] if "texcoord_indices" in fprops else None
    tris, tc_tris = [], []
    for i, poly in enumerate(polys):
        for k in range(1, len(poly) - 1):
            tris.append((poly[0], poly[k], poly[k + 1]))
            if tc_polys is not None:
                tp = tc_polys[i]
                tc_tris.append((tp[0], tp[k], tp[k + 1]))
    faces = np.asarray(tris, dtype=np.int64)
    if faces.size == 0 or faces.max() >= len(vertices) or faces.min() < 0:
        raise SchemaError(f"{path}: faces index vertices that do not exist")
    uv: np.ndarray | None = None
    face_uv: np.ndarray | None = None
    vprops = vert.dtype.names or ()
    if "texcoord" in names and tc_polys is not None:
        tc = ply["texcoord"].data
        tprops = tc.dtype.names or ()
        a, b = ("u", "v") if "u" in tprops else ("s", "t")
        uv = np.stack([tc[a], tc[b]], axis=1).astype(np.float64)
        face_uv = np.asarray(tc_tris, dtype=np.int64)
    elif {"u", "v"} <= set(vprops) or {"s", "t"} <= set(vprops):
        a, b = ("u", "v") if "u" in vprops else ("s", "t")
        uv = np.stack([vert[a], vert[b]], axis=1).astype(np.float64)
        face_uv = faces.copy()
    return vertices, faces, uv, face_uv


def obj_text(
    vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None, face_uv: np.ndarray | None
) -> str:
    """Wavefront OBJ text (1-based indices; ``f v/vt`` when UVs are given)."""
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    if uv is not None and face_uv is not None:
        lines += [f"vt {u:.9g} {v:.9g}" for u, v in uv]
        lines += [
            f"f {a + 1}/{ta + 1} {b + 1}/{tb + 1} {c + 1}/{tc + 1}"
            for (a, b, c), (ta, tb, tc) in zip(faces, face_uv, strict=True)
        ]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def import_sage_mesh(store: RunStore, ply: Path, texture: Path | None, license: str) -> str:
    """Puts one SAGE mesh (+ texture) into the run's asset cache.

    Returns:
        the asset id (``sage-<16 hex>``, from the content of the PLY and texture).

    Raises:
        SchemaError: the PLY is not a usable mesh.
    """
    ply_bytes = ply.read_bytes()
    tex_bytes = texture.read_bytes() if texture is not None else b""
    asset_id = "sage-" + sha256_bytes(ply_bytes + b"\0" + tex_bytes)[:16]
    final = store.asset_dir(asset_id)
    if (final / "meta.json").is_file():
        try:
            load_asset_meta(final)
            return asset_id
        except SchemaError:
            log.warning("asset %s is damaged; rebuilding it", asset_id)
            shutil.rmtree(final, ignore_errors=True)
    vertices, faces, uv, face_uv = read_ply(ply)
    store.assets_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{asset_id}.", dir=store.assets_dir))
    try:
        (tmp / "source.ply").write_bytes(ply_bytes)
        if texture is not None:
            (tmp / "texture.png").write_bytes(tex_bytes)
        (tmp / "visual.obj").write_text(obj_text(vertices, faces, uv, face_uv))
        ext = vertices.max(axis=0) - vertices.min(axis=0)
        meta = AssetMeta(
            asset_id=asset_id,
            backend="sage",
            visual="visual.obj",
            texture="texture.png" if texture is not None and uv is not None else None,
            extents=[float(e) for e in ext],
            license=license,
            provenance={
                "source_file": ply.name,
                "source_sha256": sha256_bytes(ply_bytes),
                "texture_file": texture.name if texture is not None else None,
                "texture_sha256": sha256_bytes(tex_bytes) if texture is not None else None,
                "importer": "factory.scenes.sage_assets",
            },
        )
        (tmp / "meta.json").write_text(asset_meta_to_json(meta))
        try:
            os.rename(tmp, final)
        except OSError:
            if not (final / "meta.json").is_file():
                raise
            # Another process put the same asset in place first: keep theirs.
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return asset_id


def articulation_record(scene: Scene) -> dict[str, Any] | None:
    """The side file's content for ``scene``: ``{schema_version, objects: {object id:
    {asset_id, joint_states}}}`` over the objects with joint states (rad or m, 0 = closed),
    or ``None`` when no object has any."""
    objects = {
        o.id: {
            "asset_id": o.asset.asset_id if o.asset is not None else "",
            "joint_states": dict(o.joint_states),
        }
        for o in scene.objects
        if o.joint_states
    }
    if not objects:
        return None
    return {"schema_version": ARTICULATION_SCHEMA_VERSION, "objects": objects}


def export_sage(scene: Scene, store: RunStore | None, out_dir: str | Path) -> Path:
    """Writes a packed SAGE scene: ``<id>.json`` and ``objects/<source_id>.ply/_texture.png``.

    Meshes are the original bytes kept at import; objects without a SAGE mesh are written as
    layout entries only. SAGE's layout has no joints: an articulated object is a layout entry
    like any other (SAGE sees one rigid object of its closed dimensions), and the objects' joint
    states go to a side file ``<id>.articulation.json`` (:func:`articulation_record`; written
    only when some object has joint states). Returns the layout JSON's path.
    """
    out = Path(out_dir)
    layout = scene_to_sage(scene)
    for obj in scene.objects:
        a = obj.asset
        if a is None or not a.asset_id or store is None:
            continue
        folder = store.asset_dir(a.asset_id)
        sid = a.source_id or a.asset_id
        if (folder / "source.ply").is_file():
            atomic_copy(folder / "source.ply", out / "objects" / f"{sid}.ply")
            if (folder / "texture.png").is_file():
                atomic_copy(folder / "texture.png", out / "objects" / f"{sid}_texture.png")
        elif not folder.is_dir():
            raise StoreError(f"object {obj.id!r}: asset folder {folder} is missing")
    path = out / f"{scene.id}.json"
    atomic_write_text(path, json.dumps(layout, indent=2, ensure_ascii=False) + "\n")
    side = out / f"{scene.id}{ARTICULATION_SUFFIX}"
    record = articulation_record(scene)
    if record is not None:
        atomic_write_text(side, json.dumps(record, indent=2, ensure_ascii=False) + "\n")
    elif side.is_file():
        side.unlink()  # an earlier export of this scene had joint states
    return path


__all__ = [
    "ARTICULATION_SCHEMA_VERSION",
    "ARTICULATION_SUFFIX",
    "articulation_record",
    "export_sage",
    "import_sage_mesh",
    "obj_text",
    "read_ply",
]
