"""The demos' frame renderer draws only what each camera sees (finite ground plane, frustum
culling): the same images up to the ground's per-vertex shading, appearance patches still
show, and the flat look of ``compile.lights=false`` / ``compile.textures=false``."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

from factory.schema import Scene


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory, make_kitchen):
    require_robot_models()
    pytest.importorskip("ompl")
    from factory.tasks.pick_place.plan import setup_scene

    assets = tmp_path_factory.mktemp("assets")
    scene: Scene = make_kitchen(assets)
    return setup_scene(scene, assets)


def test_culled_frames_match_and_show_patches(setup) -> None:
    from factory.demos.execute.cpu import FrameRenderer, RecordConfig

    cfg = RecordConfig(width=64, height=64)
    model = setup.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    culled, plain = FrameRenderer(model, cfg), FrameRenderer(model, cfg, cull=False)
    try:
        rgb_c, depth_c = culled.render(data)
        rgb_p, depth_p = plain.render(data)
        assert culled.culler is not None and culled.culler.hidden_total > 0
        for a, b, da, db in zip(rgb_c, rgb_p, depth_c, depth_p, strict=True):
            diff = np.abs(a.astype(int) - b.astype(int))
            # only the ground's shading differs (lit per vertex over larger quads)
            assert diff.mean() < 0.5 and np.mean(diff.max(-1) > 0) < 0.05
            assert np.abs(da.astype(int) - db.astype(int)).max() <= 1  # mm
        # the scene is made from the model itself: a colour written into it shows
        g = next(g for g in range(model.ngeom) if model.geom(g).name.endswith("/floor"))
        rgba, matid = model.geom_rgba[g].copy(), int(model.geom_matid[g])
        model.geom_rgba[g] = [1.0, 0.0, 0.0, 1.0]
        model.geom_matid[g] = -1
        red, _ = culled.render(data)
        model.geom_rgba[g], model.geom_matid[g] = rgba, matid
        assert any(not np.array_equal(r, c) for r, c in zip(red, rgb_c, strict=True))
    finally:
        culled.close()
        plain.close()


def test_flat_look_has_no_room_lights_or_textures(make_kitchen, tmp_path: Path) -> None:
    from factory.sim.compile import CompileOptions, compile_scene

    scene = make_kitchen(tmp_path)
    lit = compile_scene(scene, tmp_path).model
    flat = compile_scene(scene, tmp_path, CompileOptions(textures=False, lights=False)).model
    assert lit.nlight > 1 and flat.nlight == 1  # the sun only
    assert flat.ntex < lit.ntex
    assert flat.vis.headlight.diffuse[0] > lit.vis.headlight.diffuse[0]
