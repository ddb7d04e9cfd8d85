"""Scene renders for people: a top-down view and four corner views (PNG).

Cameras are free cameras computed from the scene (no camera is added to the model): the top
view looks straight down on the whole floor plan; corner view ``k`` stands in corner ``k`` of
the scene's footprint (0: min x/min y, then counter-clockwise), near the ceiling, looking at the
centre of the floor. MuJoCo's offscreen renderer draws them with the model's lights and
materials, on EGL (GPU or Mesa) or OSMesa (see :mod:`factory.sim.gl`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from factory.errors import RenderError
from factory.schema import Scene
from factory.sim.gl import configure_gl
from factory.sim.images import contact_sheet, png_bytes

configure_gl("auto")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

VIEWS: tuple[str, ...] = ("top", "corner_0", "corner_1", "corner_2", "corner_3")


@dataclass(frozen=True)
class ViewCamera:
    """A free camera: look-at point (m, world), distance (m), azimuth/elevation (deg), fovy."""

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float
    fovy: float

    def mjv(self) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        return cam


def _looking(eye: Sequence[float], target: Sequence[float], fovy: float) -> ViewCamera:
    d = np.asarray(target, float) - np.asarray(eye, float)
    dist = float(np.linalg.norm(d))
    az = math.degrees(math.atan2(d[1], d[0]))
    el = math.degrees(math.asin(d[2] / dist))
    return ViewCamera(tuple(float(v) for v in target), dist, az, el, fovy)  # type: ignore[arg-type]


def view_cameras(scene: Scene, aspect: float = 4 / 3) -> dict[str, ViewCamera]:
    """The five standard cameras of a scene.

    Args:
        scene: the scene (its rooms' footprints and ceiling heights frame the views).
        aspect: image width / height.
    """
    xmin, ymin, xmax, ymax = scene.bounds_xy()
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    height = max(r.ceiling_height for r in scene.rooms)
    fovy_top = 45.0
    half_h = max((ymax - ymin) / 2, (xmax - xmin) / 2 / aspect) * 1.08 + 0.2
    dist_top = half_h / math.tan(math.radians(fovy_top / 2)) + height
    cams = {"top": ViewCamera((cx, cy, 0.0), dist_top, 90.0, -89.99, fovy_top)}
    inset = 0.25
    eye_z = max(1.2, min(height - 0.25, 2.4))
    corners = [
        (xmin + inset, ymin + inset),
        (xmax - inset, ymin + inset),
        (xmax - inset, ymax - inset),
        (xmin + inset, ymax - inset),
    ]
    for k, (ex, ey) in enumerate(corners):
        cams[f"corner_{k}"] = _looking((ex, ey, eye_z), (cx, cy, 0.45), 70.0)
    return cams


def render_views(
    model: mujoco.MjModel,
    scene: Scene,
    views: Sequence[str] = VIEWS,
    width: int = 640,
    height: int = 480,
) -> dict[str, np.ndarray]:
    """Renders the named views of a compiled scene at its initial state.

    Returns:
        ``view -> (height, width, 3) uint8`` RGB image.

    Raises:
        RenderError: unknown view, or no OpenGL context could be made.
    """
    unknown = [v for v in views if v not in VIEWS]
    if unknown:
        raise RenderError(f"unknown view(s) {unknown}: choose from {list(VIEWS)}")
    size = max(width, height)
    if model.vis.global_.offwidth < width or model.vis.global_.offheight < height:
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, size)
        model.vis.global_.offheight = max(model.vis.global_.offheight, size)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cams = view_cameras(scene, width / height)
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # GL errors come in several types
        raise RenderError(
            f"could not create an offscreen OpenGL context (MUJOCO_GL="
            f"{mujoco_gl()}): {e}. Install Mesa's EGL (apt-get install libegl1 libegl-mesa0 "
            "libgl1-mesa-dri) or OSMesa (libosmesa6) and set render.gl accordingly"
        ) from None
    images = {}
    fovy0 = float(model.vis.global_.fovy)
    try:
        for view in views:
            cam = cams[view]
            model.vis.global_.fovy = cam.fovy
            renderer.update_scene(data, cam.mjv())
            images[view] = renderer.render().copy()
    finally:
        model.vis.global_.fovy = fovy0
        renderer.close()
    return images


def mujoco_gl() -> str:
    import os

    return os.environ.get("MUJOCO_GL", "")


__all__ = ["VIEWS", "ViewCamera", "contact_sheet", "png_bytes", "render_views", "view_cameras"]
