"""Frustum culling for MuJoCo's OpenGL renderer: geoms no view can see are not drawn.

``mjr_render`` draws every geom of an ``mjvScene`` for every viewport, so a scene drawn from
13 views per frame (the mobile task's three pinhole cameras and two fisheye cameras of five
cube faces each) sends all its triangles through the vertex stage 13 times; on a CPU
(Mesa llvmpipe) that is most of a frame's time. :class:`FrustumCuller` hides, for one view at a
time, the geoms whose bounding sphere lies wholly outside that view's frustum, by setting their
``mjvGeom.type`` to ``mjGEOM_NONE`` (``mjr_render`` then draws nothing for them) and restoring it
after the draw. A hidden geom would have produced no fragment, so the images are the same bit
for bit (lighting in ``mjr_render`` does not depend on other geoms; shadows and reflections,
which do, must be off: the culler refuses to hide anything while either flag is on).

Frames: the view is the scene's OpenGL camera (``scene.camera``, the average of the stereo
pair, as ``mjr_render`` uses it), world frame, metres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import mujoco


class FrustumCuller:
    """Hides the geoms of a scene outside one view's frustum while that view is drawn.

    Usage, per frame: ``mjv_updateScene`` (or ``Renderer.update_scene``), then
    :meth:`bind` once, then for each view ``hide(viewport)`` -> ``mjr_render`` ->
    :meth:`restore` (after the last view the scene is as ``mjv_updateScene`` left it).

    Only geoms of the model (``objtype`` geom) with a finite bounding sphere
    (``geom_rbound`` > 0: not planes) are ever hidden; decorations, flexes and skins stay.

    Args:
        model: the compiled model the scene is made from.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        import mujoco

        self.model = model
        self._none = int(mujoco.mjtGeom.mjGEOM_NONE)
        self._geom_obj = int(mujoco.mjtObj.mjOBJ_GEOM)
        self._shadow = int(mujoco.mjtRndFlag.mjRND_SHADOW)
        self._reflection = int(mujoco.mjtRndFlag.mjRND_REFLECTION)
        self._scene: mujoco.MjvScene | None = None
        self._wrappers: tuple = ()
        self._slots = np.zeros(0, np.int64)  # scene indices of cullable geoms
        self._ids = np.zeros(0, np.int64)  # their model geom ids
        self._types = np.zeros(0, np.int64)
        self._centres = np.zeros((0, 3))
        self._radii = np.zeros(0)
        self._hidden: np.ndarray = np.zeros(0, np.int64)
        self.hidden_total = 0
        """Geoms hidden so far, summed over views (for statistics)."""
        self.views = 0
        """Views culled so far."""

    def bind(self, scene: mujoco.MjvScene, data: mujoco.MjData) -> None:
        """Takes the scene's geoms after ``mjv_updateScene`` with ``data`` (current
        kinematics): which can be hidden, their centres (``data.geom_xpos``) and radii."""
        self.restore()
        m = self.model
        wrappers = scene.geoms[: int(scene.ngeom)]
        slots, ids, types = [], [], []
        for k, g in enumerate(wrappers):  # ~0.1 us per geom: cheap enough to redo per frame
            if (
                g.objtype == self._geom_obj
                and 0 <= g.objid < m.ngeom
                and m.geom_rbound[g.objid] > 0
            ):
                slots.append(k)
                ids.append(g.objid)
                types.append(g.type)
        self._scene = scene
        self._wrappers = tuple(wrappers)
        self._slots = np.array(slots, np.int64)
        self._ids = np.array(ids, np.int64)
        self._types = np.array(types, np.int64)
        self._radii = np.asarray(m.geom_rbound[self._ids], np.float64)
        self._centres = np.asarray(data.geom_xpos[self._ids], np.float64)

    def outside(self, viewport_width: int, viewport_height: int) -> np.ndarray:
        """Bool per cullable geom: its bounding sphere is wholly outside the frustum of the
        scene's current OpenGL camera drawn into a viewport of this size (pixels)."""
        import mujoco

        scene = self._scene
        if scene is None or not len(self._ids):
            return np.zeros(len(self._ids), bool)
        cam = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
        if cam.orthographic:
            return np.zeros(len(self._ids), bool)
        near, far = float(cam.frustum_near), float(cam.frustum_far)
        half_w = (
            float(cam.frustum_width)
            if cam.frustum_width
            else 0.5 * viewport_width / viewport_height * (cam.frustum_top - cam.frustum_bottom)
        )
        left = (float(cam.frustum_center) - half_w) / near  # tangents at unit distance
        right = (float(cam.frustum_center) + half_w) / near
        bottom, top = float(cam.frustum_bottom) / near, float(cam.frustum_top) / near
        fwd = np.asarray(cam.forward, np.float64)
        up = np.asarray(cam.up, np.float64)
        fwd = fwd / np.linalg.norm(fwd)
        up = up - fwd * (up @ fwd)
        up = up / np.linalg.norm(up)
        side = np.cross(fwd, up)
        rel = self._centres - np.asarray(cam.pos, np.float64)
        z = rel @ fwd
        x = rel @ side
        y = rel @ up
        r = self._radii
        out = (z < near - r) | (z > far + r)
        # side planes through the eye: x = t z has the outward normal (1, -t)/sqrt(1 + t^2)
        for t, coord, sign in ((right, x, 1.0), (left, x, -1.0), (top, y, 1.0), (bottom, y, -1.0)):
            out |= sign * (coord - t * z) / np.sqrt(1.0 + t * t) > r
        return out

    def hide(self, viewport_width: int, viewport_height: int) -> int:
        """Hides the geoms outside the current view (see :meth:`outside`) until
        :meth:`restore`; returns how many. Hides nothing while shadows or reflections are
        on (other geoms could then change the image)."""
        self.restore()
        scene = self._scene
        if scene is None or scene.flags[self._shadow] or scene.flags[self._reflection]:
            return 0
        hidden = np.flatnonzero(self.outside(viewport_width, viewport_height))
        wrappers, slots = self._wrappers, self._slots
        for k in hidden:
            wrappers[slots[k]].type = self._none
        self._hidden = hidden
        self.hidden_total += len(hidden)
        self.views += 1
        return len(hidden)

    def restore(self) -> None:
        """Gives the hidden geoms their types back."""
        if not len(self._hidden):
            return
        wrappers, slots, types = self._wrappers, self._slots, self._types
        for k in self._hidden:
            wrappers[slots[k]].type = int(types[k])
        self._hidden = np.zeros(0, np.int64)
