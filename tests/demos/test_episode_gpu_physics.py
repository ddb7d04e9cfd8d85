"""The ``episode`` execution's GPU physics (``demos.episode_physics``,
:mod:`factory.demos.episode_physics`) on Warp's CPU device: ``task=open``, ``close`` and
``place_inside`` plans stepped as MuJoCo Warp worlds and recorded from their states on the
host get the CPU executor's verdicts on the same plans (a plan stopped part way included: its
failure and reason too), and the GPU pipeline stores episodes that pass the CPU path's
checks.

Island sleeping is off (``demos.sleep=false``): on Warp's CPU device MuJoCo Warp's sleeping
steps cost about 6 times as much (57 against 10 ms a step for the bundled cabinet), and an
articulated episode runs about 4,000 steps; the CPU executor is run with the same model.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

require_robot_models()
pytest.importorskip("ompl")
pytest.importorskip("mujoco_warp")

pytestmark = pytest.mark.xdist_group("warp")


def _scene(task: str, run: Path, **demos: Any) -> Any:
    """Task ``task``'s bundled example scene copied into ``run`` and set up for ``stage=demos``
    with its planner (island sleeping off)."""
    from factory.config import DemosConfig
    from factory.demos.record.slots import StageEnv
    from factory.tasks import get_task

    src = get_task(task).example_scene_path()
    assert src is not None
    sid = json.loads(src.read_text())["id"]
    (run / "scenes" / sid).mkdir(parents=True)
    (run / "scenes" / sid / "scene.json").write_text(src.read_text())
    dc = DemosConfig(sleep=False, **demos)
    env = StageEnv(str(run), str(run / "episodes" / "shard-0.zarr"), dc, task, 0, 1)
    return get_task(task).demo_scene(env, sid)


def _stopped(plan: Any, phase: str) -> Any:
    """``plan`` with its arm and hand held where ``phase`` starts."""
    ctrl = plan.ctrl.copy()
    k = plan.phases[phase]
    ctrl[k:] = ctrl[k]
    return replace(plan, ctrl=ctrl)


STOPPED = {
    "open": ("pull", "not_open"),
    "close": ("pull", "not_closed"),
    "place_inside": ("transport", "dropped"),
}
"""Per task, the phase a plan is stopped at and the CPU executor's verdict on it: the part never
moves with the handle held (``open``, ``close``); the object, lifted, never reaches its place
(``place_inside``)."""

SIGNALS_ATOL = {
    "open": (1e-3, 1e-3, slice(None), 3e-3),
    "close": (1e-3, 1e-3, slice(None), 3e-3),
    "place_inside": (0.05, 0.06, [0, 2, 3, 4], 0.03),
}
"""Per task, the largest difference over all frames between the CPU executor's recording and
the one from MuJoCo Warp's states: of the arm joints (rad), of the tool position and of the
compared values of ``env_state`` (m or rad), then of the readings between frames (the probes':
``slip``, ``lifted``, ``off_place``; m). Measured on Warp's CPU device at 5 fps: ``open`` and
``close`` about 1e-5 throughout. ``place_inside`` (the drawer example, seed 0, the can carried
into the drawer, and the plan stopped at the lift): the arm joints up to 0.032 rad on 10 of
161 frames, the tool 0.017 m, the drawer's joint 0.046 m and the can's position 0.048 m apart
mid-motion (the same motion a few milliseconds earlier or later), the final states within
0.013 m, the can's place reading 0.018 against 0.031 m (both under ``DROPPED``, 0.05 m), the
verdicts the same; its ``env_state`` compared on the drawer's joint and the can's position
(not the share of the range, the joint's scaled, nor the can's quaternion, whose spin about
its own axis is free)."""


@pytest.mark.parametrize(
    "task",
    [
        "open",
        "close",
        # about 4.5 minutes on Warp's CPU device (its own kernels, more steps): on the GPU
        pytest.param("place_inside", marks=pytest.mark.gpu),
    ],
)
def test_verdicts_agree_with_the_cpu_executor(task: str, tmp_path: Path) -> None:
    """A planned episode and the same plan stopped part way (:data:`STOPPED`), simulated on
    the CPU (the task's ``execute_episode``) and as two MuJoCo Warp worlds (recorded from their
    states): the same verdicts and reasons, the part's final joint within 1 mm, the recorded
    signals and ``env_state`` alike frame by frame (:data:`SIGNALS_ATOL`), the same actions.
    MuJoCo Warp runs on CUDA where present, else on Warp's CPU device."""
    from factory.demos.episode_physics import simulate_plans, states_recorder
    from factory.demos.execute.plan_worlds import WarpPlanWorlds

    scene = _scene(task, tmp_path, fps=5.0, render=False)
    cfg = scene.record_config(render=False)
    phase, reason = STOPPED[task]
    for seed in range(4):  # the first seed that plans and succeeds on the CPU
        plan = scene.plan(seed)
        if isinstance(plan, scene.plan_type) and scene.simulate(plan, cfg).outcome.success:
            break
    else:
        pytest.fail(f"no {task} seed of 4 planned and succeeded on the CPU")
    plans = [plan, _stopped(plan, phase)]
    cpu = [scene.simulate(p, cfg) for p in plans]
    assert [r.outcome.reason for r in cpu] == ["", reason]
    hook = states_recorder(scene, "warp")  # place_inside: not taken under auto
    assert hook is not None and len(hook.probes(plan)) == {"place_inside": 2}.get(task, 1)
    runner = WarpPlanWorlds(scene.setup.model, hook.robot_geom, hook.allowed, cfg.fps)
    gpu = simulate_plans(runner, hook, plans, cfg)
    assert runner.times.calls == 1 and runner.times.worlds == 2
    pairs = list(zip(cpu, gpu, strict=True))
    for c, g in pairs:
        assert (g.outcome.success, g.outcome.reason) == (c.outcome.success, c.outcome.reason)
        assert g.outcome.details["joint"] == pytest.approx(c.outcome.details["joint"], abs=1e-3)
        assert g.state.shape == c.state.shape and len(g.time) == len(c.time)
        np.testing.assert_array_equal(g.action, c.action)
    rad, m, cols, probe_m = SIGNALS_ATOL[task]
    diffs = {
        "joint_pos": max(float(np.abs(g.joint_pos - c.joint_pos).max()) for c, g in pairs),
        "ee_pos": max(float(np.abs(g.ee_pose[:, :3] - c.ee_pose[:, :3]).max()) for c, g in pairs),
        "env_state": max(
            float(np.abs(g.env_state[:, cols] - c.env_state[:, cols]).max()) for c, g in pairs
        ),
    }
    assert diffs["joint_pos"] <= rad and max(diffs["ee_pos"], diffs["env_state"]) <= m, diffs
    for key in ("slip", "lifted", "off_place"):  # the readings between frames (probes)
        if key in cpu[0].outcome.details:
            for c, g in zip(cpu, gpu, strict=True):
                assert g.outcome.details[key] == pytest.approx(c.outcome.details[key], abs=probe_m)
    if task != "place_inside":  # the probe read the pull's end (the handle held), not the end
        assert gpu[0].outcome.details["slip"] < 0.01 < gpu[0].outcome.details["released"]


def test_open_through_the_gpu_pipeline_stores_checked_episodes(tmp_path: Path) -> None:
    """``task=open`` through the GPU pipeline on Warp's CPU device (``demos.episode_physics``
    auto: the planner process only plans; the main process simulates both slots as MuJoCo
    Warp worlds and draws the successes, 32 px): both stored, recorded by ``warp``, passing
    the CPU path's checks (the success rule, the hand reaching the handle, the joint as
    stored), their stored states giving their stored ``env_state`` again, and their recorded
    actions replayed in the evaluation env ending in success (``eval.policy=replay``). (A
    seed planned again need not give the same plan: the free motions' smoothing is
    time-bounded; the verdicts on the same plans are the test above.)"""
    from factory.demos.episode_execution import episode_slot
    from factory.demos.gpu_pipeline import run_gpu
    from factory.demos.record.episodes import EpisodeStore
    from factory.demos.record.payload import STATE_SPEC
    from factory.demos.record.slots import WorkItem
    from factory.policy.obs_spec import ObsSpec
    from factory.policy.vector_env import PickPlaceVecEnv, task_sim
    from factory.tasks import get_task
    from factory.tasks.articulated.execute import env_state
    from factory.tasks.articulated.plan import OPEN_AT

    scene = _scene("open", tmp_path, fps=5.0, width=32, height=32)
    env, sid = scene.env, scene.scene_id
    assert episode_slot(env, sid, 0).rec is None  # planned only: the GPU simulates
    (out,) = run_gpu(env, [WorkItem(sid, (0, 1))], 1, device="cpu")
    assert out["error"] is None and out["new"] == 2, dict(out["failures"])
    physics = out["physics_seconds"]
    assert physics["calls"] == 1 and physics["worlds"] == 2 and physics["record"] > 0
    store = EpisodeStore(Path(env.store_path))
    setup, data = scene.setup, mujoco.MjData(scene.setup.model)
    task = get_task("open")
    spec = ObsSpec(fps=5.0, cameras=(), env_state=True, task="open")
    vec = PickPlaceVecEnv(task_sim(task, setup, scene.planner, 1, spec, nthread=1), 400)
    for eid in store.episode_ids():
        info, g = store.info(eid), store.arrays(eid)
        n = info.n_frames
        assert info.success and info.recorder == "warp" and info.target_id == "drawer"
        assert g["rgb/wrist"].shape == (n, 32, 32, 3) and np.asarray(g["rgb/left"]).std() > 5
        stored = np.asarray(g["env_state"][:])
        assert stored[-1, 1] >= OPEN_AT and info.outcome["opened"] >= OPEN_AT
        assert stored[-1, 0] == pytest.approx(info.outcome["joint"], abs=1e-4)
        reach = np.linalg.norm(stored[:, 8:11], axis=1)
        assert reach[0] > 0.1 and reach.min() < 0.03
        states = np.asarray(g["state"][:])
        for f in (0, n // 2, n - 1):
            mujoco.mj_setState(setup.model, data, states[f], STATE_SPEC)
            mujoco.mj_kinematics(setup.model, data)
            np.testing.assert_allclose(env_state(setup, data), stored[f], atol=1e-5)
        # the stored actions replayed in the evaluation env (eval.policy=replay)
        vec.reset(seeds=[info.seed])
        actions = np.asarray(g["action"][:])
        done = False
        for a in [*actions, *[actions[-1]] * 20]:
            _, _, terminated, truncated, step_info = vec.step(a[None])
            if terminated[0] or truncated[0]:
                done = True
                break
        assert done and step_info["success"][0], step_info


def test_an_unknown_episode_physics_names_the_choices() -> None:
    from factory.config import DemosConfig
    from factory.demos.stage import check_config
    from factory.errors import ConfigError

    with pytest.raises(ConfigError, match="episode_physics='gpu' is unknown: choose one of auto"):
        check_config(DemosConfig(episode_physics="gpu"), "open")
    check_config(DemosConfig(episode_physics="cpu"), "open")
