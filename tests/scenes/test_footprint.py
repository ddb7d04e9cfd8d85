"""Footprint overlap (one against many, numpy): touching is no overlap, turned boxes, heights,
margins, and agreement with the pairwise separating-axis test on random footprints."""

from __future__ import annotations

import math

import numpy as np
import pytest

from factory.scenes.footprint import Footprint, inside, outlines, overlapping


def _sat(a: Footprint, b: Footprint, margin: float) -> bool:
    """Reference: separating axes of two oriented rectangles, one pair at a time (the test before
    issue 13)."""
    if a.z1 <= b.z0 or b.z1 <= a.z0:
        return False
    grow = [Footprint(f.x, f.y, f.hx + margin, f.hy + margin, f.yaw) for f in (a, b)]
    ca, cb = (f.corners() for f in grow)
    for f in (a, b):
        c, s = math.cos(f.yaw), math.sin(f.yaw)
        for axis in ((c, s), (-s, c)):
            pa, pb = ca @ axis, cb @ axis
            if pa.max() <= pb.min() or pb.max() <= pa.min():
                return False
    return True


def _one(a: Footprint, b: Footprint, margin: float = 0.0) -> bool:
    return bool(overlapping(a, [b], margin)[0])


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


def test_many_at_once_and_none() -> None:
    a = Footprint(0.0, 0.0, 0.5, 0.5)
    others = [Footprint(x, 0.0, 0.2, 0.2) for x in (0.0, 0.6, 2.0)]
    assert overlapping(a, others).tolist() == [True, True, False]
    assert overlapping(a, []).shape == (0,)


def test_outlines_are_the_corners() -> None:
    fp = Footprint(1.0, 2.0, 0.3, 0.2, 0.7)
    xy = outlines([fp])[0]
    assert np.allclose(xy, fp.corners(), atol=1e-12)
    assert inside(fp, (0.0, 0.0, 2.0, 3.0)) and not inside(fp, (0.0, 0.0, 1.2, 3.0))


def test_agrees_with_separating_axes_on_random_footprints() -> None:
    rng = np.random.default_rng(0)

    def draw() -> Footprint:
        yaw = float(rng.choice([0.0, math.pi / 2, math.pi, rng.uniform(-math.pi, math.pi)]))
        hx, hy = rng.uniform(0.05, 1.0, 2)
        z0 = float(rng.choice([0.0, rng.uniform(0.0, 1.5)]))
        return Footprint(*rng.uniform(0, 3, 2), hx, hy, yaw, z0, z0 + rng.uniform(0.05, 1.5))

    answers = []
    for _ in range(300):
        fp, others = draw(), [draw() for _ in range(6)]
        margin = float(rng.choice([0.0, 0.005, 0.02]))
        expect = [_sat(fp, o, margin) for o in others]
        assert overlapping(fp, others, margin).tolist() == expect
        answers += expect
    assert 0.1 < np.mean(answers) < 0.9  # both answers well represented


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, math.pi, -math.pi / 2])
def test_wall_side_by_side_is_free(yaw: float) -> None:
    """Two cabinets 4 cm apart along a wall, any quarter turn: free with the 2 cm clearance."""
    c, s = math.cos(yaw), math.sin(yaw)
    a = Footprint(1.0, 1.0, 0.3, 0.3, yaw)
    b = Footprint(1.0 + 0.64 * c, 1.0 + 0.64 * s, 0.3, 0.3, yaw)
    assert not _one(a, b, 0.02 - 1e-9) and _one(a, b, 0.02 + 1e-3)
