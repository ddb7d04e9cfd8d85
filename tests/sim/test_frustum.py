"""Frustum culling (``factory.sim.frustum``): hidden geoms are the ones no pixel shows."""

from __future__ import annotations

import numpy as np
import pytest

from factory.sim.gl import configure_gl

configure_gl("auto")
mujoco = pytest.importorskip("mujoco")

from factory.sim.frustum import FrustumCuller


def _model() -> mujoco.MjModel:
    """A floor, a ring of 36 boxes, spheres and capsules around a camera at the origin
    (1.2 m up, looking along +x), and a mesh behind it."""
    rng = np.random.default_rng(3)
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[10, 10, 0.1])
    spec.worldbody.add_light(pos=[0, 0, 4], dir=[0, 0, -1])
    kinds = (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE)
    for k in range(36):
        a = np.radians(10 * k)
        r = rng.uniform(1.0, 4.0)
        spec.worldbody.add_geom(
            type=kinds[k % 3],
            size=[rng.uniform(0.05, 0.3), 0.1, 0.15],
            pos=[r * np.cos(a), r * np.sin(a), rng.uniform(0.2, 2.0)],
            rgba=[*rng.uniform(0.2, 1.0, 3), 1.0],
        )
    verts = rng.normal(size=(40, 3)) * 0.2
    spec.add_mesh(name="rock", uservert=verts.ravel().tolist())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="rock", pos=[-2, 0, 1])
    spec.worldbody.add_camera(name="eye", pos=[0, 0, 1.2], xyaxes=[0, -1, 0, 0, 0, 1], fovy=60)
    return spec.compile()


def _render(model: mujoco.MjModel, cull: bool, width: int, height: int):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    model.vis.quality.offsamples = 0
    with mujoco.Renderer(model, height, width) as r:
        r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        r.update_scene(data, camera="eye")
        culler = FrustumCuller(model)
        culler.bind(r.scene, data)
        hidden = culler.hide(width, height) if cull else 0
        rgb = r.render().copy()
        r.enable_depth_rendering()
        depth = r.render().copy()
        culler.restore()
        types = [g.type for g in r.scene.geoms[: r.scene.ngeom]]
    return rgb, depth, hidden, types, culler


@pytest.mark.parametrize("size", [(64, 64), (96, 48)])
def test_culled_images_are_the_same(size: tuple[int, int]) -> None:
    model = _model()
    rgb, depth, hidden, types, _ = _render(model, True, *size)
    rgb0, depth0, _, types0, _ = _render(model, False, *size)
    assert hidden >= 15  # most of the ring and the rock behind the camera
    assert np.array_equal(rgb, rgb0) and np.array_equal(depth, depth0)
    assert types == types0  # restored


def test_outside_is_conservative() -> None:
    """Every hidden geom's bounding sphere projects outside the image; the visible ones'
    centres include every geom whose centre lies inside the frustum."""
    model = _model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, 1000)
    mujoco.mjv_updateScene(
        model,
        data,
        mujoco.MjvOption(),
        None,
        _fixed_camera(model),
        mujoco.mjtCatBit.mjCAT_ALL,
        scene,
    )
    culler = FrustumCuller(model)
    culler.bind(scene, data)
    out = culler.outside(64, 64)
    cam = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
    fwd = np.asarray(cam.forward)
    up = np.asarray(cam.up)
    side = np.cross(fwd, up)
    tan = cam.frustum_top / cam.frustum_near
    dirs = np.random.default_rng(0).normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for k, gid in enumerate(culler._ids):
        pts = data.geom_xpos[gid] + model.geom_rbound[gid] * dirs
        rel = pts - np.asarray(cam.pos)
        z, x, y = rel @ fwd, rel @ side, rel @ up
        seen = (z > cam.frustum_near) & (np.abs(x) < tan * z) & (np.abs(y) < tan * z)
        if out[k]:
            assert not seen.any(), model.geom(gid).name
    assert 0 < out.sum() < len(out)


def _fixed_camera(model: mujoco.MjModel) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
    cam.fixedcamid = model.camera("eye").id
    return cam


def test_nothing_hidden_with_shadows() -> None:
    model = _model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, 32, 32) as r:
        r.update_scene(data, camera="eye")
        assert r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW]
        culler = FrustumCuller(model)
        culler.bind(r.scene, data)
        assert culler.hide(32, 32) == 0
