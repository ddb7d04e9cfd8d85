"""Fisheye cameras for MuJoCo, whose own cameras are pinhole only.

A fisheye camera is a named camera of the model: its pose (``data.cam_xpos``/``cam_xmat``) is
the fisheye's pose and its optical axis is the camera's ``-z`` (MuJoCo's camera convention:
looking along ``-z``, ``+y`` up, ``+x`` right), so a model mounts a fisheye on a moving robot
body like any camera. Its lens is described by a :class:`FisheyeSpec` (square resolution, field
of view, projection, clipping distances); the camera's own ``fovy`` is ignored.

Projection (``equidistant``, the default): a direction at angle ``theta`` (rad) from the optical
axis and azimuth ``phi`` around it lands at radius ``r = f * theta`` (pixels) from the image
centre, with ``f`` chosen so that ``theta = fov / 2`` lands on the image circle of radius
``width / 2``. ``equisolid`` (``r = 2 f sin(theta / 2)``) is the other common lens design.

Rendering composes a cube map: :class:`FisheyeRenderer` draws the cube faces that the image
needs (front, right, left, up, down; back only for wide fields of view) with 90-degree pinhole
views from the camera's position, each only over the window of it that the lens reads (at 180
degrees the front half of a side face), side by side into one offscreen buffer of one
``mujoco.Renderer`` (the scene is updated once per frame, each face only re-projects it; per
face the geoms outside its frustum are skipped, :mod:`factory.sim.frustum`), reads RGB and
depth back at once, and resamples them per fisheye pixel through a lookup table built at
construction (face, pixel, bilinear weights for RGB, applied as one sparse matrix product;
nearest pixel for depth). The faces are drawn by setting the OpenGL cameras of the
``mjvScene`` (position, forward and up vectors, an off-centre frustum for the window) after
``mjv_updateScene``, which gives each face its full orientation, roll included (a free
``MjvCamera`` cannot roll), and leaves the model untouched.

Depth is the **ray length** in metres: the Euclidean distance from the camera's position to the
surface seen at each pixel (not the z-depth along the optical axis, which is undefined at and
beyond 90 degrees). Pixels outside the image circle, and pixels whose ray hits nothing within
the far clipping distance, hold 0 (RGB black outside the circle).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from factory.errors import FactoryError

if TYPE_CHECKING:
    import mujoco

log = logging.getLogger(__name__)

Projection = Literal["equidistant", "equisolid"]
PROJECTIONS: tuple[str, ...] = ("equidistant", "equisolid")
Interpolation = Literal["bilinear", "nearest"]

#: Cube faces in the camera frame: name -> (forward, up); right = forward x up. Order matters:
#: a direction on an edge between faces goes to the earlier face.
FACES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "right": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "up": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "down": ((0.0, -1.0, 0.0), (0.0, 0.0, -1.0)),
    "back": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
}


class FisheyeError(FactoryError):
    """A fisheye camera is specified or used wrongly (bad spec, unknown camera, no GL)."""


@dataclass(frozen=True)
class FisheyeSpec:
    """A fisheye lens: image size, field of view, projection and clipping.

    Pixel coordinates ``(u, v)``: ``u`` the column (to the right), ``v`` the row (down), pixel
    centres at integers, so the image centre is ``((width - 1) / 2, (width - 1) / 2)``.

    Attributes:
        resolution: image width = height (pixels).
        fov_deg: full field of view across the image circle (degrees, 0 < fov <= 360).
        projection: ``equidistant`` (``r = f theta``) or ``equisolid`` (``r = 2 f sin(theta/2)``).
        near: near clipping distance (m) of the cube faces.
        far: far clipping distance (m) of the cube faces, along each face's axis (so every ray
            reaches at least ``far``; depth beyond ``far`` reads 0).
    """

    resolution: int = 128
    fov_deg: float = 180.0
    projection: Projection = "equidistant"
    near: float = 0.01
    far: float = 50.0

    def __post_init__(self) -> None:
        if int(self.resolution) != self.resolution or self.resolution < 2:
            raise FisheyeError(f"fisheye resolution must be an integer >= 2, got {self.resolution}")
        if not 0.0 < self.fov_deg <= 360.0:
            raise FisheyeError(f"fisheye fov_deg must be in (0, 360], got {self.fov_deg}")
        if self.projection not in PROJECTIONS:
            raise FisheyeError(
                f"unknown fisheye projection {self.projection!r}: choose from {list(PROJECTIONS)}"
            )
        if not 0.0 < self.near < self.far:
            raise FisheyeError(f"need 0 < near < far, got near={self.near}, far={self.far}")

    @property
    def theta_max(self) -> float:
        """Half the field of view (rad): the angle that lands on the image circle."""
        return math.radians(self.fov_deg) / 2.0

    @property
    def radius_px(self) -> float:
        """Radius of the image circle (pixels): half the width."""
        return self.resolution / 2.0

    @property
    def centre(self) -> float:
        """Pixel coordinate of the image centre along both axes: ``(resolution - 1) / 2``."""
        return (self.resolution - 1) / 2.0

    @property
    def focal_px(self) -> float:
        """``f`` of the projection (pixels): ``r(theta_max) = radius_px``."""
        if self.projection == "equidistant":
            return self.radius_px / self.theta_max
        return self.radius_px / (2.0 * math.sin(self.theta_max / 2.0))

    def radius_of(self, theta: np.ndarray) -> np.ndarray:
        """Image radius (pixels) of off-axis angles ``theta`` (rad), any shape."""
        f = self.focal_px
        if self.projection == "equidistant":
            return f * theta
        return 2.0 * f * np.sin(theta / 2.0)

    def theta_of(self, radius: np.ndarray) -> np.ndarray:
        """Off-axis angle (rad) of image radii (pixels); the inverse of :meth:`radius_of`.

        Valid for angles up to pi (radii up to ``radius_of(pi)``); larger radii are clipped.
        """
        f = self.focal_px
        if self.projection == "equidistant":
            return np.minimum(radius / f, math.pi)
        return 2.0 * np.arcsin(np.minimum(radius / (2.0 * f), 1.0))

    def project(self, directions: Any) -> np.ndarray:
        """Pixel coordinates of directions in the camera frame.

        Args:
            directions: ``(..., 3)`` vectors in the camera frame (``-z`` the optical axis,
                ``+x`` right, ``+y`` up); any length but zero.

        Returns:
            ``(..., 2)`` float64 ``(u, v)`` pixel coordinates (column, row). Directions beyond
            the field of view land outside the image circle (still on the projection's curve).

        Raises:
            FisheyeError: a zero vector.
        """
        d = np.asarray(directions, dtype=np.float64)
        if d.shape[-1:] != (3,):
            raise FisheyeError(f"directions must have shape (..., 3), got {d.shape}")
        norm = np.linalg.norm(d, axis=-1)
        if np.any(norm == 0.0):
            raise FisheyeError("cannot project a zero direction")
        x, y, z = d[..., 0], d[..., 1], d[..., 2]
        rho = np.hypot(x, y)
        theta = np.arctan2(rho, -z)
        r = self.radius_of(theta)
        safe = np.where(rho > 0.0, rho, 1.0)
        scale = np.where(rho > 0.0, r / safe, 0.0)
        c = self.centre
        return np.stack([c + scale * x, c - scale * y], axis=-1)

    def unproject(self, u: Any, v: Any) -> np.ndarray:
        """Unit directions in the camera frame of pixel coordinates.

        Args:
            u: column coordinate(s) (pixels, centres at integers), any shape.
            v: row coordinate(s), same shape as ``u``.

        Returns:
            ``(..., 3)`` float64 unit vectors in the camera frame (``(0, 0, -1)`` at the centre).
        """
        dx = np.asarray(u, dtype=np.float64) - self.centre
        dy = self.centre - np.asarray(v, dtype=np.float64)
        r = np.hypot(dx, dy)
        theta = self.theta_of(r)
        s = np.sin(theta)
        safe = np.where(r > 0.0, r, 1.0)
        k = np.where(r > 0.0, s / safe, 0.0)
        return np.stack([k * dx, k * dy, -np.cos(theta)], axis=-1)

    @cached_property
    def rays(self) -> np.ndarray:
        """``(H, W, 3)`` float64 unit ray of every pixel centre (camera frame), read-only."""
        idx = np.arange(self.resolution, dtype=np.float64)
        u, v = np.meshgrid(idx, idx)  # u varies along columns, v along rows
        out = self.unproject(u, v)
        out.flags.writeable = False
        return out

    @cached_property
    def mask(self) -> np.ndarray:
        """``(H, W)`` bool: pixel centres inside the image circle (theta <= fov / 2), read-only."""
        idx = np.arange(self.resolution, dtype=np.float64) - self.centre
        r = np.hypot(idx[None, :], idx[:, None])
        out = r <= self.radius_px
        out.flags.writeable = False
        return out


def default_cube_size(spec: FisheyeSpec) -> int:
    """Cube face size (pixels) that samples the image centre about as densely as the fisheye.

    ``0.75 * resolution`` at 180 degrees (a face's centre then has 1.18x the fisheye's pixels
    per radian), scaled by ``180 / fov`` for other fields of view (equidistant), at least 8.
    """
    return max(8, round(0.75 * spec.resolution * 180.0 / spec.fov_deg))


@dataclass(frozen=True)
class CubeLookup:
    """Where each fisheye pixel inside the image circle reads the atlas of cube faces.

    Each face is a square pinhole view of ``size`` x ``size`` pixels spanning a frustum of
    half-width ``half_extent`` at unit distance (slightly more than 90 degrees, so bilinear
    neighbours never leave their face); only the window of it that some fisheye pixel reads is
    drawn. The atlas is the offscreen buffer as OpenGL reads it (row 0 at the bottom), the
    faces' windows side by side: face ``k`` of ``faces`` occupies columns
    ``[lefts[k], lefts[k] + windows[k][2])`` and rows ``[0, windows[k][3])``.

    Attributes:
        faces: names of the faces drawn, in atlas order (a subset of :data:`FACES`).
        size: face width = height (pixels) of the whole face.
        windows: per face ``(col0, row0, cols, rows)``: the window of the face's pixel grid
            that is drawn (OpenGL orientation: columns to the right, rows up). A 180-degree
            lens reads all of the front face and about half of each side face.
        lefts: per face, the atlas column where its window starts.
        atlas_shape: ``(rows, columns)`` of the atlas (pixels).
        half_extent: ``size / (size - 2)``: half the face's width at unit distance.
        pixels: ``(N,)`` int64 flat indices of the fisheye pixels inside the circle.
        bilinear: ``(N, 4)`` int64 flat atlas indices of the 4 bilinear neighbours.
        weights: ``(N, 4)`` float32 bilinear weights (rows sum to 1).
        nearest: ``(N,)`` int64 flat atlas index of the nearest face pixel.
        ray_scale: ``(N,)`` float32: ray length / z-depth of the nearest face pixel's centre.
    """

    faces: tuple[str, ...]
    size: int
    windows: tuple[tuple[int, int, int, int], ...]
    lefts: tuple[int, ...]
    atlas_shape: tuple[int, int]
    half_extent: float
    pixels: np.ndarray = field(repr=False)
    bilinear: np.ndarray = field(repr=False)
    weights: np.ndarray = field(repr=False)
    nearest: np.ndarray = field(repr=False)
    ray_scale: np.ndarray = field(repr=False)

    def frustum(self, k: int) -> tuple[float, float, float, float]:
        """Face ``k``'s drawn window at unit distance: ``(left, right, bottom, top)`` (the
        tangents of its edges along the face's right and up axes)."""
        c0, r0, cols, rows = self.windows[k]
        h, n = self.half_extent, self.size
        return (
            (2.0 * c0 / n - 1.0) * h,
            (2.0 * (c0 + cols) / n - 1.0) * h,
            (2.0 * r0 / n - 1.0) * h,
            (2.0 * (r0 + rows) / n - 1.0) * h,
        )


def cube_lookup(spec: FisheyeSpec, size: int) -> CubeLookup:
    """Builds the lookup table from fisheye pixels to the cube faces' atlas.

    Args:
        spec: the fisheye lens.
        size: cube face size (pixels, >= 4).

    Returns:
        the table; only the faces that some pixel inside the image circle uses are drawn, and
        of each only the window of pixels that some fisheye pixel reads (bilinear neighbours
        and the nearest pixel).
    """
    if size < 4:
        raise FisheyeError(f"cube face size must be >= 4 pixels, got {size}")
    pixels = np.flatnonzero(spec.mask)
    d = spec.rays.reshape(-1, 3)[pixels]
    fwd = np.array([f for f, _ in FACES.values()])
    up = np.array([u for _, u in FACES.values()])
    right = np.cross(fwd, up)
    face_all = np.argmax(d @ fwd.T, axis=1)  # first maximum: edges go to the earlier face
    used = np.unique(face_all)
    names = tuple(list(FACES)[k] for k in used)
    slot = np.full(len(FACES), -1, dtype=np.int64)
    slot[used] = np.arange(len(used))
    k = slot[face_all]
    a = np.einsum("nj,nj->n", d, fwd[face_all])
    x = np.einsum("nj,nj->n", d, right[face_all]) / a
    y = np.einsum("nj,nj->n", d, up[face_all]) / a
    h = size / (size - 2.0)
    col = (x / h + 1.0) * size / 2.0 - 0.5  # OpenGL: column to the right, row up
    row = (y / h + 1.0) * size / 2.0 - 0.5
    c0 = np.clip(np.floor(col), 0, size - 2).astype(np.int64)
    r0 = np.clip(np.floor(row), 0, size - 2).astype(np.int64)
    tx = np.clip(col - c0, 0.0, 1.0)
    ty = np.clip(row - r0, 0.0, 1.0)
    cn = np.clip(np.rint(col), 0, size - 1).astype(np.int64)
    rn = np.clip(np.rint(row), 0, size - 1).astype(np.int64)
    # each face's window: every pixel read (bilinear neighbours, nearest), side by side
    windows: list[tuple[int, int, int, int]] = []
    lefts: list[int] = []
    width = 0
    for j in range(len(used)):
        on = k == j
        wc0 = int(min(c0[on].min(), cn[on].min()))
        wc1 = int(max(c0[on].max() + 1, cn[on].max()))
        wr0 = int(min(r0[on].min(), rn[on].min()))
        wr1 = int(max(r0[on].max() + 1, rn[on].max()))
        windows.append((wc0, wr0, wc1 - wc0 + 1, wr1 - wr0 + 1))
        lefts.append(width)
        width += wc1 - wc0 + 1
    win = np.array(windows, dtype=np.int64)
    left = np.array(lefts, dtype=np.int64)[k] - win[k, 0]  # atlas column of face column 0
    bottom = -win[k, 1]  # atlas row of face row 0
    base = (bottom + r0) * width + left + c0
    bilinear = np.stack([base, base + 1, base + width, base + width + 1], axis=1)
    weights = [(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty]
    nearest = (bottom + rn) * width + left + cn
    xs = ((cn + 0.5) * 2.0 / size - 1.0) * h
    ys = ((rn + 0.5) * 2.0 / size - 1.0) * h
    ray_scale = np.sqrt(1.0 + xs * xs + ys * ys).astype(np.float32)
    return CubeLookup(
        faces=names,
        size=size,
        windows=tuple(windows),
        lefts=tuple(lefts),
        atlas_shape=(int(win[:, 3].max()), width),
        half_extent=h,
        pixels=pixels,
        bilinear=bilinear,
        weights=np.stack(weights, axis=1).astype(np.float32),
        nearest=nearest,
        ray_scale=ray_scale,
    )


class FisheyeRenderer:
    """Renders fisheye RGB and depth images of a model's named cameras through a cube map.

    One ``mujoco.Renderer`` (one GL context) draws all faces of a frame side by side; per frame
    the scene is updated once (``mjv_updateScene``), each face is one ``mjr_render`` with the
    scene's OpenGL cameras turned to that face, and RGB + depth are read back in one call.

    The offscreen buffer is sized for the atlas of faces: ``model.vis.global_.offwidth/
    offheight`` (and with ``fast``, ``offsamples = 0``) are raised while the GL context is made
    and restored afterwards, so the model is left as it was.

    Lighting is the same for all faces: ``mjv_updateScene`` places the model's lights and the
    headlight in the world once per frame (the headlight along the fisheye's optical axis), so
    diffuse shading is continuous across face seams; only specular highlights, which OpenGL
    computes per view, can differ slightly at a seam.

    Args:
        model: the compiled model (its cameras carry the fisheye poses).
        spec: the lens.
        cube_size: cube face size (pixels); default :func:`default_cube_size`.
        interpolation: ``bilinear`` (default) or ``nearest`` for RGB; depth is always nearest.
        scene_option: visibility options; default geom groups 0-2 visible, sites hidden (as the
            demos' recording cameras).
        fast: no multisampling, shadows, reflections or skybox (as the demos' recording
            cameras), and infinite planes drawn as 16 quads
            (:func:`factory.sim.render_model.render_model`); ``False`` keeps the model's visual
            settings.
        cull: per cube face, skip the geoms wholly outside the face's frustum
            (:class:`factory.sim.frustum.FrustumCuller`; the same image, fewer triangles to
            draw; nothing is skipped while shadows or reflections are on).

    Raises:
        FisheyeError: bad cube size or interpolation, or no OpenGL context could be made.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        spec: FisheyeSpec,
        cube_size: int | None = None,
        *,
        interpolation: Interpolation = "bilinear",
        scene_option: mujoco.MjvOption | None = None,
        fast: bool = True,
        cull: bool = True,
    ) -> None:
        from factory.sim.frustum import FrustumCuller
        from factory.sim.gl import configure_gl
        from factory.sim.render_model import render_model

        configure_gl("auto")
        import mujoco

        if interpolation not in ("bilinear", "nearest"):
            raise FisheyeError(f"interpolation must be bilinear or nearest, got {interpolation!r}")
        self.model = model
        self.spec = spec
        self.interpolation = interpolation
        size = default_cube_size(spec) if cube_size is None else int(cube_size)
        self.lookup = cube_lookup(spec, size)
        lk = self.lookup
        height, width = lk.atlas_shape
        drawn = render_model(model) if fast else model  # infinite planes as 16 quads
        vis = drawn.vis
        saved = (vis.global_.offwidth, vis.global_.offheight, vis.quality.offsamples)
        vis.global_.offwidth = max(vis.global_.offwidth, width)
        vis.global_.offheight = max(vis.global_.offheight, height)
        if fast:
            vis.quality.offsamples = 0
        try:
            self.renderer = mujoco.Renderer(drawn, height=height, width=width)
        except Exception as e:  # GL errors come in several types
            import os

            raise FisheyeError(
                f"could not create an offscreen OpenGL context of {width}x{height} (MUJOCO_GL="
                f"{os.environ.get('MUJOCO_GL', '')}): {e}"
            ) from None
        finally:
            vis.global_.offwidth, vis.global_.offheight, vis.quality.offsamples = saved
        if fast:
            flags = self.renderer.scene.flags
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
        if scene_option is None:
            scene_option = mujoco.MjvOption()
            scene_option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
            scene_option.sitegroup[:] = 0
        self.option = scene_option
        self.culler = FrustumCuller(drawn) if cull else None
        self._rgb = np.empty((height, width, 3), np.uint8)
        self._z = np.empty((height, width), np.float32)
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._viewports = [
            mujoco.MjrRect(lk.lefts[k], 0, lk.windows[k][2], lk.windows[k][3])
            for k in range(len(lk.faces))
        ]
        self._windows = [lk.frustum(k) for k in range(len(lk.faces))]
        self._face_fwd = np.array([FACES[n][0] for n in lk.faces])  # (F, 3) camera frame
        self._face_up = np.array([FACES[n][1] for n in lk.faces])
        n, f = np.float32(spec.near), np.float32(spec.far)
        # reversed-Z depth buffer (mujoco.Renderer's mjDEPTH_ZEROFAR) -> z-depth, as mujoco does
        c = -(f + n) / (f - n)
        d = -(np.float32(2) * f * n) / (f - n)
        self._zc = float(np.float32(-0.5) * c - np.float32(0.5))
        self._zd = float(np.float32(-0.5) * d)
        self._cam_ids: dict[str | int, int] = {}
        # RGB resampling as one sparse product: (H*W, atlas pixels) with 4 (bilinear) or 1
        # (nearest) weights per row inside the image circle, empty rows outside
        from scipy.sparse import csr_matrix

        if interpolation == "bilinear":
            cols, weights = lk.bilinear, lk.weights
        else:
            cols, weights = lk.nearest[:, None], np.ones((len(lk.nearest), 1), np.float32)
        per_row = np.zeros(spec.resolution**2, np.int64)
        per_row[lk.pixels] = cols.shape[1]
        indptr = np.concatenate([[0], np.cumsum(per_row)])
        self._resample = csr_matrix(
            (weights.ravel(), cols.ravel(), indptr), shape=(spec.resolution**2, height * width)
        )
        log.debug(
            "fisheye %dpx %.0f deg: %d cube faces of %dpx (%s)",
            spec.resolution,
            spec.fov_deg,
            len(lk.faces),
            size,
            ", ".join(lk.faces),
        )

    @property
    def mask(self) -> np.ndarray:
        """``(H, W)`` bool: pixels inside the image circle (the others are black / 0)."""
        return self.spec.mask

    @property
    def rays(self) -> np.ndarray:
        """``(H, W, 3)`` unit ray directions of the pixels in the camera frame."""
        return self.spec.rays

    @property
    def faces(self) -> tuple[str, ...]:
        """Names of the cube faces drawn per frame."""
        return self.lookup.faces

    def camera_id(self, camera: str | int) -> int:
        """The model's id of a camera given by name or id.

        Raises:
            FisheyeError: no such camera.
        """
        if camera in self._cam_ids:
            return self._cam_ids[camera]
        import mujoco

        if isinstance(camera, str):
            cid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        else:
            cid = int(camera)
        if not 0 <= cid < self.model.ncam:
            names = [self.model.camera(i).name for i in range(self.model.ncam)]
            raise FisheyeError(f"no camera {camera!r} in the model (cameras: {names})")
        self._cam_ids[camera] = cid
        return cid

    def render_atlas(self, data: mujoco.MjData, camera: str | int) -> None:
        """Draws the cube faces of ``camera`` and reads them into ``atlas_rgb``/``atlas_z``.

        ``data`` needs current kinematics (``mj_forward`` or ``mj_kinematics`` +
        ``mj_camlight``).
        """
        import mujoco

        cid = self.camera_id(camera)
        r = self.renderer
        r.update_scene(data, camera=cid, scene_option=self.option)
        rot = np.asarray(data.cam_xmat[cid], dtype=np.float64).reshape(3, 3)  # camera -> world
        pos = np.asarray(data.cam_xpos[cid], dtype=np.float64)
        fwd = self._face_fwd @ rot.T
        up = self._face_up @ rot.T
        near = self.spec.near
        gl = r._gl_context
        if gl is not None:
            gl.make_current()
        ctx = r._mjr_context
        scene = r.scene
        culler = self.culler
        if culler is not None:
            culler.bind(scene, data)
        for k, viewport in enumerate(self._viewports):
            left, right, bottom, top = self._windows[k]
            for glcam in scene.camera:  # both eyes of the (unused) stereo pair
                glcam.pos[:] = pos
                glcam.forward[:] = fwd[k]
                glcam.up[:] = up[k]
                # the face's window: an off-centre part of the face's frustum at the near plane
                glcam.frustum_center = 0.5 * (left + right) * near
                glcam.frustum_width = 0.5 * (right - left) * near
                glcam.frustum_bottom = bottom * near
                glcam.frustum_top = top * near
                glcam.frustum_near = near
                glcam.frustum_far = self.spec.far
                glcam.orthographic = 0
            if culler is not None:
                culler.hide(viewport.width, viewport.height)
            mujoco.mjr_render(viewport, scene, ctx)
        if culler is not None:
            culler.restore()
        mujoco.mjr_readPixels(self._rgb, self._z, self._rect, ctx)

    @property
    def atlas_rgb(self) -> np.ndarray:
        """``atlas_shape + (3,)`` uint8 face windows of the last frame, OpenGL rows."""
        return self._rgb

    @property
    def atlas_z(self) -> np.ndarray:
        """``atlas_shape`` float32 reversed-Z depth buffer of the last frame."""
        return self._z

    def render(self, data: mujoco.MjData, camera: str | int) -> tuple[np.ndarray, np.ndarray]:
        """Renders a fisheye frame of the state in ``data``.

        Args:
            data: the state, with current kinematics (``mj_forward`` or ``mj_kinematics`` +
                ``mj_camlight``).
            camera: name or id of the model camera that carries the fisheye pose.

        Returns:
            ``rgb`` ``(H, W, 3)`` uint8 and ``depth`` ``(H, W)`` float32: ray length (m) from
            the camera's position to the surface seen; 0 outside the image circle and where
            nothing lies within the far clip distance (RGB black outside the circle).

        Raises:
            FisheyeError: no such camera.
        """
        self.render_atlas(data, camera)
        lk = self.lookup
        res = self.spec.resolution
        values = self._resample @ self._rgb.reshape(-1, 3)  # (H*W, 3) float32
        rgb = (values + 0.5).astype(np.uint8)
        z = self._z.reshape(-1)[lk.nearest].astype(np.float64)
        zdepth = self._zd / (z + self._zc)
        ray = (zdepth * lk.ray_scale).astype(np.float32)
        ray[(z <= 0.0) | (ray > self.spec.far)] = 0.0
        depth = np.zeros(res * res, np.float32)
        depth[lk.pixels] = ray
        return rgb.reshape(res, res, 3), depth.reshape(res, res)

    def close(self) -> None:
        """Frees the GL context."""
        self.renderer.close()

    def __enter__(self) -> FisheyeRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = [
    "FACES",
    "PROJECTIONS",
    "CubeLookup",
    "FisheyeError",
    "FisheyeRenderer",
    "FisheyeSpec",
    "cube_lookup",
    "default_cube_size",
]
