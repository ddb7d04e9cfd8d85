"""``factory.demos.record.frame_render``: depth as recorded, never a NaN cast; the OpenGL
camera strip's near clip plane is 1 cm from the lens whatever the scene's extent."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from factory.demos.record.frame_render import (
    DEPTH_FAR_MM,
    NEAR_CLIP_M,
    CameraStrip,
    encode_depth,
    size_offscreen,
)

NEAR_XML = """
<mujoco>
  <worldbody>
    <light pos="0 0 3"/>
    <geom name="floor" type="box" size="{half} {half} 0.01" pos="0 0 -0.01" rgba="0.8 0.8 0.8 1"/>
    <camera name="eye" pos="0 0 1" xyaxes="1 0 0 0 1 0" fovy="60"/>
    <geom name="near" type="box" size="0.005 0.005 0.005" pos="0 0 {near_z}" rgba="1 0 0 1"/>
  </worldbody>
</mujoco>
"""
"""A camera 1 m above a floor looking down, a red 1 cm cube ``1 - near_z - 0.005`` m below the
lens, in a scene ``half`` m wide (its ``stat.extent`` grows with it)."""


def test_depth_that_is_not_finite_is_stored_as_the_far_value() -> None:
    """A pixel whose depth is NaN or infinite (a ray that hit nothing) is stored as the far
    value in both formats, without numpy's "invalid value encountered in cast" (the warning
    a bare GPU machine's CPU tail printed); finite depths round to millimetres and clip."""
    depth = np.array([[0.5, np.nan], [np.inf, 70.0]], np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mm = encode_depth(depth, "uint16_mm")
        m = encode_depth(depth, "float32", far_m=50.0)
    assert mm.dtype == np.uint16
    assert mm.tolist() == [[500, DEPTH_FAR_MM], [DEPTH_FAR_MM, 65535]]
    assert m.dtype == np.float32 and m.tolist() == [[0.5, 50.0], [50.0, 70.0]]


@pytest.mark.parametrize("half", [1.0, 20.0])
def test_camera_strip_sees_what_is_a_few_centimetres_from_the_lens(half: float) -> None:
    """A cube 3 cm below the camera fills the middle of its image at 30 mm of depth, in a
    small scene and in one 40 m wide (MuJoCo's own near plane, 1 % of the extent, would be
    40 cm there and hide it): the strip's near plane is :data:`NEAR_CLIP_M`, as the GPU
    renderer's, and the floor beyond it still reads its depth."""
    from factory.sim.gl import configure_gl

    configure_gl("auto")
    model = mujoco.MjModel.from_xml_string(NEAR_XML.format(half=half, near_z=0.965))
    assert model.stat.extent * model.vis.map.znear > 0.03 or half <= 1
    size_offscreen(model, 32, 32)
    strip = CameraStrip(model, [model.camera("eye").id], 32, 32, "uint16_mm")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    try:
        (rgb,), (depth,) = strip.render(data)
    finally:
        strip.close()
    assert model.vis.map.znear * model.stat.extent == pytest.approx(NEAR_CLIP_M)
    centre = (slice(13, 19), slice(13, 19))
    assert (np.abs(depth[centre].astype(int) - 30) <= 1).all(), depth[centre]
    assert (rgb[centre][..., 0] > 2 * rgb[centre][..., 1]).all()  # the red cube
    assert abs(int(depth[0, 0]) - 1000) <= 2  # the floor, 1 m away at the corner's axis depth
