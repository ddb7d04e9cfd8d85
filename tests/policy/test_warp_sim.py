"""The env on MuJoCo Warp (``eval.executor=warp``, :mod:`factory.policy.warp_sim`) against the
CPU env. On the CPU (Warp's CPU device, slow: about 0.6 s a frame here) the first frames of a
recorded episode: the arm tracks the same joints and the batch renderer's images are alike to
OpenGL's, and ``stage=eval`` runs a trained policy's episodes on it. On the GPU machine
(``gpu``), whole recorded episodes replay to success and the planner's verdicts are the CPU
env's."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from robot_models import require_robot_models
from warp_modules import modules_compiled_after_preload

if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()
pytest.importorskip("gymnasium")
pytest.importorskip("mujoco_warp")

from factory.config import EvalConfig, FactoryConfig, TrainConfig
from factory.context import StageContext
from factory.demos.record.episodes import EpisodeStore
from factory.errors import ConfigError
from factory.policy.env import make_vec_env
from factory.policy.eval import Job, run_batch, scripted_actor
from factory.policy.obs_spec import ObsSpec
from factory.store import RunStore, Shard

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

SPEC = ObsSpec(cameras=("left", "wrist"), width=32, height=32)


def _replay_jobs(run: Path, n: int, frames: int = 0) -> tuple[list[Job], list[np.ndarray]]:
    """Replay jobs of the first ``n`` recorded episodes (``frames`` > 0: their first frames
    only) and their recorded joints."""
    (path,) = sorted((run / "episodes").glob("shard-*.zarr"))
    store = EpisodeStore(path)
    jobs, joints = [], []
    for eid in store.episode_ids()[:n]:
        g = store.arrays(eid)
        info = store.info(eid)
        length = info.n_frames - 1 if frames <= 0 else min(frames, info.n_frames - 1)
        jobs.append(
            Job(
                scene="kitchen_a",
                seed=info.seed,
                episode_id=eid,
                state=g["state"][0],
                actions=np.asarray(g["action"][:length], np.float32),
                max_steps=length,
            )
        )
        joints.append(g["joint_pos"][:])
    return jobs, joints


def _replay(
    run: Path, executor: str, n: int, frames: int = 0
) -> tuple[list[dict], list[dict[str, np.ndarray]], list[np.ndarray], str]:
    jobs, joints = _replay_jobs(run, n, frames)
    vec, _ = make_vec_env(run, "kitchen_a", len(jobs), SPEC, nthread=2, executor=executor)
    device = str(getattr(vec.sim, "device", "cpu"))
    seen: list[dict[str, np.ndarray]] = []
    base = scripted_actor(jobs)

    def actor(obs, steps):
        seen.append({k: v.copy() for k, v in obs.items()})
        return base(obs, steps)

    try:
        records, _ = run_batch(vec, jobs, actor)
    finally:
        vec.close()
    return records, seen, joints, device


def _joint_error(seen: list[dict[str, np.ndarray]], joints: list[np.ndarray], records) -> float:
    worst = 0.0
    for i, q in enumerate(joints):
        n = min(records[i]["steps"], len(seen))
        got = np.stack([s["observation.state"][i, :7] for s in seen[:n]])
        worst = max(worst, float(np.abs(got - q[:n]).max()))
    return worst


def test_warp_env_tracks_the_cpu_env(policy_run: Path) -> None:
    """The first 10 frames of a recorded episode on Warp's CPU device: the arm's joints stay
    within 0.01 rad of the recorded ones (float32 physics) as on the CPU env, and the first
    frame's images are alike to OpenGL's (same cameras and sizes; RGB within 40 levels on
    average, depth within 5 cm for most pixels)."""
    cpu, cpu_seen, joints, _ = _replay(policy_run, "cpu", 1, frames=10)
    gpu, gpu_seen, _, device = _replay(policy_run, "warp", 1, frames=10)
    assert device == "cpu"
    assert cpu[0]["steps"] == gpu[0]["steps"] == 10
    assert _joint_error(cpu_seen, joints, cpu) < 0.01
    assert _joint_error(gpu_seen, joints, gpu) < 0.01
    for cam in SPEC.cameras:
        a, b = cpu_seen[0][f"observation.images.{cam}"], gpu_seen[0][f"observation.images.{cam}"]
        assert a.shape == b.shape == (1, 32, 32, 3) and b.dtype == np.uint8
        assert np.abs(a.astype(int) - b.astype(int)).mean() < 40, cam
        da, db = cpu_seen[0][f"observation.depth.{cam}"], gpu_seen[0][f"observation.depth.{cam}"]
        assert db.dtype == np.uint16
        close = np.abs(da.astype(int) - db.astype(int)) < 50
        assert close.mean() > 0.8, (cam, close.mean())


def test_warp_physics_with_opengl_images(policy_run: Path) -> None:
    """``eval.executor=warp_opengl`` (the diagnostic): MuJoCo Warp steps the worlds (no render
    context on the device) and OpenGL draws the cameras from each world's state, so the first
    frame's images are the CPU env's exactly and the joints track the recording as on Warp."""
    _, cpu_seen, joints, _ = _replay(policy_run, "cpu", 1, frames=1)
    mixed, mixed_seen, _, device = _replay(policy_run, "warp_opengl", 1, frames=10)
    assert device == "cpu" and mixed[0]["steps"] == 10
    assert _joint_error(mixed_seen, joints, mixed) < 0.01
    for cam in SPEC.cameras:
        for kind in ("images", "depth"):
            key = f"observation.{kind}.{cam}"
            np.testing.assert_array_equal(mixed_seen[0][key], cpu_seen[0][key], err_msg=key)
    with pytest.raises(ConfigError, match="use warp or opengl"):
        from factory.policy.warp_sim import WarpBatchSim

        WarpBatchSim(None, 1, SPEC, images="vulkan")  # type: ignore[arg-type]


def test_warp_env_preloads_its_kernels(policy_run: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The env's MuJoCo Warp kernels (physics, renderer, the image and control kernels) are
    loaded on every core before the first frame, from a dry trace of one frame on one world:
    the trace runs through, and the frames after it compile no module it missed."""
    late = modules_compiled_after_preload(monkeypatch)
    jobs, _ = _replay_jobs(policy_run, 1, frames=2)
    vec, _ = make_vec_env(policy_run, "kitchen_a", 1, SPEC, nthread=2, executor="warp")
    try:
        report = vec.sim.preload
        assert report.error == "" and report.modules > 0
        records, _ = run_batch(vec, jobs, scripted_actor(jobs))
    finally:
        vec.close()
    assert [r["steps"] for r in records] == [2]
    assert late == [], f"compiled after the preload: {late}"


def test_eval_executor_settings() -> None:
    """A bad ``eval.executor`` names the choices; a task that simulates its episodes itself
    (the mobile one) is refused by the Warp env with the fix."""
    from factory.policy.eval_stage import check_config
    from factory.policy.vector_env import task_sim

    with pytest.raises(
        ConfigError, match=r"eval\.executor='gpu' is unknown: use one of cpu, warp, warp_opengl"
    ):
        check_config(EvalConfig(executor="gpu"))

    class _OwnSim:
        name = "mobile_pick_place"

        def env_sim(self, *args):
            return object()

    with pytest.raises(ConfigError, match=r"use eval\.executor=cpu"):
        task_sim(_OwnSim(), None, None, 1, ObsSpec(cameras=()), executor="warp")  # type: ignore[arg-type]


def _eval(run: Path, executor: str, **ec) -> dict:
    from factory.policy.eval_stage import run as eval_stage

    cfg = FactoryConfig(stage="eval", run_dir=str(run))
    cfg.eval = EvalConfig(name=f"{ec['policy']}_{executor}", executor=executor, videos=0, **ec)
    eval_stage(StageContext(cfg, RunStore(run), Shard(0, 1)))
    return json.loads((run / "eval" / cfg.eval.name / "results.json").read_text())


@pytest.mark.parametrize("vision", ["end_to_end", "perception"])
def test_eval_stage_on_warp(policy_run: Path, tmp_path: Path, vision: str) -> None:
    """``stage=eval eval.executor=warp`` with a trained RGB-D policy, lerobot's image encoder or
    the perception network (which also reads the cameras' calibration): the held-out kitchen's
    episodes are the worlds of one MuJoCo Warp model (here 2, for 4 frames), observed through
    the batch renderer, with the CPU env's records."""
    from factory.policy.train_stage import run as train_stage

    run = tmp_path / "run"
    shutil.copytree(policy_run, run)
    tiny = {"diffusion": {"horizon": 8, "n_action_steps": 4, "down_dims": [16, 32]}}
    cfg = FactoryConfig(
        stage="train",
        run_dir=str(run),
        train=TrainConfig(
            name="warp_tiny",
            inputs="rgbd",
            vision=vision,
            steps=1,
            batch_size=2,
            threads=1,
            options=tiny,
        ),
    )
    train_stage(StageContext(cfg, RunStore(run), Shard(0, 1)))
    got = {
        ex: _eval(
            run, ex, policy="warp_tiny", episodes_per_scene=2, max_steps=4, workers=1, device="cpu"
        )
        for ex in ("cpu", "warp")
    }
    assert got["warp"]["episodes"] == got["cpu"]["episodes"] == 2
    lines = (run / "eval" / "warp_tiny_warp" / "episodes.jsonl").read_text().splitlines()
    assert [json.loads(x)["steps"] for x in lines] == [4, 4]
    # the set-up's kernel preload is in the Warp call's timing (what a slow set-up was), not
    # in the CPU env's
    t = got["warp"]["timing_this_call"]
    assert t["kernels_loaded"] >= 0 and t["kernel_load_s"] > 0 and t["kernel_wait_s"] >= 0
    assert t["kernel_modules"] >= t["kernels_loaded"] and t["kernel_modules"] > 10
    assert "kernels_loaded" not in got["cpu"]["timing_this_call"]


@pytest.mark.gpu
def test_warp_env_replays_on_cuda(policy_run: Path) -> None:  # pragma: no cover - GPU machine
    """Whole recorded episodes replay to success on CUDA (a frame is one CUDA graph), as on
    the CPU env, with the joints within 0.03 rad of the recorded ones."""
    cpu, _, _, _ = _replay(policy_run, "cpu", 3)
    gpu, seen, joints, device = _replay(policy_run, "warp", 3)
    assert device.startswith("cuda")
    assert [r["success"] for r in gpu] == [r["success"] for r in cpu] == [True] * 3, gpu
    assert _joint_error(seen, joints, gpu) < 0.03


@pytest.mark.gpu
def test_planner_verdicts_on_cuda(policy_run: Path, tmp_path: Path) -> None:  # pragma: no cover
    """The planner on the held-out kitchen's configurations: the same verdicts on the Warp env
    (CUDA) as on the CPU env."""
    run = tmp_path / "run"
    shutil.copytree(policy_run, run)
    got = {ex: _eval(run, ex, policy="planner", episodes_per_scene=4) for ex in ("cpu", "warp")}
    assert got["warp"]["episodes"] == got["cpu"]["episodes"] == 4
    assert got["warp"]["successes"] == got["cpu"]["successes"]
