"""Textured real meshes: OBJ files with texture coordinates, read exactly, and assets built
from a textured mesh-library entry.

A textured entry (``metadata.json`` of a mesh library, e.g. the one
:mod:`factory.assets.packaged` imports from robosuite) names a visual OBJ with ``vt`` texture
coordinates in the object frame (z up, centred in x and y, bottom at z = 0, metres), its
texture image, its convex collision hulls (<= 64 vertices each, same frame) and its effective
density. An asset is that entry scaled per axis (size words of the request: "a small can" is
0.78 of the package's can): affine scaling keeps hulls convex and UVs valid, so nothing is
recomputed, only rewritten.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.assets.geometry import MAX_HULL_VERTICES
from factory.assets.procedural import AssetError
from factory.errors import CompileError
from factory.schema import AssetMeta
from factory.sim.lit_mesh import read_obj

log = logging.getLogger(__name__)


@dataclass
class UVMesh:
    """A triangle mesh with texture coordinates per face corner.

    Attributes:
        vertices: (V, 3) positions (m), shared by faces (a closed mesh stays watertight).
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        uv: (F, 3, 2) texture coordinates of each face corner (OBJ convention: v up).
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray

    def trimesh(self) -> Any:
        """The geometry as a ``trimesh.Trimesh`` (no processing: indices kept)."""
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False)


def read_obj_uv(path: str | Path) -> UVMesh:
    """Reads an OBJ's ``v``, ``vt`` and ``f`` lines (polygons fanned into triangles; normals
    and materials ignored; :func:`factory.sim.lit_mesh.read_obj`).

    Raises:
        AssetError: the file is missing, has no faces, or a face lacks texture coordinates.
    """
    try:
        vertices, faces, uv = read_obj(path)
    except CompileError as e:
        raise AssetError(str(e)) from None
    if uv is None:
        raise AssetError(f"{path}: a face has no texture coordinates (f v/vt expected)")
    return UVMesh(vertices, faces, uv)


def clean(mesh: UVMesh, tol: float = 1e-7) -> UVMesh:
    """Merges vertices closer than ``tol`` (m), drops faces without area and unused vertices;
    texture coordinates stay with their face corners."""
    key = np.round(mesh.vertices / tol).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    faces = inv.reshape(-1)[mesh.faces]
    v = mesh.vertices[first]
    tri = v[faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    distinct = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    keep = distinct & (area > tol * tol)
    faces, uv = faces[keep], mesh.uv[keep]
    used = np.unique(faces)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    return UVMesh(v[used], remap[faces], uv)


def to_object_frame(mesh: UVMesh, scale: tuple[float, float, float]) -> UVMesh:
    """Scales the mesh per axis (``scale``, e.g. a package's ``<mesh scale>``) and moves it so
    it is centred in x and y with its bottom at z = 0 (z up stays up)."""
    v = mesh.vertices * np.asarray(scale, float)
    lo, hi = v.min(0), v.max(0)
    v = v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return UVMesh(v, mesh.faces.copy(), mesh.uv.copy())


def volume(mesh: UVMesh, hulls: list[Any]) -> float:
    """The enclosed volume (m³): the mesh's own when it is watertight, else the hulls' sum."""
    tm = mesh.trimesh()
    if tm.is_watertight:
        return float(abs(tm.volume))
    return float(sum(h.volume for h in hulls))


def build_textured_asset(
    library_dir: Path,
    entry: dict[str, Any],
    factors: tuple[float, float, float],
    folder: Path,
    asset_id: str,
    backend: str,
    request: dict[str, Any],
) -> AssetMeta:
    """Writes the asset of a textured mesh-library ``entry`` scaled per axis by ``factors``
    into ``folder``: ``visual.obj`` (geometry), ``visual_0.obj`` (with UVs), the texture (a
    hard link), ``collision_<k>.obj`` (the entry's hulls, scaled) and its licence text.

    Raises:
        AssetError: a file of the entry is missing or malformed, or a hull has more than 64
            vertices.
    """
    from factory.assets.cache import write_obj
    from factory.assets.meshproc import load_mesh
    from factory.assets.physics import material
    from factory.textures.cache import link_or_copy

    f = np.asarray(factors, float)
    src = read_obj_uv(library_dir / str(entry["file"]))
    mesh = UVMesh(src.vertices * f, src.faces, src.uv)
    tm = mesh.trimesh()
    write_obj(tm, folder / "visual.obj")
    write_obj(tm, folder / "visual_0.obj", mesh.uv)
    tex = Path(str(entry["texture"]))
    if not (library_dir / tex).is_file():
        raise AssetError(f"mesh library {library_dir}: texture {tex} of {entry['file']} is missing")
    link_or_copy(library_dir / tex, folder / tex.name)
    collision = []
    hulls = []
    for k, name in enumerate(entry.get("collision", [])):
        hull = load_mesh(library_dir / name)
        hull.vertices = np.asarray(hull.vertices) * f
        if len(hull.vertices) > MAX_HULL_VERTICES:
            raise AssetError(
                f"{library_dir / name} has {len(hull.vertices)} vertices; collision hulls take "
                f"at most {MAX_HULL_VERTICES}: re-import the library"
            )
        write_obj(hull, folder / f"collision_{k}.obj")
        collision.append(f"collision_{k}.obj")
        hulls.append(hull)
    if entry.get("license_file") and (library_dir / entry["license_file"]).is_file():
        link_or_copy(library_dir / entry["license_file"], folder / "LICENSE.txt")
    mat_name = str(entry.get("material", "plastic"))
    mat = material(mat_name)
    vol = volume(mesh, hulls)
    ext = tm.extents
    finish = entry.get("finish", {})
    part = {
        "file": "visual_0.obj",
        "name": str(entry.get("name", "body")),
        "parts": ["body"],
        "material": mat_name,
        "rgba": [1.0, 1.0, 1.0, 1.0],
        "metallic": float(finish.get("metallic", mat.metallic)),
        "roughness": float(finish.get("roughness", mat.roughness)),
        "texture": tex.name,
        "texture_gain": [1.0, 1.0, 1.0],
        "tinted": False,
        "look": str(entry.get("look", tex.name)),
        "weathering": [],
        "specular": float(finish.get("specular", 0.5)),
        "shininess": float(finish.get("shininess", 0.5)),
        "reflectance": float(finish.get("reflectance", 0.0)),
    }
    provenance = dict(entry.get("provenance", {}))
    provenance |= {"library_entry": entry.get("name", entry["file"]), "scale": f.tolist()}
    return AssetMeta(
        asset_id=asset_id,
        backend=backend,
        visual="visual.obj",
        extents=[float(v) for v in ext],
        collision=collision,
        license=str(entry.get("license", "unknown")),
        provenance=provenance,
        category=str(entry.get("category", "")),
        visual_parts=[part],
        supports=_top(ext) if entry.get("flat_top") else [],
        mass=vol * float(entry.get("density", mat.density)),
        friction=mat.friction,
        materials=[mat_name, mat_name],
        request=request,
    )


def _top(ext: np.ndarray) -> list[dict[str, Any]]:
    """A support on the flat top, inset to the middle 70 % (a can's lid inside its rim)."""
    hx, hy = 0.35 * float(ext[0]), 0.35 * float(ext[1])
    return [{"name": "top", "z": float(ext[2]), "rect": [-hx, -hy, hx, hy]}]


__all__ = ["UVMesh", "build_textured_asset", "clean", "read_obj_uv", "to_object_frame", "volume"]
