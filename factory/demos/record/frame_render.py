"""Fixed cameras drawn side by side in one OpenGL pass: RGB and depth read back together.

The pinhole part of both recording renderers (the fixed-base task's
:class:`~factory.demos.execute.cpu.FrameRenderer` and the mobile task's
:class:`~factory.tasks.mobile_pick_place.execute.MobileRenderer`): :class:`CameraStrip` draws its
cameras into one offscreen buffer and reads it back at once (one GPU synchronization per frame);
:func:`size_offscreen` prepares a model's offscreen buffer for it and :func:`encode_depth`
stores depth as recorded.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np


def size_offscreen(model: mujoco.MjModel, width: int, height: int) -> None:
    """Turns multisampling off (1.7x faster on Mesa at 128 px) and grows the model's offscreen
    buffer to at least ``width`` x ``height`` (px); call before the GL context is made."""
    vis = model.vis
    vis.quality.offsamples = 0
    vis.global_.offwidth = max(vis.global_.offwidth, width)
    vis.global_.offheight = max(vis.global_.offheight, height)


NEAR_CLIP_M = 0.01
"""Near clip distance (m) of every recording and observation camera, OpenGL's and MuJoCo Warp's
alike (:data:`factory.demos.execute.warp.RENDER_CLIP`) and the fisheye renderer's: 1 cm from the
lens, whatever the room. MuJoCo's own near plane is ``vis.map.znear`` times the model's
``stat.extent``: 1 % of a kitchen's extent is 5-10 cm, which cut the hand's own fingers and
palm (4-5 cm from the lens) out of the wrist camera's view on OpenGL only (MuJoCo Warp's ray
tracer has no near plane: its wrist images showed them, 18 % of the wrist depth pixels differed
by more than 1 cm, and a camera policy trained on OpenGL's images lost 25 points on MuJoCo
Warp). The object being grasped stays in view either way (more than 10 cm from the lens); the
fingers now cover part of it, as a real wrist camera's do (``scripts/bench_env_images.py
--grasp-view``)."""


def set_near_clip(model: mujoco.MjModel, near_m: float = NEAR_CLIP_M) -> None:
    """Sets ``model``'s near clip plane (``vis.map.znear``, a fraction of ``stat.extent``) to
    ``near_m`` metres from each camera."""
    model.vis.map.znear = near_m / max(float(model.stat.extent), 1e-9)


DEPTH_FAR_MM = 65535
"""``uint16_mm`` depth of a pixel that sees nothing within the renderer's range, or whose depth
is not a finite number: the far value (the largest uint16; every farther depth clips to it)."""


def encode_depth(depth: np.ndarray, fmt: str, far_m: float = float("inf")) -> np.ndarray:
    """Depth (m) as recorded: ``uint16_mm`` (millimetres, clipped to uint16) or ``float32`` (m).

    A depth that is not a finite number (NaN, or infinite: a ray that hit nothing in some
    renderers) is stored as the far value, never cast as it is (a NaN cast to uint16 is
    undefined): :data:`DEPTH_FAR_MM`, or ``far_m`` (the renderer's far distance) for
    ``float32``."""
    d = np.asarray(depth, np.float32)
    bad = ~np.isfinite(d)
    if fmt == "uint16_mm":
        mm = np.round(np.where(bad, 0.0, d) * 1000.0)
        out = np.clip(mm, 0, 65535).astype(np.uint16)
        out[bad] = DEPTH_FAR_MM
        return out
    out = d.astype(np.float32, copy=True)
    out[bad] = far_m
    return out


class CameraStrip:
    """Renders fixed cameras side by side into one offscreen buffer: RGB and depth of one pass.

    Reflections and the skybox are off, shadows unless ``shadows``; collision geoms (group 3)
    and sites are hidden. Depth is the depth buffer of the RGB pass (distance along the optical
    axis), so it matches the image. The near clip plane is :data:`NEAR_CLIP_M` from each
    camera (written into ``model``, :func:`set_near_clip`), the GPU renderer's.

    With ``cull``, each view draws only what it can see: the GL context is made from
    :func:`factory.sim.render_model.render_model`'s copy of ``model`` (infinite ground planes
    as a few large quads), each view's scene (made from ``model`` itself, so fields written
    into it show) has its infinite planes resized to match, and the geoms outside the view's
    frustum are skipped (:class:`factory.sim.frustum.FrustumCuller`).

    Args:
        model: the model the scenes are made from (its offscreen buffer sized already, see
            :func:`size_offscreen`).
        cams: ids of the fixed cameras, left to right.
        width, height: size of one camera's image (px).
        depth: depth format, see :func:`encode_depth`.
        shadows: draw the lights' shadows.
        cull: draw a finite-plane copy and skip the geoms outside each view.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        cams: Sequence[int],
        width: int,
        height: int,
        depth: str,
        shadows: bool = False,
        cull: bool = True,
    ) -> None:
        from factory.sim.frustum import FrustumCuller
        from factory.sim.render_model import infinite_planes, render_model

        set_near_clip(model)
        self.model = model
        self.cams = list(cams)
        self.width, self.height, self.depth = width, height, depth
        self.culler = FrustumCuller(model) if cull else None
        self._planes = frozenset(infinite_planes(model)) if cull else frozenset()
        half = 1.05 * float(model.vis.map.zfar * model.stat.extent)
        # render_model's finite plane: spacing = half, 4 x 4 quads
        self._plane_size = np.array([half, half, half / 2.0])
        self._geom_obj = int(mujoco.mjtObj.mjOBJ_GEOM)
        self._catmask = int(mujoco.mjtCatBit.mjCAT_ALL)
        n = len(self.cams)
        # the GL context bakes each plane's grid from the model it is made with
        drawn = render_model(model) if cull else model
        self.renderer = mujoco.Renderer(drawn, height, n * width)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        flags = self.renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
        self.option.sitegroup[:] = 0
        self._rgb = np.empty((height, n * width, 3), np.uint8)
        self._z = np.empty((height, n * width), np.float32)
        self._rect = mujoco.MjrRect(0, 0, n * width, height)
        extent = model.stat.extent
        self._near = np.float32(model.vis.map.znear * extent)
        self._far = np.float32(model.vis.map.zfar * extent)

    def _metric(self, z: np.ndarray) -> np.ndarray:
        """Reversed-Z depth buffer -> distance along the optical axis (m), as mujoco.Renderer."""
        near, far = self._near, self._far
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        c = np.float32(-0.5) * c - np.float32(0.5)
        d = np.float32(-0.5) * d
        return (d / (z.astype(np.float64) + c)).astype(np.float32)

    def render(self, data: mujoco.MjData) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """RGB (H, W, 3) uint8 and depth (H, W) images per camera of the state in ``data``
        (current kinematics needed), depth as :func:`encode_depth` with ``depth``."""
        r = self.renderer
        r._gl_context.make_current()
        ctx = r._mjr_context
        w, h = self.width, self.height
        culler = self.culler
        for k, cam in enumerate(self.cams):
            # the scene from this model (appearance patches are written into it), drawn with
            # the context of its render copy
            self._camera.fixedcamid = cam
            mujoco.mjv_updateScene(
                self.model, data, self.option, None, self._camera, self._catmask, r.scene
            )
            if self._planes:
                self._finite_planes(r.scene)
            if culler is not None:
                culler.bind(r.scene, data)
                culler.hide(w, h)
            mujoco.mjr_render(mujoco.MjrRect(k * w, 0, w, h), r.scene, ctx)
            if culler is not None:
                culler.restore()
        mujoco.mjr_readPixels(self._rgb, self._z, self._rect, ctx)
        rgb = np.flipud(self._rgb)
        depth = encode_depth(self._metric(np.flipud(self._z)), self.depth, float(self._far))
        rgbs = [rgb[:, k * w : (k + 1) * w].copy() for k in range(len(self.cams))]
        depths = [depth[:, k * w : (k + 1) * w].copy() for k in range(len(self.cams))]
        return rgbs, depths

    def _finite_planes(self, scene: mujoco.MjvScene) -> None:
        """Resizes the scene's infinite planes to :func:`~factory.sim.render_model.render_model`'s
        finite ones. ``mjv_updateScene`` adds geoms in model order, so model geom ``g`` is at
        most at slot ``g``."""
        for k in range(min(int(scene.ngeom), max(self._planes) + 1)):
            g = scene.geoms[k]
            if g.objtype == self._geom_obj and g.objid in self._planes:
                g.size[:] = self._plane_size

    def close(self) -> None:
        """Frees the GL context."""
        self.renderer.close()
