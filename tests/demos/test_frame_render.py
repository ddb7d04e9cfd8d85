"""``factory.demos.record.frame_render.encode_depth``: depth as recorded, never a NaN cast."""

from __future__ import annotations

import warnings

import numpy as np

from factory.demos.record.frame_render import DEPTH_FAR_MM, encode_depth


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
