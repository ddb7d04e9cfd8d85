"""Corner views that nothing blocks (:mod:`factory.scenes.view_rays`): rays in the compiled
scene move a corner camera away from a tall object in front of it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from factory.schema import Vec3


def test_a_fridge_in_front_of_a_corner_moves_its_camera(tmp_path: Path) -> None:
    """A fridge 0.7 m in front of corner 0's eye blocks that view (rays hit it within 1 m);
    the camera render_views uses stands where nothing within 1 m blocks it and at least half
    of the room's objects are seen; the other corners stay where they were."""
    from factory.assets import AssetLibrary
    from factory.scenes.render import VIEWS, _room_eyes, _room_target, clear_view_cameras
    from factory.scenes.tools import ToolSession
    from factory.scenes.view_rays import check_eye
    from factory.sim.compile import compile_scene

    session = ToolSession(AssetLibrary(tmp_path / "assets"), physics=False)
    assert session.init_scene("a kitchen", seed=3)["ok"]
    assert session.place_objects("dining table", placement="floor", rule="center")["ok"]
    fridge = session.place_objects("refrigerator", placement="floor", rule="free")
    assert fridge["ok"], fridge
    scene = session.scene
    room, eye = _room_eyes(scene)["corner_0"]
    target = _room_target(room)
    toward = np.subtract(target[:2], eye[:2])
    toward /= np.linalg.norm(toward)
    obj = scene.object(fridge["placed"][0])
    obj.position = Vec3(*(np.array(eye[:2]) + 0.7 * toward), 0.0)
    model = compile_scene(scene, tmp_path / "assets").model
    before = check_eye(model, scene, room, eye, target, 70.0, 4 / 3)
    assert before.blocked
    cams, checks = clear_view_cameras(model, scene, VIEWS)
    assert set(checks) == {f"corner_{k}" for k in range(4)}
    assert not checks["corner_0"]["blocked"] and checks["corner_0"]["moved_m"] > 0
    assert checks["corner_0"]["seen"] >= checks["corner_0"]["objects"] / 2
    for k in (1, 2, 3):
        assert checks[f"corner_{k}"]["moved_m"] == 0.0, checks
    # the camera looks from its new eye at the room's middle
    cam = cams["corner_0"]
    assert math.isclose(cam.lookat[0], target[0]) and cam.elevation < 0
