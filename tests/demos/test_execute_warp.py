"""The GPU demo executor (MuJoCo Warp): state layout and config on the CPU; agreement with the
CPU executor on the GPU machine (``gpu`` marker).

CPU twins in CI: the CPU executor's own tests (tests/demos/test_demos.py) cover the recording,
success check and replay that both executors share
(:func:`factory.demos.execute.cpu.finish_recordings`), and the GPU pipeline itself runs on Warp's
CPU device (``test_gpu_pipeline_on_warp_cpu``: planning processes, length-sorted calls, the
executor, writer processes; sleeping off, since MuJoCo Warp's sleeping solver path does not
run on the CPU device).
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models
from warp_modules import modules_compiled_after_preload, without_sleep

if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()
pytest.importorskip("ompl")

from factory.config import DemosConfig
from factory.demos.execute.cpu import STATE_SPEC, RecordConfig
from factory.demos.stage import check_config, resolve_executor
from factory.errors import ConfigError
from factory.tasks.pick_place.plan import EpisodePlan, EpisodePlanner, setup_scene

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory, make_kitchen):
    assets = tmp_path_factory.mktemp("assets")
    return setup_scene(make_kitchen(assets), assets)


def test_state_layout_matches_mj_getState(setup) -> None:
    from factory.demos.execute.warp import state_layout

    model = setup.model
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    data.qpos[:] = rng.normal(size=model.nq)
    data.qvel[:] = rng.normal(size=model.nv)
    data.ctrl[:] = rng.normal(size=model.nu)
    data.qacc_warmstart[:] = rng.normal(size=model.nv)
    data.time = 1.25
    state = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, state, STATE_SPEC)
    lay = state_layout(model)
    assert state[lay["time"]][0] == 1.25
    for name in ("qpos", "qvel", "ctrl", "qacc_warmstart"):
        assert np.array_equal(state[lay[name]], getattr(data, name)), name


def test_executor_config() -> None:
    check_config(DemosConfig(executor="cpu"), "pick_place")
    assert resolve_executor("cpu") == "cpu"
    assert resolve_executor("auto") in ("cpu", "warp")
    with pytest.raises(ConfigError, match=r"demos\.executor='gpu' is unknown"):
        check_config(DemosConfig(executor="gpu"), "pick_place")
    with pytest.raises(ConfigError, match="gpu_batch"):
        check_config(DemosConfig(gpu_batch=0), "pick_place")
    with pytest.raises(ConfigError, match="gpu_retries='later' is unknown"):
        check_config(DemosConfig(gpu_retries="later"), "pick_place")
    with pytest.raises(ConfigError, match=r"gpu_tail=0\.5 is out of range"):
        check_config(DemosConfig(gpu_tail=0.5), "pick_place")
    with pytest.raises(ConfigError, match="lookalike_radius must be >= 0"):
        check_config(DemosConfig(lookalike_radius=-1.0), "pick_place")


def test_the_longest_plans_go_to_the_cpu_in_parallel_items() -> None:
    """``split_tail`` leaves a scene's longest plans (rounded down share, ties by slot) to the
    CPU; ``spread`` deals slots over at most ``workers`` items."""
    from types import SimpleNamespace

    from factory.demos.execute.gpu_calls import split_tail
    from factory.demos.gpu_pipeline import spread

    lengths = [50, 400, 90, 400, 120, 70, 300, 60, 80, 100]
    planned = [(k, 100 + k, SimpleNamespace(ctrl=np.zeros((t, 2)))) for k, t in enumerate(lengths)]
    gpu, cpu = split_tail(planned, 0.25)
    assert [k for k, _, _ in cpu] == [1, 3]  # 2 of 10: the two 400-step plans
    assert [k for k, _, _ in gpu] == [0, 2, 4, 5, 6, 7, 8, 9]
    assert split_tail(planned, 0.09) == (planned, [])
    assert split_tail(planned, 0.0) == (planned, [])
    assert spread([4, 5, 6, 7, 8], 2) == [[4, 6, 8], [5, 7]]
    assert spread([4, 5], 15) == [[4], [5]]
    assert spread([], 3) == []


def test_cpu_retries_continue_from_the_gpu_attempts(make_kitchen, tmp_path: Path) -> None:
    """The GPU path hands its execution failures to the CPU executor (``run_item`` with
    ``first_attempts``): a slot starts at its next seed, a slot out of attempts is not tried,
    and the episode says which executor recorded it."""
    from factory.demos.cpu_items import run_item
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.slots import StageEnv, WorkItem, episode_id, episode_seed
    from factory.schema import scene_to_json

    run = tmp_path / "run"
    scene = make_kitchen(run / "assets")
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    dc = DemosConfig(width=16, height=16, attempts=3, cameras=["wrist"])
    store_path = run / "episodes" / "shard-0.zarr"
    env = StageEnv(str(run), str(store_path), dc, "pick_place", 0, 1)
    out = run_item(env, WorkItem(scene.id, (0, 1)), first_attempts={0: 1, 1: 3})
    store = EpisodeStore(store_path)
    tried = out["new"] + sum(v for k, v in out["failures"].items() if k != "scene_unusable")
    assert 1 <= tried <= 2, dict(out["failures"])  # slot 0 only: attempts 1 and 2
    assert out["new"] == 1, dict(out["failures"])
    (eid,) = store.episode_ids()
    info = store.info(eid)
    assert eid == episode_id(scene.id, 0) and info.recorder == "cpu"
    assert info.seed in (episode_seed(0, scene.id, 0, 1), episode_seed(0, scene.id, 0, 2))


RGB_TOLERANCE = 40.0
"""Largest mean absolute RGB difference (0-255) between the two executors' images of a camera:
the ray tracer and OpenGL shade differently (other light falloff and specular highlights, no
headlight ambient in the same amount), the geometry is the same (depth agrees to the mm).
Measured on the H200: 9-25 at 128 px on two generated kitchens
(benchmarks/results/demos-agreement-h200.json), up to 36 at 64 px on the test kitchen's wrist
camera."""

DEPTH_TOLERANCE_MM = 5.0
"""Largest median absolute depth difference (mm) of a camera."""


@pytest.mark.gpu
def test_gpu_executor_agrees_with_cpu(setup) -> None:
    from factory.demos.execute.agreement import compare_executors

    planner = EpisodePlanner(setup)
    plans = []
    for seed in range(40):
        res = planner.plan_episode(seed)
        if isinstance(res, EpisodePlan):
            plans.append(res)
        if len(plans) == 16:
            break
    assert len(plans) >= 12
    cfg = RecordConfig(width=64, height=64)
    agreement, cpu, gpu = compare_executors(setup, plans, cfg)
    s = agreement.summary()
    assert agreement.verdicts_agree >= 15 / 16 if len(plans) == 16 else 0.9, s
    assert s["gpu_successes"] >= 0.8 * len(plans), s
    assert s["ee_max_m"]["median"] < 0.01, s
    for cam in cfg.cameras:
        assert s["rgb_mean_abs"][cam] < RGB_TOLERANCE, s
        assert s["depth_median_abs_mm"][cam] < DEPTH_TOLERANCE_MM, s
    assert all(len(a.time) == len(b.time) for a, b in zip(cpu, gpu, strict=True))
    assert all(a.camera_poses == b.camera_poses for a, b in zip(cpu, gpu, strict=True))


@pytest.mark.slow
def test_gpu_pipeline_on_warp_cpu(
    make_kitchen, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The GPU pipeline end to end on Warp's CPU device (kernels compile in about 2-3 min):
    four slots: the longest left to the CPU executor (``demos.gpu_tail``), three packed onto
    two worlds of one call, stored by the writer processes, replayable; the kernels' loading
    is announced with the cache it reads, and its end with the seconds it took; the kernels
    are warmed up while the scene's plans are made."""
    import logging

    caplog.set_level(logging.INFO, logger="factory.demos.execute.warp")
    from factory.demos.gpu_pipeline import run_gpu
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.slots import StageEnv, WorkItem
    from factory.schema import scene_to_json

    run = tmp_path / "run"
    scene = make_kitchen(run / "assets")
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    dc = DemosConfig(sleep=False, width=32, height=32, gpu_batch=2, gpu_tail=0.25)
    store_path = run / "episodes" / "shard-0.zarr"
    env = StageEnv(str(run), str(store_path), dc, "pick_place", 0, 1)
    (out,) = run_gpu(env, [WorkItem(scene.id, (0, 1, 2, 3))], 1, device="cpu")
    assert out["executor"] == "warp" and out["error"] is None
    assert out["new"] + sum(out["failures"].values()) >= 4
    assert out["new"] >= 3, dict(out["failures"])
    assert out["cpu_tail"] == 1
    assert "loading the GPU kernels (Warp kernel cache" in caplog.text
    assert re.search(r"GPU kernels ready in [0-9.]+ s", caplog.text), caplog.text[-2000:]
    assert "GPU kernels warmed up in" in caplog.text  # while the plans were made
    store = EpisodeStore(store_path)
    assert len(store.episode_ids()) == out["new"]
    infos = [store.info(e) for e in store.episode_ids()]
    by = {i.recorder: i for i in infos}
    assert sorted(i.recorder for i in infos).count("cpu") == 1, [i.recorder for i in infos]
    # The CPU recorded the longest episode, the GPU the others.
    assert by["cpu"].n_frames >= max(i.n_frames for i in infos if i.recorder == "warp")
    info = by["warp"]
    assert info.success and info.n_frames > 50
    assert store.arrays(info.episode_id)["rgb/wrist"].shape == (info.n_frames, 32, 32, 3)


@pytest.mark.gpu
def test_gpu_pipeline_readies_the_next_scene_while_one_records(
    make_kitchen, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Two kitchens: the second's executor is made and its kernels warmed up in the set-up thread
    while the first records on the GPU (its CUDA graph captured under
    ``warp.DEVICE_LOCK``), and both scenes store their episodes."""
    import logging

    caplog.set_level(logging.INFO, logger="factory.demos")
    from factory.demos.gpu_pipeline import run_gpu
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.slots import StageEnv, WorkItem
    from factory.schema import scene_to_json

    run = tmp_path / "run"
    scenes = [make_kitchen(run / "assets", seed=s, scene_id=f"kitchen_{s}") for s in (3, 4)]
    for scene in scenes:
        (run / "scenes" / scene.id).mkdir(parents=True)
        (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    dc = DemosConfig(sleep=False, width=32, height=32, gpu_batch=8, gpu_tail=0.0)
    store_path = run / "episodes" / "shard-0.zarr"
    env = StageEnv(str(run), str(store_path), dc, "pick_place", 0, 1)
    items = [WorkItem(s.id, tuple(range(4))) for s in scenes]
    outs = run_gpu(env, items, 2, device="cuda:0")
    for out in outs:
        assert out["error"] is None and out["new"] >= 3, dict(out["failures"])
    assert "readying the GPU executor ahead failed" not in caplog.text
    warmed = re.findall(r"demos (\S+): GPU kernels warmed up in", caplog.text)
    assert warmed == [s.id for s in scenes], caplog.text[-3000:]
    store = EpisodeStore(store_path)
    assert len(store.episode_ids()) == sum(o["new"] for o in outs)


@pytest.mark.gpu
def test_gpu_demos_stage_cli(cli, make_kitchen, tmp_path: Path) -> None:
    """``demos.executor=warp`` through the CLI: planned in worker processes, executed on the
    GPU, stored like the CPU executor's episodes; a re-run resumes (nothing left to do)."""
    import json

    from factory.demos.record.episodes import EpisodeStore
    from factory.schema import scene_to_json

    run = tmp_path / "run"
    scene = make_kitchen(run / "assets")
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    args = ["stage=demos", f"run_dir={run}", "demos.executor=warp", "demos.episodes_per_scene=4"]
    out = cli(*args, "demos.workers=2", "demos.width=64", "demos.height=64")
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["executor"] == "warp" and summary["new_successes"] >= 3, summary
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    eid = store.episode_ids()[0]
    info = store.info(eid)
    assert info.success and info.n_frames > 50
    assert store.arrays(eid)["rgb/left"].shape == (info.n_frames, 64, 64, 3)
    again = cli(*args)
    assert again.returncode == 0
    assert json.loads((run / "episodes" / "summary-0-of-1.json").read_text())["new_successes"] == 0


def test_njmax_comes_in_size_classes() -> None:
    """Constraint buffers are rounded up to 2^k or 3 * 2^k rows, so that MuJoCo Warp's
    solver kernel specialised to ``njmax`` compiles for a few sizes, not for every call."""
    from factory.demos.execute.warp import size_class

    asked = (1, 3, 5, 7, 9, 13, 100, 1537)
    assert [size_class(n) for n in asked] == [1, 3, 6, 8, 12, 16, 128, 2048]
    sizes = [size_class(n) for n in range(1, 5000)]
    assert all(n <= c < 1.5 * n + 1 for n, c in zip(range(1, 5000), sizes, strict=True))
    assert len(set(sizes)) == 25  # 1, 2, 3, 4, 6, 8, ..., 4096, 6144


def test_quat_from_mat_is_mujocos() -> None:
    """The vectorized rotation-to-quaternion of the GPU recording equals mju_mat2Quat."""
    from factory.demos.execute.warp import quat_from_mat

    rng = np.random.default_rng(1)
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    mats = np.zeros((500, 9))
    ref = np.zeros((500, 4))
    for i in range(500):
        mujoco.mju_quat2Mat(mats[i], q[i])
        mujoco.mju_mat2Quat(ref[i], mats[i])
    assert np.allclose(quat_from_mat(mats.reshape(500, 3, 3)), ref, atol=1e-12)


def test_gpu_calls_pack_a_scene_into_calls_that_fit(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A scene's episodes go to the GPU in as few calls as memory allows, each packing its
    episodes onto at most ``gpu_batch`` worlds with little idle time; calls share the mix of
    lengths and stay within the memory budget. Each scene's split and the stage's sizing are
    one log line each."""
    import logging
    import os
    from types import SimpleNamespace

    from factory.demos.execute import gpu_calls
    from factory.demos.execute.cpu import RecordConfig
    from factory.demos.execute.world_schedule import packed_schedule

    rng = np.random.default_rng(0)
    steps = rng.integers(3000, 9000, 1100)
    planned = [(k, k, SimpleNamespace(ctrl=np.zeros((int(t), 9)))) for k, t in enumerate(steps)]
    cfg = RecordConfig(fps=20.0, width=64, height=64, cameras=("left", "right", "wrist"))
    page = os.sysconf("SC_PAGE_SIZE")
    monkeypatch.setattr(os, "sysconf", lambda k: 2**40 // page if "PAGES" in k else page)
    calls = gpu_calls.gpu_calls(planned, 1024, cfg, 0.002)
    frames = [int(np.ceil(len(p.ctrl) / 25)) + 1 for _, _, p in calls[0][0]]
    worlds = -(-sum(frames) // max(frames))  # the call lasts about its longest episode
    assert [(len(c), w) for c, w in calls] == [(1100, worlds)]  # one call
    assert 700 < worlds < 800
    # Packed: under 15 % idle; one world per episode would idle a third of the time.
    assert packed_schedule(frames, worlds).busy() > 0.85 > 0.7 > np.mean(frames) / max(frames)
    assert gpu_calls.gpu_calls(planned, 512, cfg, 0.002)[0][1] == 512  # gpu_batch caps
    # 4 GiB of host memory, 128 px images: several calls, each within the budget.
    monkeypatch.setattr(os, "sysconf", lambda k: 4 * 2**30 // page if "PAGES" in k else page)
    big = RecordConfig(fps=20.0, width=128, height=128, cameras=("left", "right", "wrist"))
    budget = gpu_calls.memory_budget()
    assert budget is not None
    with caplog.at_level(logging.INFO, logger="factory.demos.execute.gpu_calls"):
        calls = gpu_calls.gpu_calls(planned, 512, big, 0.002, "kitchen_x")
    assert len(calls) > 3
    line = caplog.records[-1].getMessage()
    assert line.startswith(f"scene kitchen_x: 1100 episode(s) in {len(calls)} GPU call(s) of ")
    assert "demos.gpu_batch=512" in line and f"budget {budget / 1e9:.1f} GB" in line
    text = gpu_calls.sizing_line("cuda:0", 3 * 10**9, 4 * 10**9, 3 * 10**9, 512, True, 0.7)
    assert "may take 3.0 GB (the least of: host 4.0 GB (70% of its available memory)" in text
    assert "cuda:0 3.0 GB (60% of its free memory)" in text and "gpu_batch=512" in text
    assert sorted(k for c, _ in calls for k, _, _ in c) == list(range(1100))
    for c, w in calls:
        assert sum(gpu_calls.episode_bytes(p, big, 0.002) for _, _, p in c) <= budget
        assert w <= min(512, len(c))
    means = [np.mean([len(p.ctrl) for _, _, p in c]) for c, _ in calls]
    assert max(means) - min(means) < 0.1 * np.mean(means)  # the same mix of lengths
    assert gpu_calls.gpu_calls([], 512, cfg, 0.002) == []


@pytest.mark.parametrize(
    "device",
    [
        pytest.param("cpu", marks=pytest.mark.slow),
        pytest.param("cuda:0", marks=pytest.mark.gpu),
    ],
)
def test_packed_worlds_record_what_padded_worlds_record(
    setup, device: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three episodes packed onto two worlds (the third starts in the world of the shortest
    as soon as it ends, through ``mujoco_warp.reset_data``; on CUDA inside the captured
    graph) record the states and images that three worlds starting together record.

    The executor's kernel warm-up (a dry trace of its launches, then the modules in parallel)
    leaves no module for the calls to compile."""
    from factory.demos.execute.warp import WarpExecutor

    late = modules_compiled_after_preload(monkeypatch)
    if device == "cpu":
        setup = without_sleep(setup)
    planner = EpisodePlanner(setup)
    plans = [p for p in (planner.plan_episode(s) for s in range(8)) if isinstance(p, EpisodePlan)]
    assert len(plans) >= 3
    # Short episodes of different lengths: the first 0.25-0.5 s of each.
    plans = [
        dataclasses.replace(p, ctrl=p.ctrl[:k], targets=p.targets[:k])
        for p, k in zip(plans[:3], (250, 125, 150), strict=True)
    ]
    cfg = RecordConfig(width=16, height=16)
    ex = WarpExecutor(setup, cfg, device=device)
    ex.warm_up()  # as the GPU pipeline does while the plans are made
    padded = ex.execute(plans)
    packed = ex.execute(plans, worlds=2)
    for a, b in zip(padded, packed, strict=True):
        assert len(a.state) == len(b.state)
        # Warp's CPU device is deterministic; on CUDA the order of contacts (atomics across
        # worlds) differs with the number of worlds, so float32 sums differ in the last bits.
        np.testing.assert_allclose(a.state, b.state, atol=1e-5 if device == "cpu" else 3e-3)
        np.testing.assert_array_equal(a.action, b.action)
        for cam in cfg.cameras:
            assert np.mean(a.rgb[cam] != b.rgb[cam]) < 0.01
        assert a.outcome is not None and b.outcome is not None
        assert a.outcome.reason == b.outcome.reason
    assert late == [], f"compiled after the preload: {late}"


@pytest.mark.slow
def test_images_kept_on_device_equal_frame_by_frame_copies(setup) -> None:
    """The pipeline's modes (images stored on the device and copied to a shared arena at the
    end, or every frame copied into an arena) record the same images and states as copying
    every frame into ordinary arrays (Warp's CPU device: deterministic)."""
    from factory.demos.execute.shared_frames import ArenaPool, supported
    from factory.demos.execute.warp import WarpExecutor

    if not supported():
        pytest.skip("shared arenas are Linux only")
    setup = without_sleep(setup)  # Warp's CPU device
    planner = EpisodePlanner(setup)
    plans = [p for p in (planner.plan_episode(s) for s in range(6)) if isinstance(p, EpisodePlan)]
    plans = sorted(plans, key=lambda p: len(p.ctrl))[:2]
    assert len(plans) == 2
    # Short episodes: the first 0.3 s of each (the success checks may fail; images are compared).
    plans = [dataclasses.replace(p, ctrl=p.ctrl[:150], targets=p.targets[:150]) for p in plans]
    cfg = RecordConfig(width=24, height=24)
    plain = WarpExecutor(setup, cfg, device="cpu").execute(plans)
    pool = ArenaPool(1 << 24)
    for on_device in (True, False):  # both ways of recording into shared arenas
        kept = WarpExecutor(setup, cfg, device="cpu", arenas=pool, images_on_device=on_device)
        stored = kept.execute(plans)
        assert kept.take_arenas()  # the recordings went to an arena
        for a, b in zip(plain, stored, strict=True):
            np.testing.assert_array_equal(a.state, b.state)
            for cam in cfg.cameras:
                assert a.rgb[cam].std() > 0
                np.testing.assert_array_equal(a.rgb[cam], b.rgb[cam])
                np.testing.assert_array_equal(a.depth[cam], b.depth[cam])
    pool.close()


@pytest.mark.slow
def test_overflowing_worlds_run_again_with_more_room_then_fail_cleanly(
    setup, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """On Warp's CPU device: worlds whose contact and constraint buffers overflow (one contact
    and one constraint row more than the dofs) are run again with more room and then record
    what a call with room records; where they overflow every time, their outcome is
    ``sim_overflow`` (retried by the CPU executor with the next seed), never a recording of a
    wrong simulation, and the call does not fail."""
    import logging

    from factory.demos.execute import warp as wx

    setup = without_sleep(setup)  # Warp's CPU device
    planner = EpisodePlanner(setup)
    plans = [p for p in (planner.plan_episode(s) for s in range(3)) if isinstance(p, EpisodePlan)]
    plans = [dataclasses.replace(p, ctrl=p.ctrl[:30], targets=p.targets[:30]) for p in plans[:1]]
    ex = wx.WarpExecutor(setup, RecordConfig(width=16, height=16), device="cpu")
    want = ex.execute(plans)
    real = wx.buffer_sizes

    def tight(model, qpos, headroom=3.0):  # type: ignore[no-untyped-def]
        return (1, model.nv + 1) if headroom <= 3.0 else real(model, qpos, headroom)

    monkeypatch.setattr(wx, "buffer_sizes", tight)
    with caplog.at_level(logging.INFO, logger="factory.demos.execute.warp"):
        again = ex.execute(plans)
    assert "1 world(s) overflowed; re-running with more room" in caplog.text
    for a, b in zip(want, again, strict=True):
        np.testing.assert_allclose(a.state, b.state, atol=1e-5)
        assert a.outcome is not None and b.outcome is not None
        assert a.outcome.reason == b.outcome.reason != wx.OVERFLOW
    monkeypatch.setattr(wx, "buffer_sizes", lambda model, qpos, headroom=3.0: (1, model.nv + 1))
    failed = ex.execute(plans)
    assert [r.outcome.reason for r in failed if r.outcome] == [wx.OVERFLOW]
    assert not any(r.outcome.success for r in failed if r.outcome)


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.gpu)])
def test_image_store_rows_past_two_gib_of_a_camera(device: str) -> None:
    """Regression of the H100 crash at production size (CUDA error 700): the image store was one
    camera-major ``(ncam, rows, 3 H W)`` array, whose first stride (a camera's block, 2 GiB at
    43,691 rows of 128 x 128) overflowed Warp's 32-bit strides. Now each camera has its own
    ``(rows, 3 H W)`` store: ``to_images`` files a world's frame into row 43,999 of camera 1's
    2.2 GB store, and :func:`check_strides` refuses the old layout. On Warp's CPU device in CI;
    on CUDA (``gpu``) at the size class of the crashed call (44,000 rows, about the rows of one
    of the 761-episode calls that died), where a wrong stride is an illegal memory access."""
    wp = pytest.importorskip("warp")
    from factory.demos.execute.warp import check_strides
    from factory.demos.execute.warp_kernels import to_images
    from factory.errors import RenderError
    from factory.sim.backend import init_warp

    init_warp()
    npix, rows, ncam = 128 * 128, 44_000, 2
    with wp.ScopedDevice(device):
        packed = np.zeros((2, ncam * npix), np.uint32)
        packed[0, npix:] = 0x00102030  # world 0, camera 1: RGB (16, 32, 48)
        depth = np.full((2, ncam * npix), 1.234, np.float32)
        depth[0, npix : npix + 2] = (np.nan, np.inf)  # rays that hit nothing: the far value
        adr = wp.array(np.arange(ncam, dtype=np.int32) * npix, dtype=int)
        rgb = wp.empty((rows, 3 * npix), dtype=wp.uint8)
        mm = wp.empty((rows, npix), dtype=wp.uint16)
        check_strides([rgb, mm])
        row_of = wp.array(np.array([[rows - 1, -1]], np.int32), dtype=int)
        wp.launch(
            to_images,
            dim=(2, npix),
            inputs=[
                wp.array(packed, dtype=wp.uint32),
                wp.array(depth, dtype=float),
                adr,
                adr,
                1,
                npix,
                1,
                100.0,
                row_of,
                wp.zeros(1, dtype=int),
                1,
            ],
            outputs=[rgb, mm, wp.empty((1, 1), dtype=float)],
        )
        wp.synchronize()
        last = rgb.numpy()[rows - 1].reshape(128, 128, 3)
        assert (last == [16, 32, 48]).all()
        assert (mm.numpy()[rows - 1, 2:] == 1234).all()
        assert (mm.numpy()[rows - 1, :2] == 65535).all()
        # the old camera-major layout: its strides would not fit (a view, nothing allocated)
        old = wp.array(
            ptr=rgb.ptr,
            shape=(3, rows, 3 * npix),
            dtype=wp.uint8,
            strides=(rows * 3 * npix, 3 * npix, 1),
        )
        with pytest.raises(RenderError, match=r"demos\.gpu_batch"):
            check_strides([old])
