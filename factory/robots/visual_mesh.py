"""Simplified visual meshes for the robot cache: fewer triangles to draw, the same look.

robosuite's robot meshes are CAD exports: the Omron base's body has 66k faces in 480 pieces
(screws, slots, lettering), the Panda hand 7k, and the arm's parts up to 15k each, so the
robot is most of a scene's triangles and most of a camera's drawing time. The robot cache
(:func:`factory.robots.panda.export_mjcf`) writes each visual mesh through
:func:`simplify_visual_mesh`; collision meshes are copied unchanged.

The budget (:func:`face_budget`) is :data:`VISUAL_FACES` faces for a mesh up to
:data:`BUDGET_SIZE` across, proportionally more for a larger one. The simplification of a
mesh above its budget:

1. vertices are welded by position (an OBJ repeats a corner for each normal and texture
   coordinate, which leaves every face an island that no decimation can shrink) and
   degenerate faces dropped;
2. vertices are clustered on a 2 mm grid (:func:`cluster`): the CAD slivers (fillets,
   lettering, vent slots) on which edge collapses stall go, the shape stays;
3. quadric edge collapse (``fast_simplification``, in millimetres) reduces the mesh to the
   budget; where it stalls above it, steps 2-3 are repeated with a cell 1.5 times larger.

Quadric decimation alone, in metres as the cache did before, stalled at 11,600 of the Omron
body's faces and turned smooth links lumpy; clustering alone needs cells of 1-2 cm for the
budget, which shows on flat plates. Normals are not written: MuJoCo computes them and keeps
sharp edges sharp.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

VISUAL_FACES = 1000
"""Face budget of a simplified visual mesh up to :data:`BUDGET_SIZE` across; a larger mesh
gets proportionally more (:func:`face_budget`)."""

BUDGET_SIZE = 0.4
"""Bounding-box diagonal (m) up to which a mesh gets :data:`VISUAL_FACES` faces: every arm
link; the Omron base's body (0.9 m) gets 2,300, so that its bumpers and wheel covers stay
smooth, as the same error in pixels asks."""

SIMPLIFY_VERSION = 3
"""Bumped when the simplification changes, so that robot caches made before are rebuilt (it is
part of the cache directory's name, with :data:`VISUAL_FACES`)."""

CLUSTER_START = 0.002
"""Grid cell (m) of the vertex clustering before the quadric decimation: 2 mm, well below a
pixel of the demos' cameras (about 1 cm at 1 m for 128 px and 60 degrees)."""
CLUSTER_GROWTH = 1.5
"""Factor by which the clustering cell grows while the decimation stalls above the budget."""


@dataclass(frozen=True)
class SimplifiedMesh:
    """What :func:`simplify_visual_mesh` did to one mesh.

    Attributes:
        faces_in: faces of the source file.
        faces_out: faces written.
        cluster_cell: grid cell (m) of the vertex clustering, 0 where quadric decimation
            alone met the budget.
    """

    faces_in: int
    faces_out: int
    cluster_cell: float = 0.0


def weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merges vertices at the same position (to 1e-8 m) and drops faces left degenerate.

    Args:
        vertices: (V, 3) float positions (m); faces: (F, 3) int vertex indices.

    Returns:
        the welded (V', 3) float64 vertices and (F', 3) int64 faces (unused vertices removed).
    """
    v = np.asarray(vertices, np.float64)
    key = np.round(v * 1e8).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(faces, np.int64)]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    return _compact(v[first], f[keep])


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drops unreferenced vertices and renumbers the faces."""
    used, inverse = np.unique(faces.reshape(-1), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3).astype(np.int64)


def cluster(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering: vertices in one grid cell of size ``cell`` (m) become their mean;
    faces that collapse, and repeats of a face with the same winding, are dropped.

    Returns:
        (V', 3) float64 vertices and (F', 3) int64 faces.
    """
    v = np.asarray(vertices, np.float64)
    key = np.floor(v / cell).astype(np.int64)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    means = np.zeros((len(counts), 3))
    np.add.at(means, inverse, v)
    means /= counts[:, None]
    f = inverse[np.asarray(faces, np.int64)]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[keep]
    # a face and its repeats, in the same winding (both sides of a thin wall collapsed onto
    # each other stay: each is seen from its own side)
    first = np.argmin(f, axis=1)
    rolled = np.stack([f[np.arange(len(f)), (first + k) % 3] for k in range(3)], axis=1)
    _, unique = np.unique(rolled, axis=0, return_index=True)
    return _compact(means, f[np.sort(unique)])


def _decimate(
    vertices: np.ndarray, faces: np.ndarray, max_faces: int
) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge collapse towards ``max_faces`` faces (may stop above it).

    ``fast_simplification`` collapses every edge whose error is below an absolute threshold
    that grows per pass; in metres a robot part's errors are all below the first pass's
    threshold and edges collapse in no particular order (a smooth link ends up lumpy), so the
    mesh is decimated in millimetres.
    """
    import fast_simplification

    if len(faces) <= max_faces:
        return vertices, faces
    v, f = fast_simplification.simplify(
        np.asarray(vertices * 1000.0, np.float32),
        np.asarray(faces, np.int64),
        target_count=max_faces,
    )
    return weld(np.asarray(v, np.float64) / 1000.0, f)


def simplify_arrays(
    vertices: np.ndarray, faces: np.ndarray, max_faces: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """A mesh with at most ``max_faces`` faces (see the module docstring).

    Args:
        vertices: (V, 3) positions (m); faces: (F, 3) vertex indices.
        max_faces: the face budget (>= 4).

    Returns:
        vertices (V', 3) float64, faces (F', 3) int64 and the clustering cell used (m; 0 for
        a mesh within the budget, which is only welded).
    """
    source_v, source_f = weld(vertices, faces)
    if len(source_f) <= max_faces:
        return source_v, source_f, 0.0
    cell = CLUSTER_START
    while True:
        v, f = _decimate(*cluster(source_v, source_f, cell), max_faces)
        if len(f) <= max_faces:
            return v, f, cell
        cell *= CLUSTER_GROWTH


def face_budget(vertices: np.ndarray, max_faces: int = VISUAL_FACES) -> int:
    """Faces a mesh keeps: ``max_faces`` up to :data:`BUDGET_SIZE` across (bounding-box
    diagonal), proportionally more above it (a constant size of a face, so about the same
    error in pixels for every part)."""
    v = np.asarray(vertices, np.float64)
    diagonal = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if len(v) else 0.0
    return max(max_faces, round(max_faces * diagonal / BUDGET_SIZE))


def simplify_visual_mesh(
    src: str | Path, dst: Path, max_faces: int = VISUAL_FACES
) -> SimplifiedMesh:
    """Writes ``src`` (an OBJ or STL visual mesh) to ``dst`` with at most
    :func:`face_budget` faces (``max_faces`` for a mesh up to :data:`BUDGET_SIZE` across).

    The format follows ``dst``'s suffix (``.obj`` or ``.stl``, which MuJoCo reads by its
    name). A mesh within the budget is written welded but otherwise unchanged.

    Returns:
        the face counts and the clustering cell (m) used.
    """
    import trimesh

    mesh = trimesh.load(str(src), force="mesh", process=False)
    assert isinstance(mesh, trimesh.Trimesh)
    faces_in = len(mesh.faces)
    v, f, cell = simplify_arrays(mesh.vertices, mesh.faces, face_budget(mesh.vertices, max_faces))
    out = trimesh.Trimesh(v, f, process=False)
    if dst.suffix.lower() == ".stl":
        dst.write_bytes(trimesh.exchange.stl.export_stl(out))
    else:
        dst.write_text(trimesh.exchange.obj.export_obj(out, include_normals=False))
    if cell:
        log.debug(
            "%s: %d -> %d faces (clustered at %.1f mm)", dst.name, faces_in, len(f), cell * 1e3
        )
    return SimplifiedMesh(faces_in, len(f), cell)
