"""The env of the mobile task (``factory.tasks.mobile_pick_place.env.MobileSim``) against a
recorded mobile demo of the hand-built living room: it starts where the demos' planner starts,
observes what the recording recorded (state, tool pose, the five cameras' images), replays the
recorded actions to success with the recorded sub-task switches, and names its failures."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from robot_models import require_robot_models

require_robot_models()
for _mod in ("ruckig", "ompl", "mink"):
    pytest.importorskip(_mod)

from factory.policy.obs_spec import ObsSpec
from factory.policy.vector_env import PickPlaceVecEnv
from factory.tasks.mobile_pick_place import (
    ALL_CAMERAS,
    MobileEpisodePlan,
    MobilePlanner,
    MobileRecordConfig,
    execute_mobile,
    mobile_setup,
    render_frames,
)
from factory.tasks.mobile_pick_place.env import MobileSim

FPS = 10.0
TASK = "mobile_pick_place"
HERE = Path(__file__).resolve().parent


def _helpers() -> ModuleType:
    """The living room of the demos' mobile tests (test folders are not packages)."""
    spec = importlib.util.spec_from_file_location(
        "_mobile_helpers", HERE.parent / "demos" / "test_mobile_pick_place.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def demo() -> dict[str, Any]:
    """The living room set up as the demos set it up, its planner, and episode 0 planned and
    executed at 10 fps (no images)."""
    setup = mobile_setup(_helpers()._living_room())
    planner = MobilePlanner(setup)
    plan = planner.plan_episode(0)
    assert isinstance(plan, MobileEpisodePlan), plan
    rec = execute_mobile(setup, plan, MobileRecordConfig(fps=FPS, render=False))
    assert rec.outcome is not None and rec.outcome.success, rec.outcome
    return {"setup": setup, "planner": planner, "plan": plan, "rec": rec}


def _env(demo: dict[str, Any], spec: ObsSpec | None = None) -> PickPlaceVecEnv:
    spec = spec or ObsSpec(fps=FPS, cameras=(), task=TASK)
    return PickPlaceVecEnv(MobileSim(demo["setup"], demo["planner"], 1, spec))


def _recorded_state(rec: Any, f: int) -> np.ndarray:
    return np.concatenate([rec.joint_pos[f], rec.gripper[f], rec.base_pose[f]])


def test_reset_is_the_demos_spawn_and_observes_as_recorded(demo: dict[str, Any]) -> None:
    """Seed s starts where the planner's episode s starts; the first observation is the
    recording's first frame (state 11, tool pose 7, sub-task 0)."""
    env = _env(demo)
    rec, plan = demo["rec"], demo["plan"]
    assert np.array_equal(env.sample_qpos(0), plan.qpos0)
    for obs in (env.reset(seeds=[0])[0], env.reset(states=rec.state[:1])[0]):
        assert obs["observation.state"].shape == (1, 11)
        assert np.allclose(obs["observation.state"][0], _recorded_state(rec, 0), atol=1e-6)
        assert np.allclose(obs["observation.ee_pose"][0], rec.ee_pose[0], atol=1e-6)
        assert obs["subtask_index"].tolist() == [[0]]
    assert set(env.spec.keys()) == {"observation.state", "observation.ee_pose", "subtask_index"}


def test_environment_state_is_observed_as_recorded(demo: dict[str, Any]) -> None:
    """Asked for (``ObsSpec.env_state``), the env observes ``observation.environment_state``
    (14: the pick object's and the place support's world poses) as the demo recorded it, at
    the first frame and along a replay of the recorded actions."""
    env = _env(demo, spec=ObsSpec(fps=FPS, cameras=(), env_state=True, task=TASK))
    rec = demo["rec"]
    assert env.spec.shapes()["observation.environment_state"] == ((14,), "float32")
    obs, _ = env.reset(states=rec.state[:1])
    assert np.allclose(obs["observation.environment_state"][0], rec.env_state[0], atol=1e-6)
    for f in range(1, 6):
        obs, *_ = env.step(rec.action[f - 1][None].astype(np.float32))
        # the replay tracks the recording to millimetres (the controller, not the poses)
        assert np.allclose(obs["observation.environment_state"][0], rec.env_state[f], atol=5e-3)


def test_images_are_the_recordings(demo: dict[str, Any]) -> None:
    """The five cameras (two fisheye) through the recording's renderer: the same images and
    depth as ``render_frames`` draws for the same state."""
    spec = ObsSpec(fps=FPS, cameras=ALL_CAMERAS, width=16, height=12, task=TASK)
    env = _env(demo, spec=spec)
    rec = demo["rec"]
    obs, _ = env.reset(states=rec.state[:1])
    first = replace(rec, state=rec.state[:1], rgb={}, depth={})
    render_frames(demo["setup"], first, MobileRecordConfig(fps=FPS, width=16, height=12))
    for cam in ALL_CAMERAS:
        side = (16, 16) if cam.startswith("fisheye") else (12, 16)
        assert obs[f"observation.images.{cam}"].shape == (1, *side, 3)
        assert np.array_equal(obs[f"observation.images.{cam}"][0], first.rgb[cam][0]), cam
        assert np.array_equal(obs[f"observation.depth.{cam}"][0], first.depth[cam][0]), cam
    assert env.render(0).shape == (16, 5 * 16, 3)
    env.close()


def test_replay_of_the_recorded_actions_succeeds(demo: dict[str, Any]) -> None:
    """Open-loop replay: the recorded actions from the recorded first state reach success, the
    arm and base track the recording, and the env's sub-task switches (its own checks) fall
    within two frames of the recorded labels'."""
    env = _env(demo)
    rec = demo["rec"]
    n = len(rec.time)
    obs, _ = env.reset(states=rec.state[:1], max_steps=[n + 20])
    labels, states = [0], [obs["observation.state"][0]]
    actions = rec.action[:-1].astype(np.float32)
    while not env.done[0]:
        f = min(int(env.steps[0]), len(actions) - 1)
        obs, _, terminated, truncated, _ = env.step(actions[f][None])
        labels.append(int(obs["subtask_index"][0, 0]))
        states.append(obs["observation.state"][0])
    result = env.result(0)
    assert result["success"], result
    assert terminated[0] and not truncated[0]
    assert result["record"] == {"subtask": "place", "subtasks_done": 4}
    m = min(len(labels), n)
    recorded_switches = [int(np.flatnonzero(rec.subtask == k)[0]) for k in (1, 2, 3)]
    assert np.abs(np.array(result["switches"]) - recorded_switches).max() <= 2, (
        result["switches"],
        recorded_switches,
    )
    assert np.mean(np.array(labels[:m]) == rec.subtask[:m]) > 0.97
    got = np.array(states[:m])
    want = np.stack([_recorded_state(rec, f) for f in range(m)])
    assert np.abs(got[:, :7] - want[:, :7]).max() < 0.02  # arm joints (rad)
    assert np.abs(got[:, 8:10] - want[:, 8:10]).max() < 0.005  # base position (m)


def test_jittery_commands_switch_when_the_next_subtask_begins(demo: dict[str, Any]) -> None:
    """A policy's commands never stand as still as a plan's: the recorded actions with a
    jitter of a few millimetres and milliradians on every frame (the base and arm commands
    never still) still switch sub-tasks when the next one begins as in the demos (the hand
    opens at the object, the base drives off with the object in the carry posture, the arm
    leaves the carry posture at the desk), within three frames of the labels, and succeed."""
    env = _env(demo)
    rec = demo["rec"]
    n = len(rec.time)
    rng = np.random.default_rng(0)
    actions = rec.action[:-1].astype(np.float64)
    actions[:, :7] += rng.uniform(-0.003, 0.003, (len(actions), 7))
    actions[:, 8:] += rng.uniform(-0.003, 0.003, (len(actions), 3))
    env.reset(states=rec.state[:1], max_steps=[n + 20])
    while not env.done[0]:
        env.step(actions[min(int(env.steps[0]), len(actions) - 1)][None].astype(np.float32))
    result = env.result(0)
    assert result["success"], result
    recorded_switches = [int(np.flatnonzero(rec.subtask == k)[0]) for k in (1, 2, 3)]
    assert np.abs(np.array(result["switches"]) - recorded_switches).max() <= 3, (
        result["switches"],
        recorded_switches,
    )


def test_failures_are_named(demo: dict[str, Any]) -> None:
    """Standing still at the spawn ends as ``nav_timeout``; opening the hand while carrying
    as ``drop``; the base deep in the desk as ``base_collision`` (against a wall the base's
    actuators press it 4 mm deep at most: a stuck base ends as ``nav_timeout``)."""
    env = _env(demo)
    rec = demo["rec"]
    env.reset(seeds=[0], max_steps=[12])
    still = env.last_actions[:1].astype(np.float32)
    while not env.done[0]:
        env.step(still)
    r = env.result(0)
    assert (r["reason"], r["record"]["subtasks_done"]) == ("nav_timeout", 0)

    actions = rec.action[:-1].astype(np.float32).copy()
    carry = int(np.flatnonzero(rec.subtask == 2)[0])
    actions[carry + 5 :, 7] = 0.08  # the hand opens on the way to the desk
    env.reset(states=rec.state[:1], max_steps=[len(actions)])
    while not env.done[0]:
        env.step(actions[min(int(env.steps[0]), len(actions) - 1)][None])
    r = env.result(0)
    assert (r["reason"], r["record"]["subtasks_done"]) == ("drop", 2), r

    qpos = env.sample_qpos(0)
    robot = demo["setup"].robot
    qpos[robot.base_qpos[:2]] = (4.6, 1.75)  # the base (facing +y) 10 cm into the desk
    env.reset(qpos=qpos[None], max_steps=[5])
    hold = env.last_actions[:1].astype(np.float32)
    while not env.done[0]:
        env.step(hold)
    r = env.result(0)
    assert r["reason"] == "base_collision" and r["steps"] == 1, r
