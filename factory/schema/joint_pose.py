"""Where a joint moves its link: the rigid transform of a hinge or slide at a position.

Used by the asset builder (swept boxes, poses of links) and by the MJCF compiler (link bodies
placed at their scene's joint states), which sits below the asset package.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

__all__ = ["Posed", "link_transform"]


class Posed(Protocol):
    """A joint's kind (``hinge`` or ``slide``), anchor (m) and unit axis, in one frame."""

    @property
    def kind(self) -> str: ...
    @property
    def anchor(self) -> Sequence[float]: ...
    @property
    def axis(self) -> Sequence[float]: ...


def link_transform(joint: Posed, value: float) -> np.ndarray:
    """The (4, 4) transform (the joint's frame, e.g. the object frame) that moves a link from
    its closed pose by its own joint at ``value`` (rad about the axis through the anchor, or m
    along the axis)."""
    axis = np.asarray(joint.axis, dtype=float)
    tf = np.eye(4)
    if joint.kind == "slide":
        tf[:3, 3] = axis * value
        return tf
    x, y, z = axis
    c, s = math.cos(value), math.sin(value)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    rot = np.eye(3) + s * k + (1 - c) * (k @ k)
    anchor = np.asarray(joint.anchor, dtype=float)
    tf[:3, :3] = rot
    tf[:3, 3] = anchor - rot @ anchor
    return tf
