"""A 2-D occupancy grid of a compiled MuJoCo scene, for planning where a mobile base drives.

The grid is a top view of the scene's collision geometry: every geom that collides
(``contype`` or ``conaffinity`` non-zero) and reaches into the robot's height band (default
z in [0.02, 1.9] m) occupies the cells its footprint overlaps. Static and free (movable) geoms
count alike, at their pose in the given ``MjData``: an object standing on the floor blocks the
base as a wall does. Planes (the ground), geoms wholly below the band (floor slabs) or above it
(ceilings, the lintel over a door) and the robot itself are left out. Doors and other openings
are free simply because the scene has no collision geometry there: ``factory.sim.compile``
builds a wall as solid pieces around its openings.

Footprints are exact or conservative: a box is its projected (oriented) corners, a cylinder or
capsule the hull of its end circles or spheres, a sphere a disc, a mesh the convex hull of its
vertices (MuJoCo collides a mesh through its convex hull, so this is the collision shape's
projection), anything else its oriented bounding box. A cell is occupied when its square
overlaps a footprint (a separating-axis test), so thin walls never fall between cell centres.

Frames and shapes: world frame, metres. ``occupied`` is indexed ``[iy, ix]`` (row = y); cell
``(ix, iy)`` covers ``[x0 + ix r, x0 + (ix + 1) r) x [y0 + iy r, y0 + (iy + 1) r)`` with
``origin = (x0, y0)`` and ``r = resolution``.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from factory.nav.errors import NavError

log = logging.getLogger(__name__)

ROBOT_PREFIXES: tuple[str, ...] = ("mobile/", "panda/")
"""Body-name prefixes of the robots of ``factory.demos`` (mobile and fixed); their geoms are
never obstacles of the grid."""

_RING = 24
"""Sides of the polygons that stand in for circles; their radius is enlarged so that the
polygon contains the circle."""


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class OccupancyGrid:
    """Occupied cells of a top view of a scene.

    Attributes:
        resolution: cell side (m).
        origin: world (x, y) of the lower-left corner of cell (0, 0) (m).
        occupied: (ny, nx) bool, indexed ``[iy, ix]``.
        inflation: radius the obstacles have been grown by (m); 0 for the raw grid.
    """

    resolution: float
    origin: tuple[float, float]
    occupied: np.ndarray = field(repr=False)
    inflation: float = 0.0

    def __post_init__(self) -> None:
        if not self.resolution > 0:
            raise NavError(f"grid resolution must be positive, got {self.resolution}")
        if self.occupied.ndim != 2 or 0 in self.occupied.shape:
            raise NavError(f"grid must be a non-empty 2-D array, got shape {self.occupied.shape}")

    # ---- geometry
    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) cells."""
        ny, nx = self.occupied.shape
        return int(ny), int(nx)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the grid (m, world)."""
        ny, nx = self.shape
        x0, y0 = self.origin
        return x0, y0, x0 + nx * self.resolution, y0 + ny * self.resolution

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """Cell indices ``(..., 2)`` as (ix, iy) of world points ``(..., 2)`` (may lie outside)."""
        xy = np.asarray(xy, float)
        return np.floor((xy - np.asarray(self.origin)) / self.resolution).astype(int)

    def cell_to_world(self, ij: np.ndarray) -> np.ndarray:
        """World centres ``(..., 2)`` (m) of cells ``(..., 2)`` given as (ix, iy)."""
        return (np.asarray(ij, float) + 0.5) * self.resolution + np.asarray(self.origin)

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points ``(..., 2)`` lie on the grid; bool ``(...)``."""
        ij = self.world_to_cell(xy)
        ny, nx = self.shape
        return (ij[..., 0] >= 0) & (ij[..., 0] < nx) & (ij[..., 1] >= 0) & (ij[..., 1] < ny)

    def _lookup(self, grid: np.ndarray, xy: np.ndarray, outside: float | bool) -> np.ndarray:
        ij = self.world_to_cell(xy)
        ok = self.inside(xy)
        ny, nx = self.shape
        ix = np.clip(ij[..., 0], 0, nx - 1)
        iy = np.clip(ij[..., 1], 0, ny - 1)
        return np.where(ok, grid[iy, ix], outside)

    def free(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points ``(..., 2)`` fall in free cells; off the grid is not free."""
        return self._lookup(~self.occupied, xy, False).astype(bool)

    # ---- distances and components
    @functools.cached_property
    def distance(self) -> np.ndarray:
        """(ny, nx): distance from each cell centre to the nearest occupied cell centre (m);
        0 on occupied cells, ``inf`` everywhere when nothing is occupied."""
        from scipy import ndimage

        if not self.occupied.any():
            return np.full(self.shape, np.inf)
        return np.asarray(
            ndimage.distance_transform_edt(~self.occupied, sampling=self.resolution), float
        )

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Distance (m) from world points ``(..., 2)`` to the nearest obstacle, to within a
        cell: the distance transform at the point's cell less half a cell; 0 in an occupied
        cell and off the grid."""
        d = np.maximum(self.distance - self.resolution / 2, 0.0)
        return np.asarray(self._lookup(d, xy, 0.0), float)

    def inflate(self, radius: float) -> OccupancyGrid:
        """The grid with every obstacle grown by ``radius`` (m): a cell becomes occupied when
        its centre is nearer than ``radius`` to an obstacle (to within one cell). A disc robot
        of this radius fits where the inflated grid is free."""
        if radius < 0:
            raise NavError(f"inflation radius must not be negative, got {radius}")
        grown = self.distance - self.resolution / 2 < radius
        return replace(self, occupied=self.occupied | grown, inflation=self.inflation + radius)

    @functools.cached_property
    def labels(self) -> np.ndarray:
        """(ny, nx) int: connected components of the free cells (8-connected), numbered from
        1; 0 on occupied cells."""
        from scipy import ndimage

        labels, _ = ndimage.label(~self.occupied, structure=np.ones((3, 3), bool))
        return np.asarray(labels, int)

    def component(self, xy: np.ndarray) -> np.ndarray:
        """Component label of world points ``(..., 2)``; 0 when occupied or off the grid."""
        return np.asarray(self._lookup(self.labels, xy, 0), int)

    def largest_component(self) -> int:
        """The label of the largest free component (0 when nothing is free)."""
        counts = np.bincount(self.labels.ravel())
        counts[0] = 0
        return int(counts.argmax()) if counts.any() else 0

    # ---- construction
    @classmethod
    def from_model(
        cls,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        resolution: float = 0.05,
        z_band: tuple[float, float] = (0.02, 1.9),
        exclude_bodies: Iterable[int] = (),
        exclude_prefixes: tuple[str, ...] = ROBOT_PREFIXES,
        bounds: tuple[float, float, float, float] | None = None,
        pad: float = 0.2,
    ) -> OccupancyGrid:
        """Rasterizes a scene's collision geometry (see the module docstring).

        Args:
            model: the compiled scene.
            data: its state; geom poses are read from ``geom_xpos``/``geom_xmat``, so call
                ``mj_forward`` (or ``mj_kinematics``) first.
            resolution: cell side (m).
            z_band: (low, high) heights (m, world) of the robot; a geom occupies cells only
                when its vertical extent overlaps this band.
            exclude_bodies: body ids left out, with their descendants.
            exclude_prefixes: bodies whose name starts with one of these are left out, with
                their descendants (the robots by default).
            bounds: (xmin, ymin, xmax, ymax) of the grid (m); default: the footprints of all
                obstacles plus ``pad``.
            pad: margin around the obstacles when ``bounds`` is not given (m).

        Raises:
            NavError: no obstacle and no bounds, or a bad resolution.
        """
        if not resolution > 0:
            raise NavError(f"grid resolution must be positive, got {resolution}")
        polygons = scene_footprints(model, data, z_band, exclude_bodies, exclude_prefixes)
        if bounds is None:
            if not polygons:
                raise NavError("the scene has no obstacle in the height band: give bounds")
            pts = np.concatenate(polygons)
            lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
            bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        xmin, ymin, xmax, ymax = bounds
        nx = max(1, math.ceil((xmax - xmin) / resolution - 1e-9))
        ny = max(1, math.ceil((ymax - ymin) / resolution - 1e-9))
        occupied = np.zeros((ny, nx), bool)
        for poly in polygons:
            _rasterize(occupied, poly, (xmin, ymin), resolution)
        log.debug(
            "occupancy grid %dx%d at %.3f m: %d footprints, %.1f %% occupied",
            nx,
            ny,
            resolution,
            len(polygons),
            100 * occupied.mean(),
        )
        return cls(resolution, (float(xmin), float(ymin)), occupied)


def scene_footprints(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    z_band: tuple[float, float] = (0.02, 1.9),
    exclude_bodies: Iterable[int] = (),
    exclude_prefixes: tuple[str, ...] = ROBOT_PREFIXES,
) -> list[np.ndarray]:
    """Top-view footprints of the colliding geoms in the height band.

    Returns:
        convex polygons, each (k, 2) counter-clockwise in the world frame (m); k < 3 for a
        degenerate (flat, thin) footprint.
    """
    excluded = np.zeros(model.nbody, bool)
    excluded[list(exclude_bodies)] = True
    for b in range(1, model.nbody):
        name = model.body(b).name
        parent = int(model.body_parentid[b])
        excluded[b] |= bool(exclude_prefixes) and name.startswith(exclude_prefixes)
        excluded[b] |= parent != 0 and bool(excluded[parent])
    lo, hi = z_band
    out = []
    for g in range(model.ngeom):
        if not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        if excluded[model.geom_bodyid[g]] or model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        pts = geom_points(model, data, g)
        if pts[:, 2].max() < lo or pts[:, 2].min() > hi:
            continue
        out.append(convex_hull_2d(pts[:, :2]))
    return out


def _ring(radius: float, n: int = _RING) -> np.ndarray:
    """(n, 2) corners of a regular polygon that contains the circle of ``radius``."""
    a = np.arange(n) * (2 * math.pi / n)
    r = radius / math.cos(math.pi / n)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def geom_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """World points (k, 3) whose convex hull contains geom ``g`` (m)."""
    t = int(model.geom_type[g])
    size = model.geom_size[g]
    pos = data.geom_xpos[g]
    rot = data.geom_xmat[g].reshape(3, 3)
    gt = mujoco.mjtGeom
    if t == gt.mjGEOM_SPHERE:
        ring = _ring(size[0])
        flat = np.column_stack([ring + pos[:2], np.full(len(ring), pos[2])])
        up = np.array([0.0, 0.0, size[0]])
        return np.vstack([flat, pos + up, pos - up])
    if t == gt.mjGEOM_CAPSULE:
        ends = pos + np.outer([-size[1], size[1]], rot[:, 2])
        ring = _ring(size[0])
        pts = [np.column_stack([ring + e[:2], np.full(len(ring), e[2])]) for e in ends]
        caps = [e + s * np.array([0.0, 0.0, size[0]]) for e in ends for s in (-1, 1)]
        return np.vstack([*pts, np.array(caps)])
    if t == gt.mjGEOM_CYLINDER:
        ring = _ring(size[0])
        local = np.vstack(
            [np.column_stack([ring, np.full(len(ring), z)]) for z in (-size[1], size[1])]
        )
        return local @ rot.T + pos
    if t == gt.mjGEOM_BOX:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return (corners * size[:3]) @ rot.T + pos
    if t == gt.mjGEOM_MESH and model.geom_dataid[g] >= 0:
        mesh = int(model.geom_dataid[g])
        adr, num = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        verts = np.asarray(model.mesh_vert[adr : adr + num], float)
        return verts @ rot.T + pos
    # ellipsoid, height field, SDF, ...: the oriented bounding box MuJoCo keeps for the geom
    center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return (center + corners * half) @ rot.T + pos


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Convex hull (k, 2) of points (n, 2), counter-clockwise (Andrew's monotone chain).

    Collinear and repeated points are dropped; fewer than three points come back for a
    degenerate input.
    """
    pts = np.unique(np.round(np.asarray(points, float), 6), axis=0)  # sorted by x, then y
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        chain: list[np.ndarray] = []
        for p in seq:
            while len(chain) >= 2:
                (ax, ay), (bx, by) = chain[-2], chain[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 1e-12:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _rasterize(
    occupied: np.ndarray, poly: np.ndarray, origin: tuple[float, float], res: float
) -> None:
    """Marks the cells whose square overlaps the convex polygon ``poly`` (k, 2), in place."""
    ny, nx = occupied.shape
    h = res / 2
    eps = 1e-9
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    ix0 = max(0, math.floor((lo[0] - origin[0]) / res + eps))
    ix1 = min(nx - 1, math.ceil((hi[0] - origin[0]) / res - eps) - 1)
    iy0 = max(0, math.floor((lo[1] - origin[1]) / res + eps))
    iy1 = min(ny - 1, math.ceil((hi[1] - origin[1]) / res - eps) - 1)
    if ix1 < ix0 or iy1 < iy0:
        if lo[0] == hi[0] or lo[1] == hi[1]:  # a flat footprint on a cell boundary
            ix1, iy1 = max(ix0, ix1), max(iy0, iy1)
            if ix0 >= nx or iy0 >= ny:
                return
        else:
            return
    cx = origin[0] + (np.arange(ix0, ix1 + 1) + 0.5) * res
    cy = origin[1] + (np.arange(iy0, iy1 + 1) + 0.5) * res
    px, py = np.meshgrid(cx, cy)
    inside = np.ones(px.shape, bool)
    if len(poly) >= 3:
        for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
            d = b - a
            n = np.array([d[1], -d[0]]) / math.hypot(d[0], d[1])  # outward for CCW polygons
            reach = h * (abs(n[0]) + abs(n[1]))
            inside &= n[0] * (px - a[0]) + n[1] * (py - a[1]) < reach - eps
    occupied[iy0 : iy1 + 1, ix0 : ix1 + 1] |= inside
