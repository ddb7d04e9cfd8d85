"""Fisheye cameras: the projection's law and round trip, the cube-map lookup, and rendered
markers landing on their predicted pixels with the right ray-length depth (offscreen, CPU)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from factory.errors import FactoryError
from factory.sim.fisheye import (
    FisheyeError,
    FisheyeRenderer,
    FisheyeSpec,
    cube_lookup,
    default_cube_size,
)

# ---------------------------------------------------------------- geometry (no rendering)


def _direction(theta: float, phi: float) -> np.ndarray:
    """Camera-frame unit vector at angle theta from the optical axis (-z), azimuth phi from +x
    towards +y (up)."""
    return np.array(
        [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), -math.cos(theta)]
    )


@pytest.mark.parametrize("projection", ["equidistant", "equisolid"])
@pytest.mark.parametrize("fov", [120.0, 180.0, 270.0])
def test_project_unproject_round_trip(projection: str, fov: float) -> None:
    spec = FisheyeSpec(resolution=128, fov_deg=fov, projection=projection)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    theta = np.arccos(np.clip(-d[:, 2], -1, 1))
    d = d[theta < min(spec.theta_max, math.radians(175))]
    uv = spec.project(d * rng.uniform(0.1, 10, size=(len(d), 1)))  # any length
    back = spec.unproject(uv[:, 0], uv[:, 1])
    np.testing.assert_allclose(back, d, atol=1e-9)
    # and pixels -> directions -> pixels
    u, v = rng.uniform(0, 127, size=(2, 500))
    inside = np.hypot(u - spec.centre, v - spec.centre) <= spec.radius_px
    uv2 = spec.project(spec.unproject(u[inside], v[inside]))
    np.testing.assert_allclose(uv2, np.stack([u[inside], v[inside]], axis=1), atol=1e-9)
    # the optical axis is the image centre
    np.testing.assert_allclose(spec.project([0.0, 0.0, -1.0]), [spec.centre, spec.centre])


def test_equidistant_law() -> None:
    spec = FisheyeSpec(resolution=128, fov_deg=180.0)
    thetas = np.radians([0.0, 5.0, 10.0, 40.0, 80.0, 90.0])
    for phi in (0.0, 0.7, math.pi / 2, 3.0):
        uv = spec.project(np.stack([_direction(t, phi) for t in thetas]))
        r = np.hypot(uv[:, 0] - spec.centre, uv[:, 1] - spec.centre)
        np.testing.assert_allclose(r, spec.focal_px * thetas, atol=1e-9)  # r = f * theta
        assert r[-1] == pytest.approx(64.0)  # theta = fov / 2 lands on the circle (width / 2)
        # the azimuth is kept: +x is to the right, +y up (smaller row)
        ang = np.arctan2(spec.centre - uv[1:, 1], uv[1:, 0] - spec.centre)
        np.testing.assert_allclose(np.cos(ang - phi), 1.0, atol=1e-9)
    assert spec.focal_px == pytest.approx(64.0 / (math.pi / 2))
    u, v = spec.project(_direction(math.radians(40), 0.0))
    assert u > spec.centre and v == pytest.approx(spec.centre)
    # a wider lens puts the same angle closer to the centre
    wide = FisheyeSpec(resolution=128, fov_deg=240.0)
    assert wide.project(_direction(0.5, 0.0))[0] < spec.project(_direction(0.5, 0.0))[0]


def test_rays_and_mask() -> None:
    spec = FisheyeSpec(resolution=64, fov_deg=180.0)
    rays, mask = spec.rays, spec.mask
    assert rays.shape == (64, 64, 3) and mask.shape == (64, 64) and mask.dtype == bool
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0)
    theta = np.arccos(np.clip(-rays[..., 2], -1, 1))
    assert theta[mask].max() <= spec.theta_max + 1e-12
    assert not mask[0, 0] and mask[32, 32]
    assert mask.sum() == pytest.approx(math.pi / 4 * 64 * 64, rel=0.03)
    with pytest.raises(ValueError):
        rays[0, 0, 0] = 1.0  # read-only


def test_cube_lookup_uses_the_faces_it_needs() -> None:
    assert cube_lookup(FisheyeSpec(64, fov_deg=90.0), 32).faces == ("front",)
    five = cube_lookup(FisheyeSpec(64, fov_deg=180.0), 48)
    assert five.faces == ("front", "right", "left", "up", "down")
    # the front face whole, of each side face the half towards the front (and a pixel)
    assert five.windows[0] == (0, 0, 48, 48)
    assert [w[2] * w[3] for w in five.windows[1:]] == [25 * 48, 25 * 48, 46 * 25, 46 * 25]
    assert five.windows[1][0] == 0 and five.windows[2][0] + five.windows[2][2] == 48  # x
    assert five.windows[3][1] == 0 and five.windows[4][1] + five.windows[4][3] == 48  # y
    assert five.atlas_shape == (48, 48 + 25 + 25 + 46 + 46)
    assert five.frustum(0) == pytest.approx((-48 / 46, 48 / 46, -48 / 46, 48 / 46))
    narrow = cube_lookup(FisheyeSpec(64, fov_deg=60.0), 64)
    inner = 64 * math.tan(math.radians(30.0)) * 62 / 64  # the 60-degree cone's width (px)
    assert narrow.faces == ("front",) and inner <= narrow.windows[0][2] <= inner + 3
    six = cube_lookup(FisheyeSpec(64, fov_deg=270.0), 48)
    assert "back" in six.faces and len(six.faces) == 6
    n = int(FisheyeSpec(64).mask.sum())
    assert five.pixels.shape == (n,) and five.bilinear.shape == (n, 4)
    np.testing.assert_allclose(five.weights.sum(axis=1), 1.0, atol=1e-6)
    size = 48 * 190
    assert five.bilinear.min() >= 0 and five.bilinear.max() < size
    assert five.nearest.min() >= 0 and five.nearest.max() < size
    assert five.ray_scale.min() >= 1.0 and five.ray_scale.max() <= math.sqrt(3) * 1.05
    assert default_cube_size(FisheyeSpec(128)) == 96


@pytest.mark.parametrize(
    "kwargs",
    [
        {"resolution": 1},
        {"fov_deg": 0.0},
        {"fov_deg": 400.0},
        {"projection": "pinhole"},
        {"near": 0.0},
        {"near": 2.0, "far": 1.0},
    ],
)
def test_bad_spec(kwargs: dict) -> None:
    with pytest.raises(FisheyeError):
        FisheyeSpec(**kwargs)
    assert issubclass(FisheyeError, FactoryError)


def test_project_rejects_a_zero_direction() -> None:
    with pytest.raises(FisheyeError, match="zero"):
        FisheyeSpec().project([0.0, 0.0, 0.0])


# ---------------------------------------------------------------- rendering


RADIUS = 0.08  # m, marker spheres
# camera -> world of a camera at 1.5 m looking along world +x, +z up (x_cam = -y, y_cam = +z)
LEVEL = np.column_stack([(0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0)])
EYE = np.array([0.0, 0.0, 1.5])

# (theta deg, phi deg, distance m): 40 deg to the right, 80 deg up, 10 deg lower left, and one
# behind the camera (120 deg), outside a 180-degree lens
MARKERS = [(40.0, 0.0, 1.0), (80.0, 90.0, 1.5), (10.0, 225.0, 0.8), (120.0, 20.0, 1.0)]


def _marker_xml(positions: list[np.ndarray]) -> str:
    return "".join(
        f'<geom type="sphere" size="{RADIUS}" pos="{p[0]:.6f} {p[1]:.6f} {p[2]:.6f}" '
        'material="marker" contype="0" conaffinity="0"/>'
        for p in positions
    )


def _world(theta: float, phi: float, dist: float, rot: np.ndarray, eye: np.ndarray) -> np.ndarray:
    return eye + dist * (rot @ _direction(math.radians(theta), math.radians(phi)))


def _model(body: str, markers: str):
    import mujoco

    xml = f"""
    <mujoco>
      <asset><material name="marker" rgba="1 0 0 1" emission="1"/></asset>
      <worldbody>
        <light pos="0 0 4" dir="0 0 -1"/>
        <geom name="floor" type="plane" size="5 5 0.1" rgba="0.3 0.3 0.3 1"/>
        {body}
        {markers}
      </worldbody>
    </mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def _red(rgb: np.ndarray) -> np.ndarray:
    r, g, b = (rgb[..., k].astype(int) for k in range(3))
    return (r > 120) & (g < 70) & (b < 70)


def _blob(red: np.ndarray, uv: np.ndarray, within: float = 8.0) -> tuple[int, np.ndarray]:
    v, u = np.nonzero(red)
    near = np.hypot(u - uv[0], v - uv[1]) < within
    return int(near.sum()), np.array([u[near].mean(), v[near].mean()]) if near.any() else uv


def test_markers_land_on_their_predicted_pixels() -> None:
    import mujoco

    positions = [_world(t, p, d, LEVEL, EYE) for t, p, d in MARKERS]
    body = '<camera name="fish" pos="0 0 1.5" xyaxes="0 -1 0 0 0 1"/>'
    model = _model(body, _marker_xml(positions))
    offscreen = (model.vis.global_.offwidth, model.vis.global_.offheight)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.cam_xmat[0].reshape(3, 3), LEVEL, atol=1e-9)
    spec = FisheyeSpec(resolution=128, fov_deg=180.0)
    with FisheyeRenderer(model, spec) as fisheye:
        assert fisheye.faces == ("front", "right", "left", "up", "down")
        rgb, depth = fisheye.render(data, "fish")
        assert (model.vis.global_.offwidth, model.vis.global_.offheight) == offscreen
        with pytest.raises(FisheyeError, match="no camera"):
            fisheye.render(data, "nope")
    assert rgb.shape == (128, 128, 3) and rgb.dtype == np.uint8
    assert depth.shape == (128, 128) and depth.dtype == np.float32
    assert not rgb[~spec.mask].any() and not depth[~spec.mask].any()
    red = _red(rgb)
    seen = np.zeros_like(red)
    for theta, phi, dist in MARKERS[:3]:
        uv = spec.project(_direction(math.radians(theta), math.radians(phi)))
        count, centroid = _blob(red, uv)
        assert count >= 5, f"marker at {theta} deg not found near {uv}"
        assert np.hypot(*(centroid - uv)) < 2.0, (theta, centroid, uv)
        iu, iv = np.rint(uv).astype(int)
        assert depth[iv, iu] == pytest.approx(dist - RADIUS, abs=0.02), theta
        vv, uu = np.mgrid[:128, :128]
        seen |= np.hypot(uu - uv[0], vv - uv[1]) < 8.0
    # the marker behind the camera (120 deg) is absent at 180 deg: no other red pixel
    assert not (red & ~seen).any()

    # depth is the ray length: the floor 1.5 m below, seen along every pixel's own ray
    world_rays = spec.rays @ LEVEL.T
    down = -world_rays[..., 2]
    with np.errstate(divide="ignore"):
        expected = np.where(down > 0, EYE[2] / down, np.inf)
    floor = spec.mask & (down > math.cos(math.radians(40))) & ~seen  # incidence <= 40 deg
    err = np.abs(depth[floor] - expected[floor])
    assert floor.sum() > 500
    assert np.median(err) < 0.005 and err.max() < 0.03, (np.median(err), err.max())
    # the z-depth along the optical axis would be far off: this is not it
    z_along_axis = expected[floor] * -spec.rays[..., 2][floor]
    assert np.abs(depth[floor] - z_along_axis).max() > 0.5


def test_fisheye_on_a_moving_rolled_mount_with_the_back_face() -> None:
    import mujoco

    # a camera on a body turning about the vertical, itself rolled 30 deg about its optical axis
    roll = math.radians(30)
    x_cam = np.array([0.0, -math.cos(roll), math.sin(roll)])
    y_cam = np.array([0.0, math.sin(roll), math.cos(roll)])
    axes = " ".join(f"{c:.9f}" for c in (*x_cam, *y_cam))
    body = (
        '<body name="mount" pos="0.4 -0.3 1.2"><joint name="yaw" type="hinge" axis="0 0 1"/>'
        '<geom type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0" group="3"/>'
        f'<camera name="fish" pos="0 0 0" xyaxes="{axes}"/>'
        "</body>"
    )
    spec = FisheyeSpec(resolution=128, fov_deg=270.0)
    yaw = 0.6  # rad, the pose the markers are placed for
    rot_yaw = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0, 0, 1]]
    )
    rot = rot_yaw @ np.column_stack([x_cam, y_cam, np.cross(x_cam, y_cam)])
    eye = np.array([0.4, -0.3, 1.2])
    # 30 deg right; 130 deg towards upper right (drawn on the back face); 150 deg: beyond 135
    markers = [(30.0, 0.0, 1.0), (130.0, 45.0, 1.0), (150.0, 200.0, 1.0)]
    positions = [_world(t, p, d, rot, eye) for t, p, d in markers]
    model = _model(body, _marker_xml(positions))
    data = mujoco.MjData(model)
    data.qpos[0] = yaw
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.cam_xmat[0].reshape(3, 3), rot, atol=1e-6)
    with FisheyeRenderer(model, spec) as fisheye:
        assert "back" in fisheye.faces
        rgb, depth = fisheye.render(data, 0)
        red = _red(rgb)
        for theta, phi, dist in markers[:2]:
            uv = spec.project(_direction(math.radians(theta), math.radians(phi)))
            count, centroid = _blob(red, uv)
            assert count >= 3 and np.hypot(*(centroid - uv)) < 2.0, (theta, centroid, uv)
            iu, iv = np.rint(uv).astype(int)
            assert depth[iv, iu] == pytest.approx(dist - RADIUS, abs=0.02), theta
        beyond = spec.project(_direction(math.radians(150), math.radians(200)))
        assert _blob(red, beyond)[0] == 0
        # turning the mount turns the view: the 30-degree marker moves
        data.qpos[0] = yaw + 0.3
        mujoco.mj_forward(model, data)
        rgb2, _ = fisheye.render(data, "fish")
        uv = spec.project(_direction(math.radians(30), 0.0))
        assert _blob(_red(rgb2), uv, within=3.0)[0] == 0


def test_nearest_interpolation_copies_face_pixels() -> None:
    import mujoco

    positions = [_world(t, p, d, LEVEL, EYE) for t, p, d in MARKERS]
    model = _model(
        '<camera name="fish" pos="0 0 1.5" xyaxes="0 -1 0 0 0 1"/>', _marker_xml(positions)
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    spec = FisheyeSpec(resolution=64, fov_deg=200.0)
    with FisheyeRenderer(model, spec, cube_size=40, interpolation="nearest") as fisheye:
        assert fisheye.lookup.size == 40
        rgb, depth = fisheye.render(data, "fish")
        atlas = {tuple(c) for c in fisheye.atlas_rgb.reshape(-1, 3)}
    assert {tuple(c) for c in rgb[spec.mask]} <= atlas  # no blended colours
    assert (depth[spec.mask] > 0).mean() > 0.3  # the floor and the markers
    with pytest.raises(FisheyeError, match="interpolation"):
        FisheyeRenderer(model, spec, interpolation="cubic")  # type: ignore[arg-type]
    with pytest.raises(FisheyeError, match="cube face size"):
        FisheyeRenderer(model, spec, cube_size=3)
