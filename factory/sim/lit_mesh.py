"""Visual meshes refined so that the factory's two renderers light them alike.

MuJoCo's OpenGL renderer (the CPU executor and the CPU env) lights a mesh at its vertices and
interpolates the colour across each triangle (fixed-function Gouraud shading); MuJoCo Warp's ray
tracer (the GPU executor and the Warp env) lights every ray's hit from the interpolated normal.
On a coarse mesh the two differ where the light changes across a triangle: curved surfaces lit
from the side (the normals at the corners differ), and large faces under a spot light or an
attenuated lamp (the light's direction and distance change across them). A camera policy
trained on one renderer's images then reads the other's worse (docs/POLICY.md, "Results
measured", 2026-11-30). :func:`refine_for_lighting` splits exactly those triangles' edges at
their midpoints until both conditions are small, and leaves flat small faces as they are, so the
cost is paid where the light changes; collision pieces are never touched.

The refinement is conforming (an edge is split for both triangles that share it: no cracks),
keeps the winding and the surface (new vertices lie on the old edges), carries per-corner
texture coordinates, and stops at a face budget. The compiler draws the refined copies
(:func:`lit_copy`, ``compile.light_mesh_edge``).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from factory.errors import CompileError

#: A vertex normal further than this from its face's normal is not used for shading (MuJoCo's
#: ``mjr_uploadMesh`` and MuJoCo Warp's ``vertex_normal`` both fall back to the face normal).
SMOOTH_LIMIT_DEG = 37.0


@dataclass(frozen=True)
class LightingRefinement:
    """How finely visual meshes are refined for lighting.

    Attributes:
        max_edge: longest edge kept (m): bounds the change of a spot or attenuated light's
            direction and distance across a triangle. ``0`` turns the length rule off.
        max_normal_deg: largest angle (degrees) between the shading normals at an edge's two
            ends: bounds the change of the normal across a curved surface's triangle. ``0``
            turns the curvature rule off.
        min_edge: shortest edge the curvature rule splits (m): below about a pixel of the
            policy's cameras a finer mesh changes nothing seen (and a crease's triangles would
            otherwise be split without end).
        max_faces: face budget per mesh; refinement stops before a round would exceed it.
    """

    max_edge: float = 0.15
    max_normal_deg: float = 8.0
    min_edge: float = 0.015
    max_faces: int = 60_000

    def __post_init__(self) -> None:
        if self.max_edge < 0 or self.max_normal_deg < 0:
            raise CompileError(
                f"LightingRefinement: max_edge ({self.max_edge}) and max_normal_deg "
                f"({self.max_normal_deg}) must be >= 0 (0 turns a rule off)"
            )
        if self.min_edge < 0:
            raise CompileError(f"LightingRefinement: min_edge must be >= 0, got {self.min_edge}")
        if self.max_faces < 1:
            raise CompileError(f"LightingRefinement: max_faces must be >= 1, got {self.max_faces}")

    @property
    def active(self) -> bool:
        """Whether any rule is on."""
        return self.max_edge > 0 or self.max_normal_deg > 0


def _shading_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The normal each face corner is shaded with: the area-weighted vertex normal, or the
    face's own where the two are more than :data:`SMOOTH_LIMIT_DEG` apart. Returns (F, 3, 3)."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], cross)
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-20)
    fn = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-20)
    corner = vn[faces]
    usable = np.einsum("fkd,fd->fk", corner, fn) >= np.cos(np.radians(SMOOTH_LIMIT_DEG))
    return np.where(usable[..., None], corner, fn[:, None, :])


def _edges_to_split(
    vertices: np.ndarray, faces: np.ndarray, spec: LightingRefinement
) -> np.ndarray:
    """(F, 3) bool: whether edge k of each face (corner k to corner k+1) is split this round,
    made consistent across the two faces that share it."""
    a = faces
    b = np.roll(faces, -1, axis=1)
    want = np.zeros(faces.shape, bool)
    length = np.linalg.norm(vertices[a] - vertices[b], axis=2)
    if spec.max_edge > 0:
        want |= length > spec.max_edge
    if spec.max_normal_deg > 0:
        n = _shading_normals(vertices, faces)
        cos = np.einsum("fkd,fkd->fk", n, np.roll(n, -1, axis=1))
        want |= (cos < np.cos(np.radians(spec.max_normal_deg))) & (length > spec.min_edge)
    key = np.sort(np.stack([a, b], axis=2), axis=2).reshape(-1, 2)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    split_edge = np.zeros(len(uniq), bool)
    np.logical_or.at(split_edge, inv.ravel(), want.ravel())
    return split_edge[inv.ravel()].reshape(faces.shape)


_TEMPLATES = {
    1: (("c0", "m0", "c2"), ("m0", "c1", "c2")),
    2: (("m0", "c1", "m1"), ("c0", "m0", "m1"), ("c0", "m1", "c2")),
    3: (("c0", "m0", "m2"), ("m0", "c1", "m1"), ("m2", "m1", "c2"), ("m0", "m1", "m2")),
}
"""A face's new triangles by how many of its edges are split (rotated so that edge 0 is split
for one, edge 2 kept for two): ``c<k>`` its corner k, ``m<k>`` the midpoint of its edge k
(corner k to k+1); counter-clockwise as the face."""


def _triangles(split: int, corners: np.ndarray, mids: np.ndarray) -> list[np.ndarray]:
    """The new triangles of :data:`_TEMPLATES` from per-face corner and midpoint values
    (``corners``, ``mids``: (n, 3, ...) vertex indices or texture coordinates), each (n, 3, ...)."""
    pick = {"c": corners, "m": mids}
    return [np.stack([pick[k[0]][:, int(k[1])] for k in tri], axis=1) for tri in _TEMPLATES[split]]


def _split_round(
    vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None, split: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One round: every marked edge split at its midpoint, each face re-triangulated by how
    many of its edges were split (1 -> 2, 2 -> 3, 3 -> 4 triangles)."""
    a = faces
    b = np.roll(faces, -1, axis=1)
    key = np.sort(np.stack([a, b], axis=2), axis=2).reshape(-1, 2)
    marked = key[split.ravel()]
    uniq, inv = np.unique(marked, axis=0, return_inverse=True)
    flat_mid = np.full(split.size, -1, np.int64)
    flat_mid[np.flatnonzero(split.ravel())] = len(vertices) + inv.ravel()
    mid_index = flat_mid.reshape(faces.shape)
    new_vertices = np.concatenate([vertices, vertices[uniq].mean(axis=1)])
    uv_mid = None if uv is None else 0.5 * (uv + np.roll(uv, -1, axis=1))  # (F, 3, 2)

    count = split.sum(axis=1)
    out_f: list[np.ndarray] = [faces[count == 0]]
    out_uv: list[np.ndarray] = [] if uv is None else [uv[count == 0]]
    for s in (1, 2, 3):
        idx = np.flatnonzero(count == s)
        if not len(idx):
            continue
        if s == 1:  # rotate so that edge 0 is the split one
            r = np.argmax(split[idx], axis=1)
        elif s == 2:  # rotate so that edge 2 is the one kept
            r = (np.argmin(split[idx], axis=1) + 1) % 3
        else:
            r = np.zeros(len(idx), np.int64)
        order = (np.arange(3)[None, :] + r[:, None]) % 3
        c = np.take_along_axis(faces[idx], order, axis=1)  # corners a, b, c
        m = np.take_along_axis(mid_index[idx], order, axis=1)  # m_ab, m_bc, m_ca
        out_f += _triangles(s, c, m)
        if uv is not None and uv_mid is not None:
            cu = np.take_along_axis(uv[idx], order[..., None], axis=1)
            mu = np.take_along_axis(uv_mid[idx], order[..., None], axis=1)
            out_uv += _triangles(s, cu, mu)
    new_uv = None if uv is None else np.concatenate(out_uv)
    return new_vertices, np.concatenate(out_f), new_uv


def refine_for_lighting(
    vertices: np.ndarray,
    faces: np.ndarray,
    uv: np.ndarray | None = None,
    spec: LightingRefinement | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """A visual mesh refined until both renderers light it alike (see the module's doc).

    Args:
        vertices: (V, 3) positions (m, asset frame).
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        uv: optional (F, 3, 2) texture coordinates per face corner.
        spec: the rules (default :class:`LightingRefinement()`).

    Returns:
        ``(vertices, faces, uv)``: the old vertices first and unchanged, new ones on the old
        edges' midpoints; ``uv`` is None when none was given.
    """
    spec = spec or LightingRefinement()
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    t = None if uv is None else np.asarray(uv, np.float64).reshape(-1, 3, 2)
    if not spec.active or not len(f):
        return v, f, t
    for _ in range(12):
        split = _edges_to_split(v, f, spec)
        count = split.sum(axis=1)
        if not count.any() or len(f) + int(count.sum()) > spec.max_faces:
            break
        v, f, t = _split_round(v, f, t, split)
    return v, f, t


def read_obj(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """An OBJ's ``v``, ``vt`` and ``f`` lines (polygons fanned into triangles; normals and
    materials ignored).

    Returns:
        ``(vertices (V, 3), faces (F, 3), uv (F, 3, 2) or None)``: texture coordinates per
        face corner when every face has them, None when none has.

    Raises:
        CompileError: the file is missing, has no faces, or only some faces have texture
            coordinates.
    """
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise CompileError(f"cannot read the mesh {path} ({e.strerror})") from None
    verts: list[list[float]] = []
    tex: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    corners: list[tuple[int, int, int]] = []
    untextured = 0
    for line in text.splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts[0] == "vt":
            tex.append([float(x) for x in parts[1:3]])
        elif parts[0] == "f":
            idx = [p.split("/") for p in parts[1:]]
            vi = [_index(int(i[0]), len(verts)) for i in idx]
            has_uv = all(len(i) >= 2 and i[1] for i in idx)
            ti = [_index(int(i[1]), len(tex)) for i in idx] if has_uv else [0] * len(idx)
            untextured += not has_uv
            for k in range(1, len(vi) - 1):
                faces.append((vi[0], vi[k], vi[k + 1]))
                corners.append((ti[0], ti[k], ti[k + 1]))
    if not faces:
        raise CompileError(f"{path} has no faces: a mesh asset needs triangles")
    if 0 < untextured < len(faces) and tex:
        raise CompileError(f"{path}: some faces have texture coordinates and some not")
    uv = np.asarray(tex, float)[np.asarray(corners)] if tex and not untextured else None
    return np.asarray(verts, float), np.asarray(faces, np.int64), uv


def _index(i: int, n: int) -> int:
    """An OBJ index (1-based, or negative from the end) as a 0-based one."""
    return i - 1 if i > 0 else n + i


def obj_lines(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None) -> str:
    """A mesh as OBJ text (9 significant digits): ``v`` and ``f`` lines, and with ``uv``
    (F, 3, 2) texture coordinates per face corner (``vt`` with their own indices, ``f v/vt``;
    the vertices stay shared, so the mesh stays watertight)."""
    v = np.asarray(vertices)
    f = np.asarray(faces) + 1
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v]
    if uv is None:
        lines += [f"f {a} {b} {c}" for a, b, c in f]
    else:
        flat = np.round(np.asarray(uv, float).reshape(-1, 2), 6)
        uniq, inv = np.unique(flat, axis=0, return_inverse=True)
        t = inv.reshape(-1, 3) + 1
        lines += [f"vt {a:.7g} {b:.7g}" for a, b in uniq]
        lines += [
            f"f {a}/{ta} {b}/{tb} {c}/{tc}"
            for (a, b, c), (ta, tb, tc) in zip(f.tolist(), t.tolist(), strict=True)
        ]
    return "\n".join(lines) + "\n"


def lit_copy(folder: Path, file: str, max_edge: float, scale: list[float] | None = None) -> str:
    """The name of ``folder/file``'s copy refined for lighting with edges up to ``max_edge``
    (m, after ``scale``), written beside it (atomically) on first use; ``file`` itself where
    no edge is longer. The curvature rule stays off: measured, it costs five times the faces
    and changes nothing seen (docs/POLICY.md, "Results measured", 2026-11-30)."""
    name = f"lit{round(max_edge * 1000)}mm-{Path(file).name}"
    target = folder / Path(file).parent / name
    if target.is_file():
        return str(Path(file).parent / name)
    vertices, faces, uv = read_obj(folder / file)
    s = np.asarray(scale if scale is not None else [1.0, 1.0, 1.0], float)
    spec = LightingRefinement(max_edge=max_edge, max_normal_deg=0.0)
    v, f, t = refine_for_lighting(vertices * s, faces, uv, spec)
    if len(f) == len(faces):
        return file
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "w") as out:
            out.write(obj_lines(v / s, f, t))
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return str(Path(file).parent / name)
