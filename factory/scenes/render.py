"""Scene renders for people: a top-down view, a plan view, corner views and a view per room
(PNG).

Cameras are free cameras computed from the scene (no camera is added to the model):

* ``top`` looks straight down on the whole floor plan (perspective);
* ``plan`` is an orthographic view straight down on the whole plan (x to the right, y up; the
  ceilings are hidden while it is drawn), the home's floor plan;
* ``corner_k`` stands inside a room, in its corner ``k`` (0: min x/min y, then
  counter-clockwise), near the ceiling, looking at the centre of that room's floor; the room
  is the one whose corner ``k`` is nearest to corner ``k`` of the whole plan, so in a one-room
  scene these are the room's four corners and in a home they look into the rooms at the
  home's corners, never across a wall;
* ``room_<room id>`` (homes of two rooms or more; ``rooms`` selects them all) stands in the
  corner of that room nearest to its first door where no tall object (a wardrobe) stands
  within 1 m, looking at the centre of its floor.

Where rays in the compiled scene find a corner or room view blocked (an object within 1 m in
its frustum: a lamp shade, a cabinet) or showing less than half of its room's objects, its eye
moves towards the room's centre or lower (:mod:`factory.scenes.view_rays`).

MuJoCo's offscreen renderer draws them with the model's lights and materials, on EGL (GPU or
Mesa) or OSMesa (see :mod:`factory.sim.gl`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from factory.errors import RenderError
from factory.schema import Room, Scene
from factory.sim.gl import configure_gl
from factory.sim.images import contact_sheet, png_bytes

configure_gl("auto")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

VIEWS: tuple[str, ...] = ("top", "corner_0", "corner_1", "corner_2", "corner_3")
"""The five standard views of every scene (the tools' ``render_views`` and the VLM critic)."""
PLAN = "plan"
"""The orthographic plan view."""
ROOMS = "rooms"
"""Selects every ``room_<id>`` view of a scene."""
ROOM_PREFIX = "room_"
HIDDEN_GROUP = 5
"""The geom group the plan view leaves out (MuJoCo's last; the ceilings while it draws)."""
EYE_INSET = 0.25
"""How far a corner camera stands from the walls' centre lines (m): inside the room."""


@dataclass(frozen=True)
class ViewCamera:
    """A free camera: look-at point (m, world), distance (m), azimuth/elevation (deg), fovy
    (deg; for an ``orthographic`` camera the height of the view, m)."""

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float
    fovy: float
    orthographic: bool = False

    def mjv(self) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        cam.orthographic = int(self.orthographic)
        return cam


def _looking(eye: Sequence[float], target: Sequence[float], fovy: float) -> ViewCamera:
    d = np.asarray(target, float) - np.asarray(eye, float)
    dist = float(np.linalg.norm(d))
    az = math.degrees(math.atan2(d[1], d[0]))
    el = math.degrees(math.asin(d[2] / dist))
    return ViewCamera(tuple(float(v) for v in target), dist, az, el, fovy)  # type: ignore[arg-type]


def room_view(room_id: str) -> str:
    """The name of a room's view."""
    return f"{ROOM_PREFIX}{room_id}"


def scene_views(scene: Scene) -> tuple[str, ...]:
    """Every view a scene has: the standard five, ``plan``, and one per room in a home."""
    rooms = tuple(room_view(r.id) for r in scene.rooms) if len(scene.rooms) > 1 else ()
    return (*VIEWS, PLAN, *rooms)


def _corners(room: Room) -> list[tuple[float, float]]:
    """A room's corners, counter-clockwise from min x/min y, ``EYE_INSET`` inside (m)."""
    x0, y0 = room.position.x, room.position.y
    x1, y1 = x0 + room.dimensions.width, y0 + room.dimensions.length
    i = min(EYE_INSET, room.dimensions.width / 4, room.dimensions.length / 4)
    return [(x0 + i, y0 + i), (x1 - i, y0 + i), (x1 - i, y1 - i), (x0 + i, y1 - i)]


def _door_point(room: Room) -> tuple[float, float] | None:
    walls = {w.id: w for w in room.walls}
    for door in room.doors:
        w = walls.get(door.wall_id)
        if w is not None:
            t = door.position_on_wall
            return (w.start.x + (w.end.x - w.start.x) * t, w.start.y + (w.end.y - w.start.y) * t)
    return None


ROOM_FOVY = 70.0
"""Vertical field of view of the corner and room views (deg)."""


def _room_eyes(scene: Scene) -> dict[str, tuple[Room, tuple[float, float, float]]]:
    """The views that look into one room (``corner_k``; ``room_<id>`` in a home): the room and
    the eye (m, world) that :func:`view_cameras` gives them."""
    xmin, ymin, xmax, ymax = scene.bounds_xy()
    height = max(r.ceiling_height for r in scene.rooms)
    eye_z = max(1.2, min(height - 0.25, 2.4))
    box = [(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)]
    eyes: dict[str, tuple[Room, tuple[float, float, float]]] = {}
    for k, (bx, by) in enumerate(box):
        room = min(
            scene.rooms,
            key=lambda r: math.hypot(_corners(r)[k][0] - bx, _corners(r)[k][1] - by),
        )
        eyes[f"corner_{k}"] = (room, (*_corners(room)[k], eye_z))
    if len(scene.rooms) > 1:
        for room in scene.rooms:
            corners = _corners(room)
            room_eye_z = max(1.2, min(room.ceiling_height - 0.25, 2.4))
            door = _door_point(room)
            order = sorted(range(4), key=lambda j: math.dist(corners[j], door) if door else j)
            free = [j for j in order if not _blocked(scene, room, corners[j], room_eye_z)]
            eyes[room_view(room.id)] = (room, (*corners[(free or order)[0]], room_eye_z))
    return eyes


def _room_target(room: Room) -> tuple[float, float, float]:
    """Where a view into ``room`` looks: the middle of its floor, 0.45 m up (m, world)."""
    return (
        room.position.x + room.dimensions.width / 2,
        room.position.y + room.dimensions.length / 2,
        0.45,
    )


def view_cameras(scene: Scene, aspect: float = 4 / 3) -> dict[str, ViewCamera]:
    """The cameras of a scene: every view of :func:`scene_views` (the corner and room views
    from the scene alone; :func:`render_views` moves their eyes where rays find them blocked:
    :mod:`factory.scenes.view_rays`).

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
    eyes = _room_eyes(scene)
    for view, (room, eye) in eyes.items():
        if view.startswith("corner_"):
            cams[view] = _looking(eye, _room_target(room), ROOM_FOVY)
    cams[PLAN] = ViewCamera((cx, cy, 0.0), height + 10.0, 90.0, -90.0, 2 * half_h, True)
    for view, (room, eye) in eyes.items():
        if view.startswith(ROOM_PREFIX):
            cams[view] = _looking(eye, _room_target(room), ROOM_FOVY)
    return cams


def clear_view_cameras(
    model: mujoco.MjModel, scene: Scene, views: Sequence[str], aspect: float = 4 / 3
) -> tuple[dict[str, ViewCamera], dict[str, Any]]:
    """:func:`view_cameras`, with the eyes of the named corner and room views moved where
    nothing within 1 m blocks them and they show at least half of the room's objects
    (:func:`factory.scenes.view_rays.clear_eye`, rays in the compiled ``model``).

    Returns:
        the cameras and, per checked view, ``{"blocked", "seen", "objects", "moved_m"}``.
    """
    from factory.scenes.view_rays import clear_eye, rays_in

    cams = view_cameras(scene, aspect)
    eyes = {v: e for v, e in _room_eyes(scene).items() if v in views}
    checks: dict[str, Any] = {}
    if not eyes:
        return cams, checks
    rays = rays_in(model, scene)
    for view, (room, eye) in eyes.items():
        target = _room_target(room)
        v = clear_eye(rays, scene, room, eye, target, ROOM_FOVY, aspect)
        cams[view] = _looking(v.eye, target, ROOM_FOVY)
        checks[view] = {
            "blocked": v.blocked,
            "seen": v.seen,
            "objects": v.objects,
            "moved_m": round(math.dist(v.eye, eye), 2),
        }
    return cams, checks


def _blocked(scene: Scene, room: Room, eye: tuple[float, float], eye_z: float) -> bool:
    """Whether a tall object (its top within 0.6 m of the eye's height) stands within 1 m of
    the eye: a wardrobe in the corner would fill the view."""
    return any(
        o.room_id == room.id
        and o.position.z + o.dimensions.height > eye_z - 0.6
        and math.dist((o.position.x, o.position.y), eye) < 1.0
        for o in scene.objects
    )


def expand_views(scene: Scene, views: Sequence[str]) -> list[str]:
    """The views named, with ``rooms`` replaced by the scene's room views (none in a
    one-room scene); duplicates dropped.

    Raises:
        RenderError: a view the scene does not have.
    """
    known = scene_views(scene)
    out: list[str] = []
    for v in views:
        names = [n for n in known if n.startswith(ROOM_PREFIX)] if v == ROOMS else [v]
        for n in names:
            if n not in known:
                raise RenderError(
                    f"unknown view {n!r} for scene {scene.id!r}: choose from "
                    f"{[*VIEWS, PLAN, ROOMS]} or room_<room id> of a home's rooms"
                )
            if n not in out:
                out.append(n)
    return out


def render_views(
    model: mujoco.MjModel,
    scene: Scene,
    views: Sequence[str] = VIEWS,
    width: int = 640,
    height: int = 480,
) -> dict[str, np.ndarray]:
    """Renders the named views of a compiled scene at its initial state.

    Args:
        model: the compiled scene.
        scene: the scene (the cameras are computed from its rooms).
        views: view names (:func:`scene_views`), ``rooms`` for every room view.
        width, height: image size (px).

    Returns:
        ``view -> (height, width, 3) uint8`` RGB image.

    Raises:
        RenderError: unknown view, or no OpenGL context could be made.
    """
    views = expand_views(scene, views)
    size = max(width, height)
    if model.vis.global_.offwidth < width or model.vis.global_.offheight < height:
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, size)
        model.vis.global_.offheight = max(model.vis.global_.offheight, size)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cams, _ = clear_view_cameras(model, scene, views, width / height)
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
    ortho0 = int(model.vis.global_.orthographic)
    ceilings = [
        g
        for g in range(model.ngeom)
        if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith("/ceiling")
    ]
    group0 = model.geom_group[ceilings].copy()
    hide = mujoco.MjvOption()
    hide.geomgroup[HIDDEN_GROUP] = 0
    try:
        for view in views:
            cam = cams[view]
            model.vis.global_.fovy = cam.fovy
            model.vis.global_.orthographic = int(cam.orthographic)
            # a plan shows the rooms from above: its ceilings go to a group it does not draw
            model.geom_group[ceilings] = HIDDEN_GROUP if cam.orthographic else group0
            renderer.update_scene(data, cam.mjv(), hide if cam.orthographic else None)
            images[view] = renderer.render().copy()
    finally:
        model.vis.global_.fovy = fovy0
        model.vis.global_.orthographic = ortho0
        model.geom_group[ceilings] = group0
        renderer.close()
    return images


def mujoco_gl() -> str:
    import os

    return os.environ.get("MUJOCO_GL", "")


__all__ = [
    "PLAN",
    "ROOMS",
    "VIEWS",
    "ViewCamera",
    "clear_view_cameras",
    "contact_sheet",
    "expand_views",
    "png_bytes",
    "render_views",
    "room_view",
    "scene_views",
    "view_cameras",
]
