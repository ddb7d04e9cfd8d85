# mypy: ignore-errors
"""Warp kernels of the GPU demo executor (:mod:`factory.demos.execute_warp`).

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types.
Importing this module imports Warp (not cheap); only the executor imports it.
"""

import warp as wp


@wp.kernel
def set_ctrl(
    plan: wp.array3d(dtype=float),
    step: wp.array(dtype=int),
    ctrl: wp.array2d(dtype=float),
):
    """``ctrl[w] = plan[w, step]``: each world's control of the current physics step
    (``plan``: (nworld, T, nu); the last row is held past the end)."""
    w, u = wp.tid()
    t = wp.min(step[0], plan.shape[1] - 1)
    ctrl[w, u] = plan[w, t, u]


@wp.kernel
def tick(step: wp.array(dtype=int)):
    """Advances the physics step counter read by :func:`set_ctrl`."""
    step[0] = step[0] + 1


@wp.kernel
def to_images(
    packed: wp.array2d(dtype=wp.uint32),
    depth: wp.array2d(dtype=float),
    rgb_adr: wp.array(dtype=int),
    depth_adr: wp.array(dtype=int),
    npix: int,
    depth_mm: int,
    frame: wp.array(dtype=int),
    rgb_out: wp.array4d(dtype=wp.uint8),
    mm_out: wp.array4d(dtype=wp.uint16),
    m_out: wp.array4d(dtype=float),
):
    """The renderer's packed ARGB pixels and planar depth (m) of camera ``c`` of world ``w`` ->
    the image store: ``rgb_out[c, f, w, 3 p + k]`` (uint8 RGB), ``mm_out[c, f, w, p]`` (uint16
    mm, when ``depth_mm``) or ``m_out[c, f, w, p]`` (float32 m), for frame ``f = frame[0]``;
    ``p`` runs over the ``npix`` pixels row by row from the top. Camera-major, then
    frame-major: camera ``c``'s block is the host's ``(F, n, H, W, 3)``."""
    w, c, p = wp.tid()
    f = frame[0]
    val = packed[w, rgb_adr[c] + p]
    rgb_out[c, f, w, 3 * p + 0] = wp.uint8((val >> wp.uint32(16)) & wp.uint32(0xFF))
    rgb_out[c, f, w, 3 * p + 1] = wp.uint8((val >> wp.uint32(8)) & wp.uint32(0xFF))
    rgb_out[c, f, w, 3 * p + 2] = wp.uint8(val & wp.uint32(0xFF))
    z = depth[w, depth_adr[c] + p]
    if depth_mm != 0:
        mm_out[c, f, w, p] = wp.uint16(wp.clamp(wp.round(z * 1000.0), 0.0, 65535.0))
    else:
        m_out[c, f, w, p] = z
