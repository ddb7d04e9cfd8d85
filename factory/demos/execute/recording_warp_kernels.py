# mypy: ignore-errors
"""Warp kernels of the GPU renderer of recorded states
(:mod:`factory.demos.execute.recording_render_warp`).

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types.
Importing this module imports Warp (not cheap); only the renderer imports it.
"""

import warp as wp


@wp.kernel
def to_images(
    packed: wp.array2d(dtype=wp.uint32),
    depth: wp.array2d(dtype=float),
    ray_start: wp.array(dtype=int),
    ray_npix: wp.array(dtype=int),
    ray_scale: wp.array(dtype=float),
    ray_inside: wp.array(dtype=int),
    ray_miss: wp.array(dtype=float),
    ray_far: wp.array(dtype=float),
    nworld: int,
    depth_mm: int,
    rgb_out: wp.array(dtype=wp.uint8),
    mm_out: wp.array(dtype=wp.uint16),
    m_out: wp.array(dtype=float),
):
    """The renderer's packed ARGB pixels and depth of ray ``r`` of world ``w`` -> the image
    blocks, camera-major: camera ``c`` (rays ``[s, s + n)``) fills ``rgb_out[3 (nworld s + w n
    + p) + k]`` and ``mm_out`` / ``m_out[nworld s + w n + p]`` (``p = r - s``, row by row from
    the top), so each camera's block is the host's ``(nworld, H, W, 3)`` / ``(nworld, H, W)``.

    Depth: the renderer's planar depth times ``ray_scale`` (1 for a pinhole camera: depth
    along the optical axis; ``1 / cos(theta)`` for a fisheye ray: its length, also beyond 90
    degrees where both are negative; 0 for a ray at 90 degrees); a missed ray, and a depth
    beyond ``ray_far`` (the pinhole far plane; a fisheye lens's ``far``), reads ``ray_miss``
    (the pinhole far plane, as OpenGL's cleared depth buffer; 0 for a fisheye), a negative
    depth reads 0, and pixels outside a fisheye's image circle (``ray_inside`` 0) are black
    with depth 0.
    """
    w, r = wp.tid()
    s = ray_start[r]
    n = ray_npix[r]
    o = nworld * s + w * n + (r - s)
    val = packed[w, r]
    z = depth[w, r]
    if ray_inside[r] == 0:
        rgb_out[3 * o + 0] = wp.uint8(0)
        rgb_out[3 * o + 1] = wp.uint8(0)
        rgb_out[3 * o + 2] = wp.uint8(0)
        z = 0.0
    else:
        rgb_out[3 * o + 0] = wp.uint8((val >> wp.uint32(16)) & wp.uint32(0xFF))
        rgb_out[3 * o + 1] = wp.uint8((val >> wp.uint32(8)) & wp.uint32(0xFF))
        rgb_out[3 * o + 2] = wp.uint8(val & wp.uint32(0xFF))
        if z == 0.0:  # the renderer's depth of a missed ray
            z = ray_miss[r]
        else:
            z = z * ray_scale[r]
            if z > ray_far[r]:
                z = ray_miss[r]
            elif z < 0.0:
                z = 0.0
    if depth_mm != 0:
        mm_out[o] = wp.uint16(wp.clamp(wp.round(z * 1000.0), 0.0, 65535.0))
    else:
        m_out[o] = z
