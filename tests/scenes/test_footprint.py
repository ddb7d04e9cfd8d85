"""Footprint overlap (separating axes): touching is no overlap, turned boxes, heights, margins,
clearance along a wall at every quarter turn."""

from __future__ import annotations

import math

import numpy as np
import pytest

from factory.scenes.footprint import Footprint, inside, overlaps


def _one(a: Footprint, b: Footprint, margin: float = 0.0) -> bool:
    return overlaps(a, b, margin) and overlaps(b, a, margin)  # symmetric


def test_touching_and_separate_boxes_do_not_overlap() -> None:
    a = Footprint(0.0, 0.0, 0.5, 0.5)
    assert _one(a, Footprint(0.9, 0.0, 0.5, 0.5))  # 0.1 m deep
    assert not _one(a, Footprint(1.0, 0.0, 0.5, 0.5))  # edge to edge
    assert not _one(a, Footprint(1.0, 1.0, 0.5, 0.5))  # corner to corner
    assert not _one(a, Footprint(2.0, 0.0, 0.5, 0.5))


def test_turned_box_next_to_a_corner() -> None:
    a = Footprint(0.0, 0.0, 0.5, 0.5)
    # a diamond whose bounding box overlaps the square's corner but whose sides do not
    d = 0.5 * math.sqrt(2)
    assert not _one(a, Footprint(1.0, 1.0, 0.5, 0.5, math.pi / 4))
    assert _one(a, Footprint(0.5 + d - 0.05, 0.0, 0.5, 0.5, math.pi / 4))


def test_heights_and_margins() -> None:
    sofa = Footprint(0.0, 0.0, 1.0, 0.45, 0.0, 0.0, 0.9)
    assert not _one(sofa, Footprint(0.0, 0.3, 0.4, 0.05, 0.0, 1.2, 1.8))  # painting above
    assert not _one(sofa, Footprint(0.0, 0.0, 0.4, 0.3, 0.0, 0.9, 1.2))  # stacked, touching
    table = Footprint(1.53, 0.0, 0.5, 0.45, 0.0, 0.0, 0.75)  # 3 cm gap
    assert not _one(sofa, table, 0.01) and _one(sofa, table, 0.02)  # both grow by margin


def test_corners_and_inside() -> None:
    fp = Footprint(1.0, 2.0, 0.3, 0.2, 0.7)
    c, s = math.cos(0.7), math.sin(0.7)
    assert np.allclose(fp.corners()[2], [1.0 + 0.3 * c - 0.2 * s, 2.0 + 0.3 * s + 0.2 * c])
    assert inside(fp, (0.0, 0.0, 2.0, 3.0)) and not inside(fp, (0.0, 0.0, 1.2, 3.0))


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, math.pi, -math.pi / 2])
def test_wall_side_by_side_is_free(yaw: float) -> None:
    """Two cabinets 4 cm apart along a wall, any quarter turn: free with the 2 cm clearance."""
    c, s = math.cos(yaw), math.sin(yaw)
    a = Footprint(1.0, 1.0, 0.3, 0.3, yaw)
    b = Footprint(1.0 + 0.64 * c, 1.0 + 0.64 * s, 0.3, 0.3, yaw)
    assert not _one(a, b, 0.02 - 1e-9) and _one(a, b, 0.02 + 1e-3)
