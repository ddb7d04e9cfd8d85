"""Room lighting (ceiling and lamp lights, shadows) and the appearance randomisation of
recorded episodes (``demos.appearance``): determinism, bounds, the task objects untouched,
application to the recording and its record in the episode metadata."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

from factory.config import AppearanceConfig
from factory.schema import Scene
from factory.sim.compile import compile_scene
from factory.sim.lights import MAX_CEILING, ceiling_grid


@pytest.fixture(scope="module")
def kitchen(tmp_path_factory: pytest.TempPathFactory, make_kitchen) -> tuple[Scene, Path]:
    assets = tmp_path_factory.mktemp("assets")
    return make_kitchen(assets), assets


def test_ceiling_grid_follows_room_size() -> None:
    assert ceiling_grid(2.5, 3.0) == (1, 1)
    assert ceiling_grid(4.2, 4.2) == (1, 1)
    assert ceiling_grid(6.0, 3.0) == (2, 1)
    assert ceiling_grid(6.5, 6.5) == (2, 2)
    nx, ny = ceiling_grid(14.0, 9.0)
    assert nx * ny <= MAX_CEILING and nx >= ny


def test_rooms_have_ceiling_lights_with_shadows_and_lamps_light(kitchen) -> None:
    scene, assets = kitchen
    lamp = next((o for o in scene.objects if o.category in ("floor_lamp", "table_lamp")), None)
    if lamp is None:  # give the kitchen a lamp: a plain box of lamp size (no asset)
        obj = scene.objects[0]
        lamp = replace(obj, id="floor_lamp_t", category="floor_lamp", asset=None, task_role=None)
        scene = replace(scene, objects=[*scene.objects, lamp])
    model = compile_scene(scene, assets).model
    names = [model.light(i).name for i in range(model.nlight)]
    for room in scene.rooms:
        ceiling = [i for i, n in enumerate(names) if n.startswith(f"{room.id}/ceiling_")]
        nx, ny = ceiling_grid(room.dimensions.width, room.dimensions.length)
        assert len(ceiling) == nx * ny
        for i in ceiling:
            assert model.light_castshadow[i]
            assert model.light_type[i] == mujoco.mjtLightType.mjLIGHT_SPOT
            z = model.light_pos[i][2]
            assert room.ceiling_height - 0.2 < z - room.position.z < room.ceiling_height
            assert room.contains_xy(*model.light_pos[i][:2])
    i = names.index(f"{lamp.id}/lamp")
    assert model.light_bodyid[i] == model.body(lamp.id).id and not model.light_castshadow[i]
    # the OpenGL renderer draws eight lights with the headlight: a one-room scene fits
    assert model.nlight <= 7
    assert max(model.vis.headlight.diffuse) < 0.3  # the rooms' lights do the lighting


def test_renders_are_neither_dark_nor_washed_out(kitchen) -> None:
    from factory.scenes.render import render_views

    scene, assets = kitchen
    model = compile_scene(scene, assets).model
    images = render_views(model, scene, views=("corner_0", "corner_2"), width=160, height=120)
    for view, im in images.items():
        grey = im.mean(axis=-1)
        p5, p50, p99 = np.percentile(grey, [5, 50, 99])
        assert 50 < p50 < 200, (view, p50)
        assert p5 > 10 and p99 < 255, (view, p5, p99)
        assert (im.max(axis=-1) >= 254).mean() < 0.05, view  # little clipped white


# ---- appearance randomisation (needs the robot)


@pytest.fixture(scope="module")
def setup(kitchen):
    require_robot_models()
    pytest.importorskip("ompl")
    from factory.tasks.pick_place.plan import setup_scene

    scene, assets = kitchen
    return setup_scene(scene, assets)


@pytest.fixture(scope="module")
def index(setup):
    from factory.demos.record.appearance import setup_index

    return setup_index(setup, ("left", "right", "wrist"))


def test_choice_is_seeded(index) -> None:
    from factory.demos.record.appearance import choose

    cfg = AppearanceConfig()
    a, b, c = choose(index, cfg, 7), choose(index, cfg, 7), choose(index, cfg, 8)
    assert a == b and a != c
    assert a.objects and a.lights and len(a.cameras) == 3
    swaps = [look.material_from for s in range(20) for look in choose(index, cfg, s).objects]
    assert any(swaps) and set(swaps) <= set(index.donors) | {""}
    off = choose(index, replace(cfg, enabled=False), 7)
    assert not (off.objects or off.lights or off.cameras)
    # one kind switched off leaves the others' draws as they were
    no_cam = choose(index, replace(cfg, camera=False), 7)
    assert no_cam.objects == a.objects and no_cam.lights == a.lights and not no_cam.cameras


def test_bounds_and_task_objects_untouched(setup, index) -> None:
    from factory.demos.record.appearance import choose, model_patch

    model = setup.model
    cfg = AppearanceConfig()
    task = {setup.objects.pick.id, setup.objects.target.id, setup.objects.support.id}
    fixed = np.isin(model.geom_bodyid, [model.body(t).id for t in task])
    fixed[setup.robot.geoms] = True
    for seed in range(20):
        app = choose(index, cfg, seed)
        assert not {look.id for look in app.objects} & task
        p = model_patch(model, index, app)
        assert np.array_equal(p.geom_rgba[fixed], model.geom_rgba[fixed])
        assert np.array_equal(p.geom_matid[fixed], model.geom_matid[fixed])
        for cam in app.cameras:
            i = index.cameras[cam.name]
            shift = p.cam_pos[i] - model.cam_pos[i]
            assert np.abs(shift).max() <= cfg.camera_pos + 1e-9
            dot = abs(float(np.dot(p.cam_quat[i], model.cam_quat[i])))
            angle = np.degrees(2 * np.arccos(min(1.0, dot)))
            assert angle <= cfg.camera_angle + 1e-6
        for light in app.lights:
            assert 1 - cfg.light_intensity <= light.intensity <= 1 + cfg.light_intensity
            assert np.abs(light.offset).max() <= cfg.light_pos
        for look in app.objects:
            assert np.all(np.abs(np.asarray(look.tint) - 1) <= 0.21)


def test_scene_cameras_take_the_wider_jitter(setup, index) -> None:
    """``scene_camera_*`` widens the jitter of the cameras placed in the scene (their pose is
    recorded) and leaves the wrist camera's (computed from the joints) as it was."""
    from factory.demos.record.appearance import choose, model_patch

    assert index.scene_cameras == ("left", "right")
    model = setup.model
    base = AppearanceConfig()
    wide = replace(base, scene_camera_pos=0.05, scene_camera_angle=10.0)
    widest = {"left": 0.0, "right": 0.0}
    for seed in range(20):
        a, b = choose(index, base, seed), choose(index, wide, seed)
        assert a.objects == b.objects and a.lights == b.lights
        p = model_patch(model, index, b)
        for cam in b.cameras:
            i = index.cameras[cam.name]
            shift = float(np.abs(p.cam_pos[i] - model.cam_pos[i]).max())
            dot = abs(float(np.dot(p.cam_quat[i], model.cam_quat[i])))
            angle = float(np.degrees(2 * np.arccos(min(1.0, dot))))
            if cam.name == "wrist":
                assert cam == next(c for c in a.cameras if c.name == "wrist")
            else:
                assert shift <= 0.05 + 1e-9 and angle <= 10.0 + 1e-6
                widest[cam.name] = max(widest[cam.name], angle)
    assert min(widest.values()) > base.camera_angle  # wider than the default range


def test_recording_applies_appearance_and_restores_model(setup, tmp_path: Path) -> None:
    from factory.config import DemosConfig
    from factory.demos.execute.cpu import STATE_SPEC, FrameRenderer, RecordConfig, execute
    from factory.demos.record.appearance import (
        apply_patch,
        episode_looks,
        place_cameras_and_lights,
        setup_index,
    )
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.slots import StageEnv, episode_seed
    from factory.tasks.pick_place.demos import PickPlaceScene
    from factory.tasks.pick_place.plan import EpisodePlan, EpisodePlanner

    planner = EpisodePlanner(setup)
    plan = next(
        p for p in (planner.plan_episode(s) for s in range(6)) if isinstance(p, EpisodePlan)
    )
    cfg = RecordConfig(width=48, height=48)
    model = setup.model
    before = {f: np.array(getattr(model, f)) for f in ("geom_rgba", "cam_pos", "light_pos")}
    idx = setup_index(setup, cfg.cameras)
    looks = episode_looks(model, idx, AppearanceConfig(), [11, 12])
    recs = execute(setup, [plan, plan], cfg, nthread=1, looks=looks)
    for f, v in before.items():
        assert np.array_equal(getattr(model, f), v), f"{f} not restored"
    plain = execute(setup, [plan], cfg, nthread=1)[0]
    assert recs[0].outcome is not None and recs[0].outcome.success
    assert np.array_equal(recs[0].state, plain.state)  # physics untouched
    assert not np.array_equal(recs[0].rgb["left"], recs[1].rgb["left"])
    assert not np.array_equal(recs[0].rgb["left"], plain.rgb["left"])
    # the recorded appearance, applied to the model, reproduces the images exactly
    renderer = FrameRenderer(model, cfg)
    data = mujoco.MjData(model)
    frame = len(recs[1].time) // 2
    try:
        apply_patch(model, looks[1][1])
        mujoco.mj_setState(model, data, recs[1].state[frame], STATE_SPEC)
        mujoco.mj_forward(model, data)
        place_cameras_and_lights(model, data)
        rgbs, _ = renderer.render(data)
        # the recorded calibration is the pose the moved cameras were drawn from (base frame)
        p = setup.placement
        c, s = np.cos(p.yaw), np.sin(p.yaw)
        base = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        for cam in ("left", "right"):
            i = model.camera(f"camera_{cam}").id
            pos = base.T @ (data.cam_xpos[i] - p.pos())
            rot = base.T @ data.cam_xmat[i].reshape(3, 3)
            want = np.concatenate([pos, rot.ravel()])
            np.testing.assert_allclose(recs[1].camera_poses[cam], want, atol=1e-9)
            assert recs[1].camera_fovy[cam] == float(model.cam_fovy[i])
    finally:
        for f, v in before.items():
            np.copyto(getattr(model, f), v)
        renderer.close()
    assert np.array_equal(rgbs[0], recs[1].rgb["left"][frame])
    assert sorted(plain.camera_poses) == ["left", "right"]  # the wrist camera's: kinematics
    for cam in ("left", "right"):  # each episode's look moves its cameras
        assert recs[0].camera_poses[cam] != recs[1].camera_poses[cam] != plain.camera_poses[cam]
    # stored and read back with the episode
    env = StageEnv(str(tmp_path), str(tmp_path / "s.zarr"), DemosConfig(), "pick_place", 0, 1)
    seed = episode_seed(0, setup.scene.id, 0, 0)
    meta, arrays = PickPlaceScene(env, setup, None).payload(0, seed, plan, recs[1], cfg)
    store = EpisodeStore(tmp_path / "s.zarr")
    store.write(meta, arrays)
    info = store.info(meta.episode_id)
    assert info.appearance == looks[1][0] and info.schema_version == 4
    assert info.camera_poses == recs[1].camera_poses and info.camera_fovy["left"] > 0


def test_older_metadata_still_reads() -> None:
    """Versions 1-3 read as version 4 without what they lacked (``appearance``, ``recorder``,
    the cameras' calibration); a malformed calibration is refused."""
    from factory.schema.episode import EpisodeInfo, RobotBase, episode_info_from_dict
    from factory.schema.errors import SchemaError
    from factory.schema.scene import to_dict

    info = EpisodeInfo(
        episode_id="s-ep000",
        scene_id="s",
        task="pick_place",
        instruction="put the mug in the bowl",
        seed=1,
        success=True,
        failure_reason="",
        pick_id="mug_0",
        target_id="bowl_0",
        support_id="table_0",
        robot=RobotBase(0.0, 0.0, 0.0, 0.0),
        fps=20.0,
        timestep=0.002,
        n_frames=10,
        cameras=["left"],
        image_size=[32, 32],
        depth_format="uint16_mm",
        state_spec=1,
    )
    old = to_dict(info)
    del old["appearance"], old["recorder"]
    del old["camera_poses"], old["camera_fovy"]
    old["schema_version"] = 1
    assert episode_info_from_dict(old).appearance is None
    v2 = to_dict(info)
    del v2["recorder"], v2["camera_poses"], v2["camera_fovy"]
    v2["schema_version"] = 2
    assert episode_info_from_dict(v2).recorder == ""
    v3 = to_dict(info)  # before the cameras' calibration: read without it
    del v3["camera_poses"], v3["camera_fovy"]
    v3["schema_version"] = 3
    got = episode_info_from_dict(v3)
    assert got.camera_poses == {} and got.camera_fovy == {} and got.schema_version == 4
    v4 = to_dict(replace(info, camera_poses={"left": [0.0] * 11}, camera_fovy={"left": 50.0}))
    with pytest.raises(SchemaError, match="12 values"):
        episode_info_from_dict(v4)
