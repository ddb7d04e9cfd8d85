"""The GPU renderer of recorded states (MuJoCo Warp) with each task's own cameras, and the
pipeline of the tasks that simulate their episodes themselves: the mobile task (five cameras,
two of them fisheyes) and the articulated tasks (the fixed-base Panda's three).

CI runs everything on Warp's CPU device (the same kernels, slowly); each renderer test has a
``gpu``-marked twin on CUDA. The pipeline through the CLI picks CUDA where it exists, so the
same test covers both machines.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()
pytest.importorskip("ompl")
pytest.importorskip("mujoco_warp")

from factory.sim.fisheye import FisheyeSpec
from factory.tasks.mobile_pick_place import (
    ALL_CAMERAS,
    FISHEYE_CAMERAS,
    MobileEpisodePlan,
    MobilePlanner,
    MobileRecordConfig,
    MobileRecording,
    camera_rig,
    execute_mobile,
    mobile_setup,
    render_frames,
)

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

HERE = Path(__file__).resolve().parent
DEVICES = ["cpu", pytest.param("cuda:0", marks=pytest.mark.gpu)]

RGB_TOLERANCE = {"left": 12.0, "right": 12.0, "wrist": 30.0, "fisheye_front": 15.0}
"""Largest mean absolute RGB difference (0-255) between OpenGL (:class:`MobileRenderer`) and
MuJoCo Warp's ray tracer per camera, 64 px, eight frames of the hand-built living room's
episode (fisheye_back: as fisheye_front). Measured on Warp's CPU device: left 3.1, right 2.9,
wrist 16.9, fisheye_front 3.7, fisheye_back 10.2. The shading differs (light falloff,
specular highlights); the wrist camera sits inside the bounding spheres of the hand's visual
meshes, and OpenGL draws a ring of robot mesh there that the ray tracer (and ``mj_ray``) does
not hit (apparently inner faces)."""

DEPTH_TOLERANCE_MM = {"pinhole": 3.0, "fisheye": 12.0}
"""Largest median absolute depth difference (mm) per camera kind. Measured: 0 mm for the
pinhole cameras (both depth along the optical axis), 1-3 mm for the fisheyes (10 mm over the
pixels where both see something: the cube map reads depth from the nearest face pixel, the ray
tracer along each pixel's own ray)."""


def _helpers() -> ModuleType:
    """The living room of the demos' mobile tests (test folders are not packages)."""
    spec = importlib.util.spec_from_file_location(
        "_mobile_helpers", HERE / "test_mobile_pick_place.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _frames(states: np.ndarray) -> MobileRecording:
    """A recording holding only states (what the renderers read)."""
    z = np.zeros((len(states), 1))
    return MobileRecording(
        time=np.arange(len(states), dtype=float),
        state=states,
        base_pose=z,
        joint_pos=z,
        gripper=z,
        ee_pose=z,
        action=z,
        subtask=z[:, 0].astype(np.int8),
        subtask_done=z[:, 0].astype(bool),
    )


@pytest.fixture(scope="module")
def episode() -> dict[str, Any]:
    """The hand-built living room and episode 0 simulated at 5 fps without images; eight of
    its frames (spawn, driving, picking, carrying, placing)."""
    setup = mobile_setup(_helpers()._living_room())
    plan = MobilePlanner(setup).plan_episode(0)
    assert isinstance(plan, MobileEpisodePlan), plan
    rec = execute_mobile(setup, plan, MobileRecordConfig(fps=5.0, render=False))
    assert rec.outcome is not None and rec.outcome.success and not rec.rgb
    return {"setup": setup, "states": rec.state[:: max(1, len(rec.state) // 8)][:8]}


@pytest.mark.parametrize("device", DEVICES)
def test_warp_renderer_agrees_with_opengl(episode: dict[str, Any], device: str) -> None:
    """The same recorded frames drawn by OpenGL (the CPU path) and by MuJoCo Warp: the same
    arrays (keys, shapes, dtypes, depth conventions, black outside the fisheye circle) with
    images alike within the stated tolerances; the frames of two recordings filling calls of
    3 worlds (one episode split over two calls, the last call padded) are drawn as one
    ``render`` of all their states draws them."""
    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer

    setup, states = episode["setup"], episode["states"]
    cfg = MobileRecordConfig(fps=5.0, width=64, height=64)
    cpu = _frames(states)
    render_frames(setup, cpu, cfg)
    renderer = WarpRecordingRenderer(setup.model, camera_rig(cfg), device=device, max_worlds=3)
    assert renderer.worlds == 3
    first, second = _frames(states[:5]), _frames(states[5:])
    renderer.render_recordings([first, second])
    assert renderer.times.calls == 3 and renderer.times.frames == len(states)
    assert first.render_seconds > 0 and second.render_seconds > 0
    rgb, depth = renderer.render(states)
    mask = FisheyeSpec(resolution=64, fov_deg=cfg.fisheye_fov_deg).mask
    measured = {}
    for c in ALL_CAMERAS:
        for a, b in ((cpu.rgb, rgb), (cpu.depth, depth)):
            assert a[c].shape == b[c].shape and a[c].dtype == b[c].dtype, c
        both = np.concatenate([first.rgb[c], second.rgb[c]])
        np.testing.assert_array_equal(both, rgb[c])
        np.testing.assert_array_equal(np.concatenate([first.depth[c], second.depth[c]]), depth[c])
        diff = float(np.abs(cpu.rgb[c].astype(float) - rgb[c]).mean())
        ddiff = float(np.median(np.abs(cpu.depth[c].astype(float) - depth[c])))
        measured[c] = (round(diff, 1), ddiff)
        fish = c in FISHEYE_CAMERAS
        assert diff < RGB_TOLERANCE.get(c, RGB_TOLERANCE["fisheye_front"]), measured
        assert ddiff <= DEPTH_TOLERANCE_MM["fisheye" if fish else "pinhole"], measured
        assert rgb[c].std() > 10 and depth[c].max() > 1000  # a room, in mm
        if fish:
            assert not rgb[c][:, ~mask].any() and not depth[c][:, ~mask].any()
            assert (depth[c][:, mask] > 0).mean() > 0.5
        else:
            assert (depth[c] > 0).all()
    # float32 metres: the same depths
    metres = MobileRecordConfig(fps=5.0, width=64, height=64, depth="float32")
    _, depth_m = WarpRecordingRenderer(setup.model, camera_rig(metres), device=device).render(
        states[:2]
    )
    for c in ALL_CAMERAS:
        assert depth_m[c].dtype == np.float32
        np.testing.assert_allclose(depth_m[c] * 1000.0, depth[c][:2], atol=0.51)


# ------------------------------------------------------------------ the fisheye lens on Warp

RADIUS = 0.08  # m, marker spheres
LEVEL = np.column_stack([(0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0)])
"""Camera -> world of a camera looking along world +x, +z up (x_cam = -y, y_cam = +z)."""
EYE = np.array([0.0, 0.0, 1.5])
MARKERS = [(40.0, 0.0, 1.0), (80.0, 90.0, 1.5), (10.0, 225.0, 0.8), (120.0, 20.0, 1.0)]
"""(theta deg, phi deg, distance m): 40 deg to the right, 80 deg up, 10 deg lower left, and
one behind the camera (120 deg), outside a 180-degree lens."""


def _direction(theta: float, phi: float) -> np.ndarray:
    """Unit vector at ``theta`` from the optical axis (-z), azimuth ``phi`` from +x toward +y
    (camera frame)."""
    return np.array(
        [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), -math.cos(theta)]
    )


def _marker_model() -> Any:
    import mujoco

    spheres = "".join(
        f'<geom type="sphere" size="{RADIUS}" pos="{p[0]:.6f} {p[1]:.6f} {p[2]:.6f}" '
        'material="marker" contype="0" conaffinity="0"/>'
        for p in (
            EYE + d * (LEVEL @ _direction(math.radians(t), math.radians(f))) for t, f, d in MARKERS
        )
    )
    xml = f"""
    <mujoco>
      <asset><material name="marker" rgba="1 0 0 1" emission="1"/></asset>
      <worldbody>
        <light pos="0 0 4" dir="0 0 -1"/>
        <geom name="floor" type="plane" size="5 5 0.1" rgba="0.3 0.3 0.3 1"/>
        <camera name="{FISHEYE_CAMERAS["fisheye_front"]}" pos="0 0 1.5" xyaxes="0 -1 0 0 0 1"/>
        {spheres}
      </worldbody>
    </mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize("device", DEVICES)
def test_fisheye_markers_land_on_their_predicted_pixels_on_warp(device: str) -> None:
    """A fisheye is one ray-traced camera with the equidistant lens's rays: markers at known
    angles appear at the pixels the lens predicts, at their distance (ray length), the one
    behind the camera does not (it does through a 260-degree lens), and the floor's depth is
    each pixel's ray length."""
    import mujoco

    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer

    model = _marker_model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.cam_xmat[0].reshape(3, 3), LEVEL, atol=1e-9)
    state = _state(model, data)[None]
    cfg = MobileRecordConfig(width=128, height=96, cameras=("fisheye_front",), depth="float32")
    rgb, depth = WarpRecordingRenderer(model, camera_rig(cfg), device=device).render(state)
    im, dp = rgb["fisheye_front"][0], depth["fisheye_front"][0]
    assert im.shape == (128, 128, 3) and dp.shape == (128, 128)  # fisheyes are square
    spec = FisheyeSpec(resolution=128, fov_deg=180.0)
    assert not im[~spec.mask].any() and not dp[~spec.mask].any()
    r, g, b = (im[..., k].astype(int) for k in range(3))
    red = (r > 120) & (g < 70) & (b < 70)
    vv, uu = np.mgrid[:128, :128]
    seen = np.zeros_like(red)
    for theta, phi, dist in MARKERS[:3]:
        uv = spec.project(_direction(math.radians(theta), math.radians(phi)))
        near = red & (np.hypot(uu - uv[0], vv - uv[1]) < 8.0)
        assert near.sum() >= 5, f"marker at {theta} deg not found near {uv}"
        centroid = np.array([uu[near].mean(), vv[near].mean()])
        assert np.hypot(*(centroid - uv)) < 1.5, (theta, centroid, uv)
        iu, iv = np.rint(uv).astype(int)
        assert dp[iv, iu] == pytest.approx(dist - RADIUS, abs=0.01), theta
        seen |= np.hypot(uu - uv[0], vv - uv[1]) < 8.0
    assert not (red & ~seen).any()  # the marker at 120 degrees is behind a 180-degree lens
    world = spec.rays @ LEVEL.T
    down = -world[..., 2]
    floor = spec.mask & (down > math.cos(math.radians(60))) & ~seen
    expected = EYE[2] / np.where(floor, down, 1.0)
    assert floor.sum() > 1000
    assert np.abs(dp[floor] - expected[floor]).max() < 0.002  # every pixel's own ray
    # a 260-degree lens sees the marker 120 degrees off the axis, at its distance
    wide = MobileRecordConfig(
        width=128, cameras=("fisheye_front",), depth="float32", fisheye_fov_deg=260.0
    )
    rgb, depth = WarpRecordingRenderer(model, camera_rig(wide), device=device).render(state)
    im, dp = rgb["fisheye_front"][0], depth["fisheye_front"][0]
    theta, phi, dist = MARKERS[3]
    uv = FisheyeSpec(resolution=128, fov_deg=260.0).project(
        _direction(math.radians(theta), math.radians(phi))
    )
    r, g, b = (im[..., k].astype(int) for k in range(3))
    near = (r > 120) & (g < 70) & (b < 70) & (np.hypot(uu - uv[0], vv - uv[1]) < 6.0)
    assert near.sum() >= 5
    assert np.hypot(uu[near].mean() - uv[0], vv[near].mean() - uv[1]) < 1.5
    iu, iv = np.rint(uv).astype(int)
    assert dp[iv, iu] == pytest.approx(dist - RADIUS, abs=0.01)


def _state(model: Any, data: Any) -> np.ndarray:
    import mujoco

    from factory.tasks.mobile_pick_place import STATE_SPEC

    out = np.zeros(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, out, STATE_SPEC)
    return out


# ------------------------------------------------------------------ the stage


def test_mobile_stage_cli_with_the_warp_executor(cli, tmp_path: Path) -> None:
    """``stage=demos task=mobile_pick_place demos.executor=warp`` on a generated living room:
    planned and simulated in a worker process, rendered by MuJoCo Warp (CUDA where present,
    else Warp's CPU device), stored as the CPU path stores it."""
    from factory.assets import AssetLibrary
    from factory.demos.record.episodes import EpisodeStore
    from factory.scenes.brain import AgentConfig, generate_scene
    from factory.schema import scene_to_json

    run = tmp_path / "run"
    scene, _ = generate_scene(
        "a living room where the robot moves the coke can from the coffee table to the desk",
        AssetLibrary(run / "assets"),
        seed=0,
        config=AgentConfig(physics_critic=False),
    )
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    out = cli(
        "stage=demos",
        f"run_dir={run}",
        "task=mobile_pick_place",
        "demos.executor=warp",
        "demos.episodes_per_scene=1",
        "demos.width=64",
        "demos.height=64",
        "demos.fps=5",
        "demos.workers=1",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["executor"] == "warp" and summary["new_successes"] == 1, summary
    assert summary["seconds"]["gpu"]["frames"] > 50 and summary["seconds"]["render"] > 0
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    info = store.info(eid)
    assert info.task == "mobile_pick_place" and info.success and info.recorder == "warp"
    assert info.cameras == list(ALL_CAMERAS) and info.depth_format == "uint16_mm"
    g = store.arrays(eid)
    n = info.n_frames
    assert g["action"].shape == (n, 11) and g["base_pose"].shape == (n, 3)
    assert int(g["subtask_done"][:].sum()) == 4
    for cam in ALL_CAMERAS:
        assert g[f"rgb/{cam}"].shape == (n, 64, 64, 3)
        assert g[f"depth/{cam}"].shape == (n, 64, 64) and g[f"depth/{cam}"].dtype == np.uint16
        assert np.asarray(g[f"rgb/{cam}"][n // 2]).std() > 5


# ------------------------------------------------------------------ the articulated tasks' rig

ARTICULATED_RGB_TOLERANCE = {"left": 12.0, "right": 12.0, "wrist": 15.0}
"""Largest mean absolute RGB difference (0-255) per camera between the CPU executor's recording
of a ``task=open`` episode (OpenGL, :class:`~factory.tasks.articulated.record.
ArticulatedRenderer`) and MuJoCo Warp's drawing of its states, 64 px, eight frames of the
bundled one-cabinet kitchen's episode: the mobile task's pinhole tolerances
(:data:`RGB_TOLERANCE`). Measured on Warp's CPU device over all 43 frames of the episode (seed
0): left 8.3, right 6.0, wrist 17.6 (29.0 on its worst frame, the hand close to the handle);
depth: median difference 0 mm on every frame. ``task=place_inside``'s bundled episode (161
frames, the same rig): left 7.2, right 6.7, wrist 19.7 (42.4 on its worst frame), depth 0 mm,
and the same 668 far-plane pixels in both. Those wrist figures were OpenGL's near plane (1 % of
the scene's extent) hiding the hand, which MuJoCo Warp draws; with both at 1 cm
(:data:`~factory.demos.record.frame_render.NEAR_CLIP_M`), on the test's eight frames: left 8.4,
right 5.9, wrist 3.8 (9.8 on its worst frame)."""


def _copy_example(task: str, run: Path) -> str:
    """Copies task ``task``'s bundled example scene into ``run``; returns its id."""
    from factory.tasks import get_task

    src = get_task(task).example_scene_path()
    assert src is not None
    sid = json.loads(src.read_text())["id"]
    (run / "scenes" / sid).mkdir(parents=True)
    (run / "scenes" / sid / "scene.json").write_text(src.read_text())
    return str(sid)


@pytest.fixture(scope="module")
def open_episode(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The bundled one-cabinet kitchen set up for ``task=open`` as ``stage=demos`` sets it up,
    and one episode recorded by the CPU executor (images by OpenGL, 64 px, 5 fps); eight of
    its frames (reaching, pulling, letting go)."""
    from factory.config import DemosConfig
    from factory.demos.record.slots import StageEnv
    from factory.tasks import get_task

    run = tmp_path_factory.mktemp("open")
    sid = _copy_example("open", run)
    dc = DemosConfig(width=64, height=64, fps=5.0)
    env = StageEnv(str(run), str(run / "episodes" / "shard-0.zarr"), dc, "open", 0, 1)
    scene = get_task("open").demo_scene(env, sid)
    cfg = scene.record_config()
    renderer = scene.renderer(cfg)
    try:
        for seed in range(5):
            plan = scene.plan(seed)
            if isinstance(plan, scene.plan_type):
                rec = scene.simulate(plan, cfg, renderer)
                if rec.outcome.success:
                    break
        else:
            pytest.fail("no successful open episode in 5 seeds")
    finally:
        renderer.close()
    idx = np.linspace(0, len(rec.state) - 1, 8).round().astype(int)
    return {"run": run, "sid": sid, "env": env, "scene": scene, "cfg": cfg, "rec": rec, "idx": idx}


def _articulated_frames(states: np.ndarray) -> Any:
    """An articulated recording holding only states (what the renderers read)."""
    from factory.tasks.articulated.record import Recording

    z = np.zeros((len(states), 1))
    return Recording(
        time=np.arange(len(states), dtype=float),
        state=states,
        joint_pos=z,
        gripper=z,
        ee_pose=z,
        action=z,
        env_state=z,
    )


@pytest.mark.parametrize("device", DEVICES)
def test_warp_renderer_agrees_with_the_articulated_cpu_recording(
    open_episode: dict[str, Any], device: str
) -> None:
    """A ``task=open`` episode recorded by the CPU executor, and its recorded states drawn by
    MuJoCo Warp with the scene's own camera rig (the fixed-base Panda's left, right and wrist
    cameras, not the mobile robot's): the same cameras, shapes, dtypes and depth conventions,
    images alike within the mobile task's tolerances, depth equal to the millimetre, no NaN;
    two recordings filling calls of 3 worlds are drawn as one ``render`` of their states."""
    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer
    from factory.robots.panda import CAMERAS

    scene, cfg, rec, idx = (open_episode[k] for k in ("scene", "cfg", "rec", "idx"))
    rig = scene.camera_rig(cfg)
    assert rig.keys == cfg.cameras == ("left", "right", "wrist") and rig.depth == "uint16_mm"
    assert [c.camera for c in rig.cameras] == [CAMERAS[c] for c in cfg.cameras]
    assert all(c.fisheye is None and (c.width, c.height) == (64, 64) for c in rig.cameras)
    states = rec.state[idx]
    renderer = WarpRecordingRenderer(scene.setup.model, rig, device=device, max_worlds=3)
    first, second = _articulated_frames(states[:5]), _articulated_frames(states[5:])
    renderer.render_recordings([first, second])
    assert renderer.times.calls == 3 and renderer.times.frames == len(states)
    rgb, depth = renderer.render(states)
    measured = {}
    for c in cfg.cameras:
        cpu_rgb, cpu_depth = rec.rgb[c][idx], rec.depth[c][idx]
        assert rgb[c].shape == cpu_rgb.shape == (8, 64, 64, 3) and rgb[c].dtype == np.uint8
        assert depth[c].shape == cpu_depth.shape and depth[c].dtype == cpu_depth.dtype
        np.testing.assert_array_equal(np.concatenate([first.rgb[c], second.rgb[c]]), rgb[c])
        np.testing.assert_array_equal(np.concatenate([first.depth[c], second.depth[c]]), depth[c])
        diff = float(np.abs(cpu_rgb.astype(float) - rgb[c]).mean())
        ddiff = float(np.median(np.abs(cpu_depth.astype(float) - depth[c])))
        measured[c] = (round(diff, 1), ddiff)
        assert rgb[c].std() > 10 and (depth[c] > 0).all()
    for c in cfg.cameras:
        assert measured[c][0] < ARTICULATED_RGB_TOLERANCE[c], measured
        assert measured[c][1] <= DEPTH_TOLERANCE_MM["pinhole"], measured
    # float32 metres: the same depths, finite
    metres = scene.camera_rig(replace(cfg, depth="float32"))
    _, depth_m = WarpRecordingRenderer(scene.setup.model, metres, device=device).render(states[:2])
    for c in cfg.cameras:
        assert depth_m[c].dtype == np.float32 and np.isfinite(depth_m[c]).all()
        np.testing.assert_allclose(depth_m[c] * 1000.0, depth[c][:2], atol=0.51)


def _sky_model() -> Any:
    """An endless floor, a box and a camera looking level at the horizon (0.5 m up): its upper
    half sees nothing, the floor's rows next to the horizon lie beyond the far plane (20 m:
    ``zfar`` 10 x ``extent`` 2; the first row under the horizon sees the floor 30 m away)."""
    import mujoco

    return mujoco.MjModel.from_xml_string(
        """
    <mujoco>
      <statistic extent="2"/>
      <visual><map zfar="10"/></visual>
      <worldbody>
        <light pos="0 0 4" dir="0 0 -1"/>
        <geom name="floor" type="plane" size="0 0 0.1" rgba="0.4 0.4 0.4 1"/>
        <geom type="box" size="0.3 0.3 0.3" pos="2 0.5 0.3" rgba="0.8 0.2 0.2 1"/>
        <camera name="level" pos="0 0 0.5" xyaxes="0 -1 0 0 0 1" fovy="60"/>
      </worldbody>
    </mujoco>"""
    )


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("fmt", ["uint16_mm", "float32"])
def test_a_pinhole_ray_that_hits_nothing_reads_the_cpu_far_value(device: str, fmt: str) -> None:
    """Where a pinhole camera sees nothing (the sky above the horizon) or sees beyond the far
    plane (the floor near the horizon), the Warp renderer's depth is the CPU renderer's far
    value (OpenGL's far plane, ``vis.map.zfar`` x ``stat.extent``, as ``CameraStrip`` encodes
    it), never NaN; the box's and the near floor's depths agree."""
    import mujoco

    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer
    from factory.demos.record.frame_render import CameraStrip, size_offscreen
    from factory.demos.record.rig import CameraRig, RigCamera

    model = _sky_model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    size_offscreen(model, 48, 32)
    strip = CameraStrip(model, [0], 48, 32, fmt)
    try:
        (cpu_rgb,), (cpu_depth,) = strip.render(data)
    finally:
        strip.close()
    rig = CameraRig((RigCamera("left", "level", 48, 32),), fmt)
    rgb, depth = WarpRecordingRenderer(model, rig, device=device).render(_state(model, data)[None])
    im, dp = rgb["left"][0], depth["left"][0].astype(float)
    assert im.shape == cpu_rgb.shape == (32, 48, 3) and dp.shape == cpu_depth.shape
    far_m = float(model.vis.map.zfar * model.stat.extent)
    far = min(65535.0, round(far_m * 1000.0)) if fmt == "uint16_mm" else far_m
    cpu = cpu_depth.astype(float)
    assert np.isfinite(dp).all() and np.isfinite(cpu).all()
    assert far_m == pytest.approx(20.0)
    sky = np.isclose(cpu, far, rtol=1e-4)
    metres = cpu / (1000.0 if fmt == "uint16_mm" else 1.0)
    box = metres < 3.0  # the box, 1.7-2.3 m ahead; the floor under it (rows 17 on)
    box[17:] = False
    assert box.sum() > 20
    # beside the box: the rows above the horizon and the first floor row below it (30 m); the
    # near floor not
    assert (sky | box)[:17].all() and not sky[-8:].any()
    np.testing.assert_allclose(dp[sky], far, rtol=1e-4)
    near = ~sky
    scale = 1000.0 if fmt == "float32" else 1.0  # mm
    assert np.median(np.abs(dp[near] - cpu[near])) * scale <= DEPTH_TOLERANCE_MM["pinhole"]
    assert np.median(np.abs(dp[box] - cpu[box])) * scale <= DEPTH_TOLERANCE_MM["pinhole"]


def test_open_stage_cli_with_the_warp_executor(cli, tmp_path: Path) -> None:
    """``stage=demos task=open demos.executor=warp demos.episode_physics=cpu`` on the bundled
    one-cabinet kitchen: planned and simulated in a worker process, the main process setting
    the scene up without its planner and drawing the recorded states on MuJoCo Warp (CUDA
    where present, else Warp's CPU device) with the fixed-base Panda's cameras; stored as the
    CPU path stores it (the task's arrays, the scene cameras' calibration), the recorder
    ``warp``."""
    from factory.demos.record.episodes import EpisodeStore
    from factory.tasks.articulated.record import ArticulatedRenderer

    run = tmp_path / "run"
    sid = _copy_example("open", run)
    out = cli(
        "stage=demos",
        f"run_dir={run}",
        "task=open",
        "demos.executor=warp",
        "demos.episodes_per_scene=1",
        "demos.width=32",
        "demos.height=32",
        "demos.fps=5",
        "demos.workers=1",
        "demos.episode_physics=cpu",  # the GPU's physics: tests/demos/test_episode_gpu_physics.py
        env={"OMP_NUM_THREADS": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["executor"] == "warp" and summary["new_successes"] == 1, summary
    assert summary["seconds"]["gpu"]["frames"] > 10 and summary["seconds"]["render"] > 0
    assert len(summary["scenes"][sid]["robot_base"]) == 3
    # the writer read the images from the main process's shared memory (not pickled)
    log_text = (run / "logs" / "demos-0-of-1.log").read_text()
    assert "episode images handed to the writers in shared memory: 1" in log_text
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    info = store.info(eid)
    assert info.task == "open" and info.success and info.recorder == "warp"
    assert (info.pick_id, info.target_id) == ("base_cabinet_0", "drawer")
    assert info.cameras == ["left", "right", "wrist"] and info.depth_format == "uint16_mm"
    assert set(info.camera_poses) == {"left", "right"} and set(info.camera_fovy) == {
        "left",
        "right",
    }
    g = store.arrays(eid)
    n = info.n_frames
    assert g["action"].shape == (n, 8) and g["env_state"].shape == (n, 11)
    for cam in info.cameras:
        assert g[f"rgb/{cam}"].shape == (n, 32, 32, 3)
        assert g[f"depth/{cam}"].shape == (n, 32, 32) and g[f"depth/{cam}"].dtype == np.uint16
        assert np.asarray(g[f"rgb/{cam}"][n // 2]).std() > 5
        assert (np.asarray(g[f"depth/{cam}"][:]) > 0).all()
    # the stored images are those of the stored states, camera by camera: drawn again by the
    # CPU renderer from the stored states, they agree within the agreement test's tolerances
    import mujoco

    from factory.config import DemosConfig
    from factory.demos.record.payload import STATE_SPEC
    from factory.tasks.articulated.demos import record_config, scene_setup

    dc = DemosConfig(width=32, height=32, fps=5.0)
    setup = scene_setup(run, sid, dc, "open")
    cfg = record_config(dc)
    renderer = ArticulatedRenderer(setup.model, cfg)
    data = mujoco.MjData(setup.model)
    states = np.asarray(g["state"][:])
    diffs: dict[str, list[float]] = {c: [] for c in cfg.cameras}
    try:
        for f in range(0, n, max(1, n // 8)):
            mujoco.mj_setState(setup.model, data, states[f], STATE_SPEC)
            mujoco.mj_forward(setup.model, data)
            rgbs, depths = renderer.render(data)
            for c, im, dp in zip(cfg.cameras, rgbs, depths):
                diffs[c].append(float(np.abs(im.astype(float) - g[f"rgb/{c}"][f]).mean()))
                stored = np.asarray(g[f"depth/{c}"][f], float)
                assert np.median(np.abs(dp - stored)) <= DEPTH_TOLERANCE_MM["pinhole"], (c, f)
    finally:
        renderer.close()
    for c, d in diffs.items():
        assert np.mean(d) < ARTICULATED_RGB_TOLERANCE[c], {k: np.mean(v) for k, v in diffs.items()}


def test_a_bad_camera_rig_names_the_fix() -> None:
    """A rig of unknown depth format, a camera twice, a fisheye that is not square, or a camera
    the model lacks is refused with a :class:`ConfigError` saying what to give instead."""
    from factory.demos.execute.recording_render_warp import WarpRecordingRenderer
    from factory.demos.record.rig import CameraRig, RigCamera
    from factory.errors import ConfigError

    left = RigCamera("left", "level", 48, 32)
    with pytest.raises(ConfigError, match="choose one of uint16_mm, float32"):
        CameraRig((left,), "png")
    with pytest.raises(ConfigError, match="names a camera twice"):
        CameraRig((left, left))
    with pytest.raises(ConfigError, match="a fisheye image is square"):
        RigCamera("fisheye_front", "level", 48, 32, FisheyeSpec(resolution=48))
    with pytest.raises(ConfigError, match="at least 1 px"):
        RigCamera("left", "level", 0, 32)
    model = _sky_model()
    with pytest.raises(ConfigError, match=r"no camera\(s\) \['camera_left'\]"):
        WarpRecordingRenderer(model, CameraRig((RigCamera("left", "camera_left", 8, 8),)))
    with pytest.raises(ConfigError, match=r"demos\.render=false"):
        WarpRecordingRenderer(model, CameraRig(()))
