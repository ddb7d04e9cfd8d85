"""Pictures of single assets: one asset on a grey floor, framed from the front-right."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from factory.schema import AssetMeta, AssetRef, Physics, Room, Scene, SceneObject, Size3, Vec3
from factory.sim.compile import compile_scene


def asset_scene(meta: AssetMeta) -> Scene:
    """A scene holding just the asset, centred in a room sized to it."""
    w, ln, h = meta.extents
    side = max(w, ln, h) * 3 + 1.0
    room = Room(
        id="studio",
        room_type="studio",
        position=Vec3(-side / 2, -side / 2, 0),
        dimensions=Size3(side, side, max(2.5, h * 1.5)),
        floor_material="concrete",
    )
    obj = SceneObject(
        id="asset",
        room_id="studio",
        category=meta.category or "object",
        position=Vec3(0, 0, 0),
        dimensions=Size3(w, ln, h),
        asset=AssetRef(backend=meta.backend, asset_id=meta.asset_id),
        physics=Physics(mass=meta.mass or 1.0, static=True),
    )
    return Scene(id="preview", rooms=[room], objects=[obj], source="example")


def render_asset(
    assets_dir: Path,
    meta: AssetMeta,
    width: int = 512,
    height: int = 512,
    azimuth: float = 120.0,
    elevation: float = -25.0,
    opened: float = 0.0,
    margin: float = 1.15,
) -> np.ndarray:
    """An RGB image ``(height, width, 3)`` of the asset, an articulated one with every joint
    at ``opened`` (0: closed, 1: its upper limit) of its range; ``margin`` scales the camera's
    distance (1: the bounding sphere of the closed extents fills the view)."""
    model = compile_scene(asset_scene(meta), assets_dir).model
    data = mujoco.MjData(model)
    if opened and meta.articulation is not None:
        for j in meta.articulation.joints:
            joint = model.joint(f"asset/{j.name}")
            data.qpos[joint.qposadr[0]] = opened * joint.range[1]
    mujoco.mj_forward(model, data)
    w, ln, h = meta.extents
    radius = 0.5 * math.sqrt(w * w + ln * ln + h * h)
    fovy = 35.0
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = [0, 0, h / 2]
    cam.distance = radius / math.tan(math.radians(fovy / 2)) * margin
    cam.azimuth, cam.elevation = azimuth, elevation
    model.vis.global_.fovy = fovy
    model.light_castshadow[:] = 0  # small objects: shadow-map acne outweighs the cue
    model.vis.headlight.ambient[:] = [0.45, 0.45, 0.45]
    renderer = mujoco.Renderer(model, height=height, width=width)
    try:
        renderer.update_scene(data, cam)
        return renderer.render().copy()
    finally:
        renderer.close()
