"""Scenes sharing a layout are checked in one batch with the verdicts of one call each."""

from __future__ import annotations

import copy

import numpy as np

from factory.schema import Physics, Placement, Room, Scene, SceneObject, Size3, Vec3
from factory.sim.backend_cpu import CpuBackend
from factory.sim.compile import compile_scene
from factory.sim.layout_batch import check_by_layout, layout_key
from factory.sim.stability import StabilityProtocol, check_stability


def _scene(sid: str, mug_xy: tuple[float, float], mug_z: float = 0.75) -> Scene:
    room = Room(id="lab", room_type="lab", position=Vec3(0, 0, 0), dimensions=Size3(3, 3, 2.5))
    table = SceneObject(
        id="table",
        room_id="lab",
        category="table",
        position=Vec3(1.5, 1.5, 0),
        dimensions=Size3(1.0, 0.7, 0.75),
        physics=Physics(mass=25.0),
    )
    mug = SceneObject(
        id="mug",
        room_id="lab",
        category="mug",
        position=Vec3(mug_xy[0], mug_xy[1], mug_z),
        dimensions=Size3(0.08, 0.08, 0.1),
        physics=Physics(mass=0.3),
        placement=Placement(kind="on_top", support_id="table"),
    )
    return Scene(id=sid, rooms=[room], objects=[table, mug], source="example")


def test_layout_key_ignores_free_poses_only() -> None:
    a = compile_scene(_scene("a", (1.4, 1.5))).model
    b = compile_scene(_scene("b", (1.7, 1.3))).model
    assert layout_key(a) == layout_key(b)
    other = _scene("c", (1.4, 1.5))
    other.objects[1].dimensions = Size3(0.09, 0.08, 0.1)
    assert layout_key(compile_scene(other).model) != layout_key(a)
    bigger = copy.deepcopy(_scene("d", (1.4, 1.5)))
    bigger.objects[0].physics = Physics(mass=30.0)
    assert layout_key(compile_scene(bigger).model) != layout_key(a)


def test_batched_verdicts_equal_one_call_per_scene() -> None:
    scenes = {
        "on": _scene("on", (1.4, 1.5)),
        "edge": _scene("edge", (1.99, 1.5)),  # half over the edge: falls
        "off": _scene("off", (2.3, 1.5)),  # in the air beside the table: falls
        "wide": _scene("wide", (1.6, 1.6)),
    }
    scenes["wide"].objects[1].dimensions = Size3(0.12, 0.12, 0.1)  # another layout
    models = {sid: compile_scene(sc).model for sid, sc in scenes.items()}
    protocol = StabilityProtocol()
    batched = check_by_layout(models, CpuBackend(nthread=1), protocol)
    verdicts = []
    for sid, model in models.items():
        alone = check_stability(model, backend=CpuBackend(nthread=1), protocol=protocol)
        got = batched[sid]
        assert got.stable.shape == (1,)
        assert bool(got.stable[0]) == bool(alone.stable[0])
        assert bool(got.accepted[0]) == bool(alone.accepted[0])
        np.testing.assert_allclose(got.translation, alone.translation, atol=1e-9)
        np.testing.assert_allclose(got.settled_qpos, alone.settled_qpos, atol=1e-9)
        verdicts.append(bool(alone.stable[0]))
    assert any(verdicts) and not all(verdicts)
