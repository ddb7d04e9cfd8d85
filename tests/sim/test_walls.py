"""Wall openings: the solid parts cover exactly the wall minus its openings."""

from __future__ import annotations

import pytest

from factory.schema import Door, Vec3, Wall, Window
from factory.sim.walls import solid_rects


def _area(rects) -> float:
    return sum((r.u1 - r.u0) * (r.z1 - r.z0) for r in rects)


def _wall() -> Wall:
    return Wall(id="w", start=Vec3(0, 0, 0), end=Vec3(5, 0, 0), height=2.5)


def test_plain_wall_is_one_box() -> None:
    rects = solid_rects(_wall(), [])
    assert len(rects) == 1 and _area(rects) == pytest.approx(12.5)


def test_door_and_window_are_cut_out() -> None:
    door = Door(id="d", wall_id="w", position_on_wall=0.2, width=0.9, height=2.1)
    window = Window(
        id="n", wall_id="w", position_on_wall=0.7, width=1.2, height=1.0, sill_height=0.9
    )
    rects = solid_rects(_wall(), [door, window])
    assert _area(rects) == pytest.approx(12.5 - 0.9 * 2.1 - 1.2 * 1.0)
    # no solid rectangle overlaps an opening's centre
    for u, z in [(1.0, 1.0), (3.5, 1.4)]:
        assert not any(r.u0 < u < r.u1 and r.z0 < z < r.z1 for r in rects)
    # pairwise disjoint
    for i, a in enumerate(rects):
        for b in rects[i + 1 :]:
            assert (
                min(a.u1, b.u1) <= max(a.u0, b.u0) + 1e-9
                or min(a.z1, b.z1) <= max(a.z0, b.z0) + 1e-9
            )


def test_opening_past_the_end_is_clipped() -> None:
    door = Door(id="d", wall_id="w", position_on_wall=1.0, width=1.0, height=3.0)
    rects = solid_rects(_wall(), [door])
    assert _area(rects) == pytest.approx(12.5 - 0.5 * 2.5)
