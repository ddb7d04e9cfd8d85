"""Oriented rectangles on the floor plane as arrays: the overlap test of thousands at once.

A rectangle is a row ``[x, y, hx, hy, yaw]``: centre (m, world frame), half sizes along its own
x and y axes (m) and turn about z (rad), the array form of
:class:`factory.scenes.footprint.Footprint` (whose one-pair test this repeats with the same
separating-axis rule and the same margin semantics, vectorised over broadcastable batches).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

_UNIT = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def rect_rows(
    x: ArrayLike, y: ArrayLike, hx: ArrayLike, hy: ArrayLike, yaw: ArrayLike
) -> np.ndarray:
    """Stacks broadcastable fields (centre and half sizes in m, yaw in rad) into ``(..., 5)``
    rectangle rows."""
    return np.stack(np.broadcast_arrays(x, y, hx, hy, yaw), axis=-1).astype(float)


def corners(r: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """``(..., 4, 2)`` world corners of rectangles ``(..., 5)`` grown by ``margin`` (m)."""
    c, s = np.cos(r[..., 4]), np.sin(r[..., 4])
    local = _UNIT * (r[..., None, 2:4] + margin)  # (..., 4, 2)
    x = local[..., 0] * c[..., None] - local[..., 1] * s[..., None] + r[..., None, 0]
    y = local[..., 0] * s[..., None] + local[..., 1] * c[..., None] + r[..., None, 1]
    return np.stack([x, y], axis=-1)


def _axes(r: np.ndarray) -> np.ndarray:
    """``(..., 2, 2)`` the two edge normals of each rectangle."""
    c, s = np.cos(r[..., 4]), np.sin(r[..., 4])
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], axis=-2)


def rects_overlap(a: np.ndarray, b: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Whether rectangles overlap in the plane, each grown by ``margin`` (m).

    Args:
        a: ``(..., 5)`` rectangles.
        b: ``(..., 5)`` rectangles, broadcastable against ``a``.
        margin: growth of both (touching after growth does not count as overlap).

    Returns:
        bool array of the broadcast batch shape.
    """
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    ca, cb = corners(a, margin), corners(b, margin)
    axes = np.concatenate([_axes(a), _axes(b)], axis=-2)  # (..., 4, 2)
    pa = np.einsum("...kd,...ad->...ak", ca, axes)  # (..., 4 axes, 4 corners)
    pb = np.einsum("...kd,...ad->...ak", cb, axes)
    separated = (pa.max(-1) <= pb.min(-1)) | (pb.max(-1) <= pa.min(-1))
    return ~separated.any(-1)


def spans_overlap(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Whether height spans ``[a0, a1]`` and ``[b0, b1]`` (m) overlap (touching does not)."""
    return ~((a1 <= b0) | (b1 <= a0))
