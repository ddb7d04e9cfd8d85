"""Appearance randomisation on the GPU executor (``WarpExecutor.execute(..., looks=...)``):
the patch tables, the kernel that gives a starting episode its look, and agreement with the CPU
executor's images and cameras' calibration of the same looks (padded and packed worlds).

Fast in CI: the tables and the kernel on Warp's CPU device. The end-to-end comparison runs on
Warp's CPU device (``slow``: 20-35 s, mostly ray tracing on two shared cores) and on CUDA (``gpu``).
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest
from robot_models import require_robot_models
from warp_modules import without_sleep

if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()
pytest.importorskip("ompl")

from factory.config import AppearanceConfig
from factory.demos.execute.cpu import RecordConfig
from factory.demos.record.appearance import (
    PATCH_FIELDS,
    PATCH_GROUPS,
    episode_looks,
    patch_tables,
    setup_index,
)
from factory.tasks.pick_place.plan import EpisodePlan, EpisodePlanner, setup_scene

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

CAMERAS = ("left", "right", "wrist")

STRONG = AppearanceConfig(color_jitter=0.5, texture_swap=1.0, light_intensity=0.6, light_color=0.3)
"""Looks stronger than the default ones, so that every test episode's look changes its images'
colours by clearly more than :data:`EFFECT_TOLERANCE`."""

RGB_TOLERANCE = 40.0
"""Largest mean absolute RGB difference (0-255) between the CPU executor's and the GPU
executor's images of a camera with the same looks: the renderers' own difference
(tests/demos/test_execute_warp.py). Measured with looks at 64 px on Warp's CPU device: 5-18 on
the left and right cameras, up to 37 on the wrist camera (7-28 without looks)."""

EFFECT_TOLERANCE = 6.0
"""Largest difference (0-255, per channel) between the two renderers of a look's effect on an
image's mean colour (the episode's mean RGB with its look minus without) on the ``left`` and
``right`` cameras. A mean pixel difference alone cannot tell a look applied from one ignored:
the renderers differ by more (see :data:`RGB_TOLERANCE`) than a look changes. Measured at 64 px
on Warp's CPU device: at most 4.0 while the effects are 15-85 (the wrist camera, close to the
lights, differs by up to 10 and is left out)."""


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory, make_kitchen):
    assets = tmp_path_factory.mktemp("assets")
    return setup_scene(make_kitchen(assets), assets)


def test_patch_tables_hold_each_episodes_patch(setup) -> None:
    """The tables keep only the geoms, lights and cameras some look changes (not the robot's,
    not the task objects'), and rebuild every episode's patch."""
    model = setup.model
    index = setup_index(setup, CAMERAS)
    looks = episode_looks(model, index, AppearanceConfig(), [1, 2, 3, 4])
    tables = patch_tables(model, [p for _, p in looks])
    geoms = set(tables.ids["geoms"].tolist())
    assert geoms and len(geoms) < model.ngeom
    assert not geoms & set(np.asarray(setup.robot.geoms).tolist())
    task = [setup.objects.pick.id, setup.objects.target.id, setup.objects.support.id]
    task_geoms = np.flatnonzero(np.isin(model.geom_bodyid, [model.body(t).id for t in task]))
    assert not geoms & set(task_geoms.tolist())
    assert len(tables.ids["cameras"]) == len(CAMERAS)
    assert tables.width == max(len(v) for v in tables.ids.values())
    for e, (_, patch) in enumerate(looks):
        for group, names in PATCH_GROUPS.items():
            ids = tables.ids[group]
            for f in names:
                rows = tables.rows[f]
                assert rows.shape[:2] == (len(looks), len(ids))
                rebuilt = np.array(getattr(model, f))
                rebuilt[ids] = rows[e]
                np.testing.assert_allclose(rebuilt, getattr(patch, f), rtol=1e-6, atol=1e-7)
    assert sorted(f for names in PATCH_GROUPS.values() for f in names) == sorted(PATCH_FIELDS)


def test_set_looks_gives_starting_worlds_their_episodes_rows() -> None:
    """The kernel writes row ``e`` of the tables into the worlds marked to start episode ``e``
    at this boundary, and leaves the other worlds and elements alone."""
    import warp as wp

    from factory.demos.execute.warp_kernels import set_looks

    wp.config.quiet = True  # type: ignore[attr-defined]
    n, per_frame = 3, 4
    episode = np.array([[0, 1, 2], [0, 3, -1]], np.int32)  # boundary 1: world 1 starts ep 3
    reset = np.array([True, True, True])  # world 0 keeps its episode; world 2 has none
    rows = {
        "geom_rgba": np.arange(4 * 2 * 4, dtype=np.float32).reshape(4, 2, 4),
        "geom_matid": np.arange(8, dtype=np.int32).reshape(4, 2),
        "light_pos": np.arange(4 * 3, dtype=np.float32).reshape(4, 1, 3),
        "light_diffuse": np.repeat(np.arange(4, dtype=np.float32), 3).reshape(4, 1, 3),
        "light_specular": np.ones((4, 1, 3), np.float32) * 2,
        "light_active": np.array([[True], [True], [True], [False]]),
        "cam_pos": np.zeros((4, 0, 3), np.float32),
        "cam_quat": np.zeros((4, 0, 4), np.float32),
    }
    ids = {"geoms": [4, 1], "lights": [0], "cameras": []}
    sizes = {"geoms": 5, "lights": 2, "cameras": 1}
    with wp.ScopedDevice("cpu"):
        fields = {}
        for group, names in PATCH_GROUPS.items():
            for f in names:
                shape = (n, sizes[group], *rows[f].shape[2:])
                fields[f] = np.full(shape, -1, rows[f].dtype)
        types = {"geom_matid": int, "light_active": bool, "geom_rgba": wp.vec4, "cam_quat": wp.quat}
        dev = {f: wp.array(v, dtype=types.get(f, wp.vec3)) for f, v in fields.items()}
        inputs = []
        for group, names in PATCH_GROUPS.items():
            inputs.append(wp.array(np.asarray(ids[group], np.int32), dtype=int))
            inputs += [wp.array(rows[f], dtype=types.get(f, wp.vec3)) for f in names]
        step = wp.array(np.array([per_frame + 1], np.int32), dtype=int)  # boundary 1
        head = [wp.array(reset, dtype=bool), wp.array(episode, dtype=int), step, per_frame]
        outs = [dev[f] for f in PATCH_FIELDS]
        wp.launch(set_looks, dim=(n, 2), inputs=[*head, *inputs, *outs])
        got = {f: a.numpy() for f, a in dev.items()}
    for f, before in fields.items():
        group = next(g for g, names in PATCH_GROUPS.items() if f in names)
        want = before.copy()
        want[1, ids[group]] = rows[f][3]  # world 1: episode 3's row
        want[0, ids[group]] = rows[f][0]  # world 0 is marked: its own episode's row again
        np.testing.assert_array_equal(got[f], want, err_msg=f)


def _mean_colour(images: np.ndarray) -> np.ndarray:
    return images.reshape(-1, 3).astype(np.float64).mean(axis=0)


@pytest.mark.parametrize(
    "device",
    [
        pytest.param("cpu", marks=pytest.mark.slow),
        pytest.param("cuda:0", marks=pytest.mark.gpu),
    ],
)
def test_gpu_looks_match_cpu_looks(setup, device: str) -> None:
    """Three episodes with their looks on two worlds (two start together with different looks;
    the third starts with its own in the world the shortest frees, through the reset inside the
    call) draw what the CPU executor draws with the same looks; the physics is untouched and the
    episodes record the same appearance metadata."""
    from factory.demos.execute.cpu import execute
    from factory.demos.execute.warp import WarpExecutor
    from factory.errors import AppearanceError

    if device == "cpu":
        setup = without_sleep(setup)
    planner = EpisodePlanner(setup)
    plans = [p for p in (planner.plan_episode(s) for s in range(8)) if isinstance(p, EpisodePlan)]
    assert len(plans) >= 3
    # Short episodes (0.1-0.2 s, 3-5 frames) of different lengths.
    plans = [
        dataclasses.replace(p, ctrl=p.ctrl[:k], targets=p.targets[:k])
        for p, k in zip(plans[:3], (100, 50, 75), strict=True)
    ]
    cfg = RecordConfig(width=64, height=64, cameras=CAMERAS)
    looks = episode_looks(setup.model, setup_index(setup, CAMERAS), STRONG, [11, 12, 13])
    cpu_plain = execute(setup, plans, cfg, nthread=1)
    cpu = execute(setup, plans, cfg, nthread=1, looks=looks)
    ex = WarpExecutor(setup, cfg, device=device)
    with pytest.raises(AppearanceError, match="one look per plan"):
        ex.execute(plans, looks=looks[:2])
    gpu_plain = ex.execute(plans)
    gpu = ex.execute(plans, worlds=2, looks=looks)  # episode 1 follows episode 2 in world 1
    effects = []
    for i in range(3):
        assert gpu[i].appearance == cpu[i].appearance == looks[i][0]
        assert gpu_plain[i].appearance is None
        # the cameras' calibration: the same numbers from the model and the episode's patch
        assert gpu[i].camera_poses == cpu[i].camera_poses != cpu_plain[i].camera_poses
        assert gpu[i].camera_fovy == cpu[i].camera_fovy
        assert sorted(gpu[i].camera_poses) == ["left", "right"]
        assert gpu_plain[i].camera_poses == cpu_plain[i].camera_poses
        atol = 1e-5 if device == "cpu" else 3e-3
        np.testing.assert_allclose(gpu[i].state, gpu_plain[i].state, atol=atol)
        for cam in CAMERAS:
            diff = np.abs(gpu[i].rgb[cam].astype(float) - cpu[i].rgb[cam].astype(float)).mean()
            assert diff < RGB_TOLERANCE, (i, cam, diff)
        for cam in ("left", "right"):
            on_cpu = _mean_colour(cpu[i].rgb[cam]) - _mean_colour(cpu_plain[i].rgb[cam])
            on_gpu = _mean_colour(gpu[i].rgb[cam]) - _mean_colour(gpu_plain[i].rgb[cam])
            assert np.abs(on_gpu - on_cpu).max() < EFFECT_TOLERANCE, (i, cam, on_cpu, on_gpu)
            effects.append(on_cpu)
    # The looks change the images clearly more than the tolerance (a look ignored, or the
    # first episode's look kept for the one that follows it in world 1, would fail above).
    per_episode = np.array(effects).reshape(3, 2, 3)
    assert np.abs(per_episode).max(axis=(1, 2)).min() > 2 * EFFECT_TOLERANCE, per_episode
    assert np.abs(per_episode[1] - per_episode[2]).max() > 2 * EFFECT_TOLERANCE, per_episode
