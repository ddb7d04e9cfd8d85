"""Texture coordinates of procedural parts, in metres (divide by a look's tile for UVs).

Every mapping keeps the texel the same size in metres on every face and every part, so a
texture never stretches from one face to the next (MuJoCo's ``texuniform`` for meshes):

* ``planar`` (boxes, panels, prisms and any flat-faced solid, extrusions included: caps and
  side strips): each face is projected onto its own plane, u horizontal and v up for walls,
  (x, y) for horizontal faces; the two are swapped per face so that v runs along the
  face's longer side (wood grain along a board or a leg). Exact: UV area = 3-D area.
* ``revolved`` (cylinders, frusta, hollow shells): bands are unrolled, u the arc length
  around each ring of vertices and v the length along the profile, both measured on the
  final mesh (so a revolved part scaled into an ellipse, a wall clock, still maps evenly);
  faces touching the axis (caps, vessel floors) are planar. The parts are labelled (section,
  profile point) when made, since the axis is not known afterwards.
* ``sphere`` (ellipsoids: fruit, balls, cushions of the toy bear): a cube projection by each
  face's dominant normal axis; UV area is 0.58 to 1 times the 3-D area.
* ``rounded`` (rounded boxes and cushions, :func:`.primitives.rounded_box`): each face belongs
  to the box face its normal leans to, and its rounded edges are unrolled onto that face (the
  arc length around the edge is added to the flat face's coordinate), so a table top's grain
  runs on over its rounded edge to the 45° line; exact on flat faces and edge strips, a little
  stretched at the spherical corners (worst face 1.07 x its part's median over the catalogue).

UVs are per face corner (F, 3, 2): a seam is just two corners with different UVs, and the OBJ
writer emits ``vt`` entries with their own indices, so the mesh stays watertight.
"""

from __future__ import annotations

import numpy as np
import trimesh

MAPPINGS = ("planar", "revolved", "sphere", "rounded")

STRETCH_BOUND = 1.8
"""Every face's UV-area / 3-D-area ratio lies within this factor of the part's median (the
cube projection's worst case is sqrt(3) = 1.73; planar and revolved faces are within 1 %)."""


def _normals(mesh: trimesh.Trimesh) -> np.ndarray:
    tri = mesh.triangles
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.maximum(length, 1e-15)


def planar_uv(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per-face planar UVs (F, 3, 2) in metres, v along each flat face's longer side."""
    tri = np.asarray(mesh.triangles, float)
    n = _normals(mesh)
    horizontal = np.abs(n[:, 2]) > 0.9
    up = np.array([0.0, 0.0, 1.0])
    tu = np.cross(np.broadcast_to(up, n.shape), n)
    tu_len = np.linalg.norm(tu, axis=1, keepdims=True)
    tu = np.where(horizontal[:, None], np.array([1.0, 0.0, 0.0]), tu / np.maximum(tu_len, 1e-15))
    tv = np.where(horizontal[:, None], np.array([0.0, 1.0, 0.0]), np.cross(n, tu))
    uv = np.stack([np.einsum("fkc,fc->fk", tri, tu), np.einsum("fkc,fc->fk", tri, tv)], axis=-1)
    # one flat face = the faces sharing a normal (and, for boxes, a plane)
    offset = np.einsum("fc,fc->f", tri[:, 0], n)
    keys = np.round(np.column_stack([n, offset]), 5)
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.reshape(-1)
    for g in np.unique(group):
        sel = group == g
        ext = np.ptp(uv[sel].reshape(-1, 2), axis=0)
        if ext[0] > ext[1] * 1.0001:
            uv[sel] = uv[sel][..., ::-1]
    return uv


def revolve_labels(mesh: trimesh.Trimesh, profile: np.ndarray, sections: int) -> np.ndarray:
    """Labels (V, 2) of a freshly revolved mesh's vertices: (section k, profile point j), with
    k = -1 for points on the axis. Made in the part's own frame (axis = z); they stay valid
    through any later move or scaling of the mesh (the vertices keep their order)."""
    v = np.asarray(mesh.vertices, float)
    r = np.hypot(v[:, 0], v[:, 1])
    theta = np.arctan2(v[:, 1], v[:, 0])
    k = np.round(theta / (2 * np.pi / sections)).astype(np.int64) % sections
    prof = np.asarray(profile, float)
    d = (r[:, None] - prof[None, :, 0]) ** 2 + (v[:, 2, None] - prof[None, :, 1]) ** 2
    j = np.argmin(d, axis=1)
    k[r < 1e-9] = -1
    return np.column_stack([k, j])


def revolved_uv(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Unrolled UVs (F, 3, 2) in metres of a (possibly scaled) surface of revolution.

    u is the arc length around each ring of vertices and v the length along the profile,
    both measured on the final mesh, so an ellipse-scaled cylinder (a wall clock) maps as
    evenly as a round one; faces touching the axis (cap and floor fans) are planar. A closed
    outline (a ring, :func:`.primitives.ring`) is unrolled past its last point back to its
    first.
    """
    pts3 = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces)
    k, j = labels[:, 0], labels[:, 1]
    n_sec = int(k.max()) + 1
    n_prof = int(j.max()) + 1
    vid = np.full((n_sec, n_prof), -1, np.int64)
    ring = k >= 0
    vid[k[ring], j[ring]] = np.nonzero(ring)[0]
    for idx in np.nonzero(~ring)[0]:  # an axis point is every section's
        vid[:, j[idx]] = idx
    uv = planar_uv(mesh)
    if (vid < 0).any():  # not a complete revolve: keep the planar mapping
        return uv
    pts = pts3[vid]  # (sections, profile points, 3)
    around = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=2)
    arc = np.vstack([np.zeros((1, n_prof)), np.cumsum(around, axis=0)])  # (sections + 1, J)
    along = np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=2).mean(axis=0)
    # one v per ring (the mean over sections): u shears from ring to ring, which keeps areas
    # only when each ring is a line of constant v
    prof = np.concatenate([[0.0], np.cumsum(along)])  # (J,)
    fk, fj = k[faces], j[faces]
    side = (fk >= 0).all(axis=1)
    ks, js = fk[side], fj[side]
    wraps = (ks.max(axis=1) - ks.min(axis=1)) > 1
    ks = np.where(wraps[:, None] & (ks == 0), n_sec, ks)
    closes = (js.max(axis=1) - js.min(axis=1)) > 1  # a closed outline (a ring) closing up
    if closes.any():
        js = np.where(closes[:, None] & (js == 0), n_prof, js)
        arc = np.hstack([arc, arc[:, :1]])
        shut = np.linalg.norm(pts[:, 0] - pts[:, -1], axis=1).mean()
        prof = np.append(prof, prof[-1] + shut)
    uv[side, :, 0] = arc[ks, js]
    uv[side, :, 1] = prof[js]
    return uv


def sphere_uv(mesh: trimesh.Trimesh) -> np.ndarray:
    """Cube-projection UVs (F, 3, 2) in metres by each face's dominant normal axis."""
    tri = np.asarray(mesh.triangles, float)
    axis = np.argmax(np.abs(_normals(mesh)), axis=1)
    pairs = np.array([[1, 2], [0, 2], [0, 1]])[axis]  # x-facing: (y, z); y: (x, z); z: (x, y)
    return np.take_along_axis(tri, pairs[:, None, :], axis=2)


def rounded_uv(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Unrolled UVs (F, 3, 2) in metres of a rounded box (:func:`.primitives.rounded_box`).

    ``labels`` (V, 13) hold each vertex's unit offset direction from the inner box and the
    rounding radius, in the box's own frame, and that frame's rotation into the mesh's frame
    (3 x 3, row-major; the same on every row), so a turned box maps as its unturned self.
    A face belongs to the box face D its vertices' directions lean to; each tangent axis A
    gets ``c_A + r * atan2(n_A, hypot(n_D, n_B))`` (c the inner-box point under the vertex):
    the flat coordinate plus the arc length around the edge. Walls have u horizontal and v
    up, tops (x, y); per box face, u and v are swapped
    so that v runs along the longer side, as :func:`planar_uv` does.
    """
    rot = np.asarray(labels[0, 4:13], float).reshape(3, 3)
    p = np.asarray(mesh.vertices, float) @ rot  # into the box's frame
    n = np.asarray(labels[:, :3], float)
    r = np.asarray(labels[:, 3], float)
    c = p - r[:, None] * n
    faces = np.asarray(mesh.faces)
    ns = n[faces].sum(axis=1)
    dom = np.argmax(np.abs(ns), axis=1)
    side = np.sign(ns[np.arange(len(faces)), dom])
    uv = np.zeros((len(faces), 3, 2))
    for d, (a, b) in ((2, (0, 1)), (0, (1, 2)), (1, (0, 2))):
        nd = np.abs(n[:, d])
        ua = c[:, a] + r * np.arctan2(n[:, a], np.hypot(nd, n[:, b]))
        ub = c[:, b] + r * np.arctan2(n[:, b], np.hypot(nd, n[:, a]))
        coords = np.column_stack([ua, ub])
        for sgn in (-1.0, 1.0):
            sel = (dom == d) & (side == sgn)
            if not sel.any():
                continue
            group = coords[faces[sel]]
            ext = np.ptp(group.reshape(-1, 2), axis=0)
            if ext[0] > ext[1] * 1.0001:
                group = group[..., ::-1]
            uv[sel] = group
    return uv


def uv_of(mesh: trimesh.Trimesh, mapping: str, labels: np.ndarray | None = None) -> np.ndarray:
    """The UVs (F, 3, 2, metres) of a part's final mesh by its mapping; a revolved part needs
    the vertex ``labels`` made with it (:func:`revolve_labels`)."""
    if mapping == "revolved" and labels is not None:
        if len(labels) != len(mesh.vertices):
            raise ValueError(
                f"revolve labels for {len(labels)} vertices, the mesh has {len(mesh.vertices)}"
            )
        return revolved_uv(mesh, labels)
    if mapping == "sphere":
        return sphere_uv(mesh)
    if mapping == "rounded" and labels is not None:
        if len(labels) != len(mesh.vertices):
            raise ValueError(
                f"rounded labels for {len(labels)} vertices, the mesh has {len(mesh.vertices)}"
            )
        return rounded_uv(mesh, labels)
    return planar_uv(mesh)


def stretch(mesh: trimesh.Trimesh, uv: np.ndarray) -> np.ndarray:
    """Per-face ratio UV area / 3-D area (NaN for faces without 3-D area)."""
    a3 = np.asarray(mesh.area_faces, float)
    e1 = uv[:, 1] - uv[:, 0]
    e2 = uv[:, 2] - uv[:, 0]
    a2 = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    out = np.full(len(a3), np.nan)
    ok = a3 > 1e-14
    out[ok] = a2[ok] / a3[ok]
    return out
