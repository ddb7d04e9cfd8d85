"""Wall openings: the solid parts cover exactly the wall minus its openings; shared walls: each
room's wall pieces keep to its own side."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from factory.scenes.floorplan import init_scene
from factory.schema import Door, Scene, Vec3, Wall, Window
from factory.sim.compile import CompileOptions, compile_scene
from factory.sim.walls import PlanRect, solid_rects, subtract


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


def test_subtract_leaves_disjoint_rest() -> None:
    rect = PlanRect(0.0, 0.0, 4.0, 1.0)
    assert subtract(rect, [PlanRect(5, 5, 6, 6)]) == [rect]
    parts = subtract(rect, [PlanRect(1.0, -1.0, 2.0, 0.5), PlanRect(3.0, 0.0, 5.0, 1.0)])
    area = sum((p.x1 - p.x0) * (p.y1 - p.y0) for p in parts)
    assert area == pytest.approx(4.0 - 0.5 - 1.0)
    for i, a in enumerate(parts):
        assert not any(a.overlaps(b) for b in parts[i + 1 :])
    assert subtract(rect, [rect.grown(0.1)]) == []


def _wall_boxes(scene: Scene) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(room id, lower corner, upper corner) of every wall piece of the compiled scene (world
    frame, m; the pieces are boxes turned by multiples of 90 degrees)."""
    model = compile_scene(scene, None, CompileOptions(textures=False)).model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    out = []
    for g in range(model.ngeom):
        parts = model.geom(g).name.split("/")
        if len(parts) == 3 and parts[2].isdigit():
            half = np.abs(data.geom_xmat[g].reshape(3, 3)) @ model.geom_size[g]
            out.append((parts[0], data.geom_xpos[g] - half, data.geom_xpos[g] + half))
    return out


def _inside(p: np.ndarray, boxes: list[tuple[str, np.ndarray, np.ndarray]]) -> list[str]:
    return [room for room, lo, hi in boxes if (p > lo + 1e-9).all() and (p < hi - 1e-9).all()]


@pytest.mark.parametrize("request_text", ["a two-room apartment", "a family home"])
def test_rooms_walls_do_not_overlap(request_text: str) -> None:
    """Where rooms meet, each room's wall keeps to its own side: no two wall pieces of
    different rooms share a volume (z-fighting), every wall stays solid on both sides above
    the doors, and the doors between rooms stay open."""
    scene, _ = init_scene(request_text, seed=0)
    assert len(scene.rooms) >= 2
    boxes = _wall_boxes(scene)
    for i, (ra, lo_a, hi_a) in enumerate(boxes):
        for rb, lo_b, hi_b in boxes[i + 1 :]:
            if ra != rb:
                overlap = np.minimum(hi_a, hi_b) - np.maximum(lo_a, lo_b)
                assert not (overlap > 1e-6).all(), f"walls of {ra} and {rb} overlap"
    shared = 0
    for room in scene.rooms:
        for w in room.walls:
            s, e = np.array([w.start.x, w.start.y]), np.array([w.end.x, w.end.y])
            u = (e - s) / w.length
            n = np.array([-u[1], u[0]])
            q = w.thickness / 4
            for t in np.linspace(-w.thickness / 2 + 0.01, w.length + w.thickness / 2 - 0.01, 40):
                for off in (-q, q):  # above the doors and windows (2.1 m)
                    p = np.array([*(s + u * t + n * off), w.height - 0.1])
                    assert _inside(p, boxes), f"a hole in the walls at {p}"
            for d in (d for d in room.doors if d.wall_id == w.id):
                owners = set()
                for off in (-q, q):
                    p = np.array([*(s + u * d.position_on_wall * w.length + n * off), 1.0])
                    assert not _inside(p, boxes), f"door {d.id} is walled up"
                    p[2] = w.height - 0.1
                    owners.update(_inside(p, boxes))
                shared += len(owners) == 2
    assert shared >= 2  # the door between two rooms, seen from both: a wall half each side
