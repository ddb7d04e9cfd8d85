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
