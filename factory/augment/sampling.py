"""Joint configurations of objects on their support surfaces, sampled thousands at a time.

A *mover* is an object to be re-posed on its current support (``placement.kind == "on_top"``);
a *configuration* gives every mover a pose ``[x, y, z, yaw_deg]`` (bottom centre, world frame;
turn about z in degrees). Sampling follows the on-top placement of
:func:`factory.scenes.placement.on_top_candidates`, vectorised: a surface of the support that
the object fits under, a turn (aligned with the support, a quarter turn, or 40 % of the time up
to 0.3 rad askew), then a position where that footprint lies on the surface. A configuration is
*footprint-free* when no mover overlaps (in the plane and in height) another mover or an object
that stays on the same support: the cheap 2-D test that runs before any simulation. Each mover
takes the first footprint-free of several draws, given the movers posed before it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from factory.augment.rects import rect_rows, rects_overlap, spans_overlap
from factory.errors import FactoryError
from factory.scenes.placement import SceneState, support_rects

SURFACE_MARGIN = 0.01
"""Gap kept between a footprint and the surface's edge (m), as in on-top placement."""

OBSTACLE_MARGIN = 0.005
"""Growth of footprints in the overlap test of objects on one support (m), as in placement."""

ASKEW_PROBABILITY = 0.4
ASKEW_MAX = 0.3  # rad

TRIES = 32
"""Draws per mover and configuration at most: the first footprint-free one is taken."""

BLOCK = 1024
"""Configurations processed together (bounds the memory of the overlap tests)."""


class SamplingError(FactoryError):
    """An object cannot be posed on its support at all (no surface it fits on)."""


@dataclass(frozen=True)
class Surface:
    """A support surface in the world frame.

    Attributes:
        support_id: the supporting object.
        name: the surface's name in the support's asset (``top``, ``shelf_1``, ...).
        z: height of the surface (m, world).
        origin: ``(2,)`` first corner (m, world).
        eu: ``(2,)`` unit vector along the first edge.
        ev: ``(2,)`` unit vector along the second edge.
        su: length of the first edge (m).
        sv: length of the second edge (m).
        yaw0: the support's turn (rad), the reference of aligned poses.
    """

    support_id: str
    name: str
    z: float
    origin: np.ndarray
    eu: np.ndarray
    ev: np.ndarray
    su: float
    sv: float
    yaw0: float


@dataclass(frozen=True)
class Mover:
    """An object to re-pose and what constrains it.

    Attributes:
        object_id: the object.
        size: ``(width, length, height)`` (m), the object's extents.
        surfaces: the support's surfaces the object fits under.
        obstacles: ``(m, 5)`` rectangles of objects that stay on the same support.
        obstacle_z: ``(m, 2)`` their height spans (m, world).
    """

    object_id: str
    size: tuple[float, float, float]
    surfaces: tuple[Surface, ...]
    obstacles: np.ndarray
    obstacle_z: np.ndarray


@dataclass
class Samples:
    """Sampled configurations.

    Attributes:
        pose: ``(n, k, 4)`` ``[x, y, z, yaw_deg]`` of the ``k`` movers (world frame; yaw in
            ``[-180, 180)``).
        free: ``(n,)`` bool: the configuration fits on the surfaces and is footprint-free.
    """

    pose: np.ndarray
    free: np.ndarray


def _rect_of(state: SceneState, obj_id: str) -> tuple[list[float], tuple[float, float]]:
    fp = state.footprint(state.scene.object(obj_id))
    return [fp.x, fp.y, fp.hx, fp.hy, fp.yaw], (fp.z0, fp.z1)


def movers_of(state: SceneState, ids: list[str]) -> list[Mover]:
    """The movers ``ids`` of ``state.scene`` (their supports' assets in ``state.metas``).

    Raises:
        SamplingError: an object is not on a support, or fits on none of its surfaces.
    """
    moving = set(ids)
    out = []
    for oid in ids:
        obj = state.scene.object(oid)
        sup_id = obj.placement.support_id
        if obj.placement.kind != "on_top" or sup_id is None:
            raise SamplingError(f"{oid!r} is not on a support surface")
        if sup_id in moving:
            raise SamplingError(f"{oid!r} stands on {sup_id!r}, which moves too")
        support = state.scene.object(sup_id)
        w, ln, h = obj.dimensions.width, obj.dimensions.length, obj.dimensions.height
        surfaces = []
        for name, z, corner, clearance in support_rects(state, support, interiors=False):
            if h > clearance - 0.01:
                continue  # does not fit under the next board
            ux, uy = corner[1] - corner[0], corner[3] - corner[0]
            su, sv = float(np.linalg.norm(ux)), float(np.linalg.norm(uy))
            if su < 1e-6 or sv < 1e-6:
                continue
            gw, gl = w + 2 * SURFACE_MARGIN, ln + 2 * SURFACE_MARGIN
            if not ((gw <= su and gl <= sv) or (gl <= su and gw <= sv)):
                continue  # fits neither aligned nor turned a quarter
            surfaces.append(
                Surface(
                    sup_id,
                    name,
                    float(z),
                    np.asarray(corner[0], float),
                    ux / su,
                    uy / sv,
                    su,
                    sv,
                    math.radians(support.rotation.z),
                )
            )
        if not surfaces:
            raise SamplingError(f"{oid!r} fits on no surface of {sup_id!r}")
        rects, spans = [], []
        for other in state.scene.objects:
            if other.placement.support_id != sup_id or other.id in moving:
                continue
            if other.placement.kind != "on_top":
                continue
            rect, span = _rect_of(state, other.id)
            rects.append(rect)
            spans.append(span)
        out.append(
            Mover(
                oid,
                (float(w), float(ln), float(h)),
                tuple(surfaces),
                np.asarray(rects, float).reshape(-1, 5),
                np.asarray(spans, float).reshape(-1, 2),
            )
        )
    return out


def _sample_one(mover: Mover, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 4)`` poses ``[x, y, z, yaw_rad]`` and ``(n,)`` whether each fits its surface."""
    w, ln, _ = mover.size
    surfs = mover.surfaces
    pick = rng.integers(len(surfs), size=n)
    quarter = rng.integers(4, size=n)
    askew = rng.uniform(size=n) < ASKEW_PROBABILITY
    tilt = rng.uniform(-ASKEW_MAX, ASKEW_MAX, size=n)
    ua, vb = rng.uniform(size=n), rng.uniform(size=n)
    rel = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2])[quarter] + np.where(askew, tilt, 0.0)
    c, s = np.abs(np.cos(rel)), np.abs(np.sin(rel))
    half_u = (w * c + ln * s) / 2 + SURFACE_MARGIN
    half_v = (w * s + ln * c) / 2 + SURFACE_MARGIN
    su = np.array([f.su for f in surfs])[pick]
    sv = np.array([f.sv for f in surfs])[pick]
    fits = (2 * half_u <= su) & (2 * half_v <= sv)
    a = half_u + ua * np.maximum(su - 2 * half_u, 0.0)
    b = half_v + vb * np.maximum(sv - 2 * half_v, 0.0)
    origin = np.array([f.origin for f in surfs])[pick]
    eu = np.array([f.eu for f in surfs])[pick]
    ev = np.array([f.ev for f in surfs])[pick]
    xy = origin + a[:, None] * eu + b[:, None] * ev
    z = np.array([f.z for f in surfs])[pick]
    yaw = np.array([f.yaw0 for f in surfs])[pick] + rel
    return np.column_stack([xy, z, yaw]), fits


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angles (deg) wrapped to ``[-180, 180)``."""
    return np.mod(np.asarray(a, float) + 180.0, 360.0) - 180.0


def _free_of(mover: Mover, p: np.ndarray, rects: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """``(r,)`` whether poses ``p (r, 4)`` of ``mover`` clear its obstacles and the movers
    already posed in the same configurations (``rects (r, j, 5)``, ``spans (r, j, 2)``)."""
    w, ln, h = mover.size
    mine = rect_rows(p[:, 0], p[:, 1], w / 2, ln / 2, p[:, 3])
    z0, z1 = p[:, 2], p[:, 2] + h
    ok = np.ones(len(p), bool)
    if len(mover.obstacles):
        hit = rects_overlap(mine[:, None, :], mover.obstacles[None], OBSTACLE_MARGIN)
        hit &= spans_overlap(
            z0[:, None], z1[:, None], mover.obstacle_z[None, :, 0], mover.obstacle_z[None, :, 1]
        )
        ok &= ~hit.any(axis=1)
    for i in range(rects.shape[1]):
        hit = rects_overlap(mine, rects[:, i], OBSTACLE_MARGIN)
        ok &= ~(hit & spans_overlap(z0, z1, spans[:, i, 0], spans[:, i, 1]))
    return ok


def _first_free(
    mover: Mover,
    rects: np.ndarray,
    spans: np.ndarray,
    tries: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Pose of one mover in each of ``n = len(rects)`` configurations where the movers before
    it are at ``rects (n, j, 5)`` / ``spans (n, j, 2)``: draws are repeated for the
    configurations still without one, up to ``tries`` times. Returns ``(n, 4)`` poses
    ``[x, y, z, yaw_rad]`` and ``(n,)`` whether a footprint-free one was found."""
    n = len(rects)
    pose = np.zeros((n, 4))
    found = np.zeros(n, bool)
    todo = np.arange(n)
    for _ in range(tries):
        p, fits = _sample_one(mover, len(todo), rng)
        ok = fits & _free_of(mover, p, rects[todo], spans[todo])
        pose[todo] = p  # the last draw stands where none was free
        found[todo[ok]] = True
        todo = todo[~ok]
        if len(todo) == 0:
            break
    return pose, found


def sample(movers: list[Mover], n: int, rng: np.random.Generator, tries: int = TRIES) -> Samples:
    """``n`` joint configurations of ``movers`` and whether each is footprint-free.

    Movers are posed one after the other: each is drawn again (up to ``tries`` times) in the
    configurations where it is not footprint-free given the obstacles and the movers already
    posed there (on a crowded table the chance that a joint draw is free is the product of the
    movers' chances; this way the work grows with their sum). The draws depend only on
    ``rng``'s state, the movers, ``n`` and ``tries`` (deterministic per seed).
    """
    k = len(movers)
    pose = np.zeros((n, k, 4))
    free = np.ones(n, bool)
    for start in range(0, n, BLOCK):
        b = min(n, start + BLOCK) - start
        rects = np.zeros((b, k, 5))
        spans = np.zeros((b, k, 2))
        for j, m in enumerate(movers):
            p, found = _first_free(m, rects[:, :j], spans[:, :j], tries, rng)
            pose[start : start + b, j, :3] = p[:, :3]
            pose[start : start + b, j, 3] = wrap_deg(np.degrees(p[:, 3]))
            free[start : start + b] &= found
            rects[:, j] = rect_rows(p[:, 0], p[:, 1], m.size[0] / 2, m.size[1] / 2, p[:, 3])
            spans[:, j] = np.column_stack([p[:, 2], p[:, 2] + m.size[2]])
    return Samples(pose, free)
