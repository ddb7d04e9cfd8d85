"""Shaped parts for procedural assets: rounded and bevelled boxes, cushions, solids and rings
of revolution, pleated panels, and moving a part.

Like :mod:`.geometry`'s parts, each has a watertight visual mesh and a collision of convex
pieces of at most :data:`~.geometry.MAX_HULL_VERTICES` vertices. A rounded box keeps its box
as collision (the rounding only trims the edges), so supports and rest heights stay those of
the box; solids of revolution are covered by one convex frustum per profile band, or by the
hull of the profile; rings by convex sectors. Units are metres, in the object frame (z up).
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from factory.assets.geometry import MAX_HULL_VERTICES, Part
from factory.assets.uv import revolve_labels

RGBA = tuple[float, float, float, float]


def _axis_coords(half: float, r: float, segments: int, flat: int) -> np.ndarray:
    """Grid coordinates along one axis of a rounded box: ``segments`` steps through each
    rounded zone (spaced so that the normals turn by equal angles, 45° per zone) and ``flat``
    cells over the flat middle."""
    inner = half - r
    zone = inner + r * np.tan(np.linspace(0.0, math.pi / 4, segments + 1))
    zone[-1] = half
    mid = np.linspace(-inner, inner, flat + 1)
    return np.concatenate([-zone[::-1], mid[1:-1], zone])


def _subdivided_box(half: np.ndarray, coords: list[np.ndarray]) -> trimesh.Trimesh:
    """The surface of the box ``[-half, half]`` as a grid over each face (outward faces)."""
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    base = 0
    for d, (a, b) in ((2, (0, 1)), (0, (1, 2)), (1, (2, 0))):
        ca, cb = coords[a], coords[b]
        ga, gb = np.meshgrid(ca, cb, indexing="ij")
        na, nb = len(ca), len(cb)
        idx = np.arange(na * nb).reshape(na, nb)
        q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
        for sign in (1.0, -1.0):
            p = np.zeros((na * nb, 3))
            p[:, a], p[:, b], p[:, d] = ga.ravel(), gb.ravel(), sign * half[d]
            tri = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
            if sign < 0:
                tri = tri[:, ::-1]
            verts.append(p)
            faces.append(tri + base)
            base += len(p)
    mesh = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)
    mesh.merge_vertices()
    return mesh


def rounded_box(
    extents: tuple[float, float, float],
    center: tuple[float, float, float],
    material: str,
    rgba: RGBA,
    radius: float,
    name: str = "box",
    fill: float = 1.0,
    segments: int = 2,
    bulge: float = 0.0,
    flat: int = 1,
    collide: bool = True,
) -> Part:
    """A box of ``extents`` (m) centred at ``center`` whose edges and corners are rounded with
    ``radius`` (m; capped at 45 % of the smallest extent), ``segments`` steps per 45° of each
    rounding (1: a bevel-like round, 2: smooth).

    ``bulge`` (m) crowns the top and bottom faces (a cushion): their middles rise by ``bulge``
    and their rims stay put, within the same extents; ``flat`` cells across the flat middle
    give the crown its curvature (set to 4 or more with a bulge). The bounding box equals the
    requested box exactly, and the collision is that box (``collide=False``: none, for a
    visual detail that lies inside another part's collision). UVs: the ``rounded`` mapping
    (:func:`.uv.rounded_uv`), which unrolls each rounded edge onto the face it belongs to.
    """
    ext = np.asarray(extents, float)
    half = ext / 2
    r = float(min(radius, 0.45 * ext.min()))
    body = half.copy()
    body[2] -= bulge
    r = min(r, 0.9 * float(body.min()))
    if r <= 0 or bulge < 0 or bulge >= half[2] - r:
        raise ValueError(f"rounded_box {name}: radius {radius} / bulge {bulge} do not fit {ext}")
    n_flat = max(flat, 2 if bulge else 1)
    n_flat += n_flat % 2 if bulge else 0  # a vertex in the middle for the crown's top
    coords = [_axis_coords(float(h), r, segments, n_flat) for h in body]
    mesh = _subdivided_box(body, coords)
    p = np.asarray(mesh.vertices, float)
    inner = body - r
    c = np.clip(p, -inner, inner)
    off = p - c
    n = off / np.linalg.norm(off, axis=1, keepdims=True)
    p = c + r * n
    if bulge:
        fx = np.clip(1 - (p[:, 0] / body[0]) ** 2, 0, 1)
        fy = np.clip(1 - (p[:, 1] / body[1]) ** 2, 0, 1)
        p[:, 2] += np.sign(n[:, 2]) * (np.abs(n[:, 2]) > 1e-9) * bulge * fx * fy
    mesh = trimesh.Trimesh(p + np.asarray(center, float), mesh.faces, process=False)
    labels = np.column_stack([n, np.full(len(p), r), np.tile(np.eye(3).ravel(), (len(p), 1))])
    collision = [trimesh.creation.box(extents=ext).apply_translation(center)] if collide else []
    return Part(mesh, collision, material, rgba, fill, name, "rounded", labels)


def moved(part: Part, matrix: np.ndarray) -> Part:
    """The part moved by the rigid 4x4 ``matrix`` (visual, collision, and the frame kept in a
    rounded part's labels); returns the same part."""
    part.visual.apply_transform(matrix)
    for c in part.collision:
        c.apply_transform(matrix)
    if part.mapping == "rounded" and part.labels is not None:
        rot = np.asarray(matrix, float)[:3, :3] @ part.labels[0, 4:13].reshape(3, 3)
        part.labels = part.labels.copy()
        part.labels[:, 4:13] = rot.ravel()
    return part


def _profile_hull(profile: np.ndarray) -> np.ndarray:
    """The convex hull (counter-clockwise) of 2-D points (r, z), monotone chain."""
    pts = sorted({(round(float(a), 12), round(float(b), 12)) for a, b in profile})

    def cross(o: tuple, a: tuple, b: tuple) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple] = []
    upper: list[tuple] = []
    for pt in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], pt) <= 0:
            lower.pop()
        lower.append(pt)
    for pt in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], pt) <= 0:
            upper.pop()
        upper.append(pt)
    return np.array(lower[:-1] + upper[:-1], float)


def _ring_points(rz: np.ndarray, sections: int) -> np.ndarray:
    a = np.linspace(0, 2 * math.pi, sections, endpoint=False)
    out: list[np.ndarray] = []
    for r, z in rz:
        if r <= 1e-12:
            out.append(np.array([[0.0, 0.0, z]]))
        else:
            out.append(np.column_stack([r * np.cos(a), r * np.sin(a), np.full(sections, z)]))
    return np.concatenate(out)


def _hull_of_profile(rz: np.ndarray, sections: int) -> trimesh.Trimesh:
    """The convex hull of the solid of revolution of ``rz`` (the revolve of its 2-D hull),
    with at most :data:`MAX_HULL_VERTICES` vertices."""
    hull2 = _profile_hull(np.vstack([rz, [[0.0, rz[:, 1].min()], [0.0, rz[:, 1].max()]]]))
    rim = hull2[hull2[:, 0] > 1e-12]
    while len(rim) * 6 > MAX_HULL_VERTICES - 2:  # too many profile points: keep the widest
        rim = np.delete(rim, int(np.argmin(rim[:, 0])), axis=0)
    sec = max(6, min(sections, (MAX_HULL_VERTICES - 2) // max(1, len(rim))))
    axis = hull2[hull2[:, 0] <= 1e-12]
    hull = trimesh.Trimesh(_ring_points(np.vstack([rim, axis]), sec)).convex_hull
    return hull


def revolved(
    profile: list[tuple[float, float]],
    material: str,
    rgba: RGBA,
    z0: float = 0.0,
    xy: tuple[float, float] = (0.0, 0.0),
    sections: int = 24,
    name: str = "revolved",
    fill: float = 1.0,
    collision: str = "bands",
) -> Part:
    """A solid of revolution about the vertical axis through ``xy``: ``profile`` is the outer
    outline (radius, height) from bottom to top (heights not decreasing, m; the axis is added
    at both ends), e.g. a lamp base, a vase-like lamp body or a flared pot.

    Collision: ``bands``, one convex frustum per profile segment (exact for the faceted
    solid: the union is the solid), or ``hull``, the convex hull of the whole (one piece; for
    shapes whose inside nobody reaches, a lamp shade).
    """
    rz = np.asarray(profile, float)
    if np.any(np.diff(rz[:, 1]) < -1e-12):
        raise ValueError(f"revolved {name}: the profile's heights must not decrease")
    full = np.vstack([[0.0, rz[0, 1]], rz, [0.0, rz[-1, 1]]])
    mesh = trimesh.creation.revolve(full, sections=sections)
    labels = revolve_labels(mesh, full, sections)
    shift = np.array([xy[0], xy[1], z0])
    mesh.apply_translation(shift)
    pieces: list[trimesh.Trimesh] = []
    if collision == "hull":
        pieces.append(_hull_of_profile(rz, sections).apply_translation(shift))
    else:
        sec = min(sections, MAX_HULL_VERTICES // 2)
        for k in range(len(rz) - 1):
            band = rz[k : k + 2]
            if band[1, 1] - band[0, 1] < 1e-9 or band[:, 0].max() < 1e-9:
                continue
            hull = trimesh.Trimesh(_ring_points(band, sec)).convex_hull
            pieces.append(hull.apply_translation(shift))
    return Part(mesh, pieces, material, rgba, fill, name, "revolved", labels)


def ring(
    profile: list[tuple[float, float]],
    material: str,
    rgba: RGBA,
    z0: float = 0.0,
    xy: tuple[float, float] = (0.0, 0.0),
    segments: int = 12,
    name: str = "ring",
    fill: float = 1.0,
) -> Part:
    """A closed ring about the vertical axis (a toilet seat, a clock's rim, a pot's lip):
    ``profile`` is a closed outline (radius, height) that does not touch the axis, counter-
    clockwise. Collision: ``segments`` convex sectors, each the hull of the outline at three
    angles (exact up to the chord of a sector)."""
    rz = np.asarray(profile, float)
    if rz[:, 0].min() <= 0:
        raise ValueError(f"ring {name}: the outline must stay off the axis")
    closed = np.vstack([rz, rz[:1]])
    sections = 4 * segments
    mesh = trimesh.creation.revolve(closed, sections=sections)
    labels = revolve_labels(mesh, closed, sections)
    if mesh.volume < 0:  # a clockwise outline: turn the faces outward
        mesh.invert()
    shift = np.array([xy[0], xy[1], z0])
    mesh.apply_translation(shift)
    if len(rz) * 3 > MAX_HULL_VERTICES:
        raise ValueError(f"ring {name}: at most {MAX_HULL_VERTICES // 3} outline points")
    pieces = []
    for k in range(segments):
        a0, a1 = 2 * math.pi * k / segments, 2 * math.pi * (k + 1) / segments
        pts = [
            [r * math.cos(a), r * math.sin(a), z] for a in (a0, (a0 + a1) / 2, a1) for r, z in rz
        ]
        pieces.append(trimesh.Trimesh(np.array(pts) + shift).convex_hull)
    return Part(mesh, pieces, material, rgba, fill, name, "revolved", labels)


def pleated(
    width: float,
    depth: float,
    height: float,
    thickness: float,
    pleats: int,
    center: tuple[float, float, float],
    material: str,
    rgba: RGBA,
    name: str = "pleats",
    fill: float = 1.0,
    gather: float = 1.0,
) -> Part:
    """A hanging pleated panel (a curtain): a cloth ``thickness`` thick that folds ``pleats``
    times across ``width`` (x) with folds ``depth`` deep (y), hanging ``height`` (z); its top
    is gathered to ``gather`` times its width (narrower folds at a rod). Centred at
    ``center``. Collision: the box around it (the hull of the folds)."""
    n = 6 * pleats + 1
    x = np.linspace(-width / 2, width / 2, n)
    amp = max(0.0, depth - thickness) / 2
    y = amp * np.sin(2 * math.pi * pleats * (x + width / 2) / width)
    front = np.column_stack([x, y - thickness / 2])
    back = np.column_stack([x, y + thickness / 2])
    pts = np.vstack([front, back])
    tris = []
    for i in range(n - 1):
        tris += [(i, i + 1, n + i + 1), (i, n + i + 1, n + i)]
    mesh = trimesh.creation.extrude_triangulation(pts, np.array(tris), height)
    if gather != 1.0:
        v = np.asarray(mesh.vertices, float).copy()
        v[:, 0] *= 1 + (gather - 1) * (v[:, 2] / height)
        mesh = trimesh.Trimesh(v, mesh.faces, process=False)
    mesh.apply_translation([center[0], center[1], center[2] - height / 2])
    if mesh.volume < 0:  # pragma: no cover - the strip's winding decides
        mesh.invert()
    lo, hi = mesh.bounds
    hull = trimesh.creation.box(extents=hi - lo).apply_translation((lo + hi) / 2)
    return Part(mesh, [hull], material, rgba, fill, name, "planar")
