"""Turning an arbitrary mesh into a simulation asset (mesh-library and text-to-3D backends).

Steps: load (GLB/OBJ/PLY/STL via trimesh) and check it has faces; merge duplicate vertices,
drop degenerate faces, fill holes, fix normals; decimate above ``max_faces``
(fast-simplification); rotate y-up files to z-up if asked; scale to the requested height or
dimensions and move it into the object frame (centred in x and y, bottom at z = 0); convex
decomposition with CoACD (hulls of at most 64 vertices).
"""

from __future__ import annotations

import io
import logging
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from factory.assets.geometry import MAX_HULL_VERTICES
from factory.assets.procedural import AssetError

log = logging.getLogger(__name__)


def load_mesh(source: str | Path | bytes, file_type: str | None = None) -> trimesh.Trimesh:
    """Loads a mesh file (or bytes with ``file_type``) as one triangle mesh.

    Raises:
        AssetError: not a mesh, or a mesh without faces.
    """
    try:
        if isinstance(source, bytes):
            loaded = trimesh.load(
                io.BytesIO(source), file_type=file_type, force="mesh", process=False
            )
        else:
            loaded = trimesh.load(str(source), force="mesh", process=False)
    except Exception as e:  # trimesh raises many types on garbage
        name = "the data" if isinstance(source, bytes) else str(source)
        raise AssetError(f"{name} is not a readable mesh ({type(e).__name__}: {e})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        name = "the data" if isinstance(source, bytes) else str(source)
        raise AssetError(f"{name} has no faces: a mesh asset needs triangles")
    return loaded


def repair(mesh: trimesh.Trimesh, max_faces: int = 20000) -> trimesh.Trimesh:
    """Merges vertices, removes degenerate faces, fills holes, fixes normals, decimates."""
    m = mesh.copy()
    m.merge_vertices()
    m.update_faces(m.nondegenerate_faces())
    m.remove_unreferenced_vertices()
    if len(m.faces) > max_faces:
        try:
            m = m.simplify_quadric_decimation(face_count=max_faces)
        except Exception as e:  # pragma: no cover - optional dependency missing
            log.warning("decimation failed (%s); keeping %d faces", e, len(m.faces))
    trimesh.repair.fill_holes(m)
    trimesh.repair.fix_normals(m)
    return m


def to_object_frame(
    mesh: trimesh.Trimesh,
    height: float | None = None,
    dims: tuple[float, float, float] | None = None,
    y_up: bool = False,
) -> trimesh.Trimesh:
    """Scales (to ``dims`` per axis, or uniformly to ``height``) and moves the mesh so it is
    centred in x and y with its bottom at z = 0."""
    m = mesh.copy()
    if y_up:
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    ext = m.extents
    if np.any(ext <= 0):
        raise AssetError("the mesh is flat (zero extent along an axis)")
    if dims is not None:
        m.apply_scale(np.asarray(dims, float) / ext)
    elif height is not None:
        m.apply_scale(float(height) / ext[2])
    lo, hi = m.bounds
    m.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return m


def decompose(
    mesh: trimesh.Trimesh, threshold: float = 0.08, max_parts: int = 24, seed: int = 0
) -> list[trimesh.Trimesh]:
    """Approximate convex decomposition with CoACD; every part has <= 64 vertices."""
    import coacd

    coacd.set_log_level("error")
    cm = coacd.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, int))
    kwargs: dict[str, Any] = {
        "threshold": threshold,
        "max_convex_hull": max_parts,
        "max_ch_vertex": MAX_HULL_VERTICES,
        "decimate": True,
        "seed": seed,
    }
    parts = coacd.run_coacd(cm, **kwargs)
    hulls = []
    for verts, faces in parts:
        hull = trimesh.Trimesh(verts, faces).convex_hull
        if len(hull.vertices) > MAX_HULL_VERTICES:
            hull = reduce_hull(hull)
        hulls.append(hull)
    if not hulls:
        raise AssetError("convex decomposition produced no parts")
    return hulls


def reduce_hull(hull: trimesh.Trimesh) -> trimesh.Trimesh:
    """Keeps the hull's 64 most spread vertices (farthest-point sampling), re-hulled."""
    v = np.asarray(hull.vertices)
    idx = [int(np.argmax(np.linalg.norm(v - v.mean(0), axis=1)))]
    d = np.linalg.norm(v - v[idx[0]], axis=1)
    while len(idx) < MAX_HULL_VERTICES:
        i = int(np.argmax(d))
        idx.append(i)
        d = np.minimum(d, np.linalg.norm(v - v[i], axis=1))
    return trimesh.Trimesh(v[idx]).convex_hull
