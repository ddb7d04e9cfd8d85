"""The simulation env: observations, seeds, the batched form, replay of recorded episodes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from robot_models import require_robot_models

require_robot_models()
pytest.importorskip("gymnasium")

from factory.config import DemosConfig
from factory.demos.record.episodes import EpisodeStore
from factory.demos.record.slots import episode_seed
from factory.policy.env import EVAL_SEED_OFFSET, PickPlaceEnv, eval_seed, make_vec_env
from factory.policy.eval import Job, plan_actions, run_batch, scripted_actor
from factory.policy.obs_spec import ObsSpec, obs_spec_of_dataset
from factory.schema.errors import PolicyError


def _store(run: Path) -> EpisodeStore:
    (path,) = sorted((run / "episodes").glob("shard-*.zarr"))
    return EpisodeStore(path)


def _seed_that_places(env: PickPlaceEnv, scene: str, start: int = 0) -> int:
    from factory.errors import TaskError

    for k in range(start, start + 50):
        seed = eval_seed(0, scene, k)
        try:
            env.vec.sample_qpos(seed)
            return seed
        except TaskError:
            continue
    raise AssertionError("no evaluation seed places the objects")


def test_reset_step_keys_shapes_and_spaces(policy_run: Path) -> None:
    env = PickPlaceEnv(policy_run, "kitchen_a", env_state=True, max_steps=3)
    try:
        assert env.vec.spec.cameras == ("left", "wrist")  # the demos' recording settings
        obs, info = env.reset(seed=_seed_that_places(env, "kitchen_a"))
        expect = {
            "observation.state": ((8,), np.float32),
            "observation.ee_pose": ((7,), np.float32),
            "observation.environment_state": ((14,), np.float32),
            "observation.camera_poses": ((13,), np.float32),  # the left camera's calibration
            "observation.images.left": ((32, 32, 3), np.uint8),
            "observation.images.wrist": ((32, 32, 3), np.uint8),
            "observation.depth.left": ((32, 32), np.uint16),
            "observation.depth.wrist": ((32, 32), np.uint16),
        }
        assert {k: (v.shape, v.dtype) for k, v in obs.items()} == expect
        assert env.observation_space.contains(obs)
        assert info["seed"] >= EVAL_SEED_OFFSET and info["reason"] == "" and not info["is_success"]
        # the hand is open at home; depth in millimetres sees the table within a few metres
        assert abs(obs["observation.state"][7] - 0.08) < 1e-3
        assert 200 < np.median(obs["observation.depth.left"]) < 5000
        # the environment state is the two objects' poses (unit quaternions, world frame)
        es = obs["observation.environment_state"]
        assert np.allclose(np.linalg.norm(es[3:7]), 1) and np.allclose(np.linalg.norm(es[10:]), 1)
        # the left camera where the scene placed it: within the appearance jitter (1 cm) of
        # where the recorded episodes of this kitchen had it, the same field of view
        import pyarrow.parquet as pq

        data = sorted((policy_run / "dataset" / "merged" / "data").glob("*/*.parquet"))[0]
        recorded = np.asarray(pq.read_table(data).column("observation.camera_poses")[0].as_py())
        calib = obs["observation.camera_poses"]
        assert np.abs(calib[:3] - recorded[:3]).max() <= 0.01 + 1e-6
        assert np.abs(calib[3:12] - recorded[3:12]).max() < 0.05 and calib[12] == recorded[12]
        hold = obs["observation.state"].copy()
        for k in range(3):
            obs, reward, term, trunc, info = env.step(hold)
            assert info["steps"] == k + 1
        # nothing happened: a time-out with the success check's reason (never lifted)
        assert trunc and not term and reward == 0.0 and info["reason"] == "slip"
        assert env.render().shape == (32, 96, 3)
        assert env.task and env.action_space.contains(hold)
    finally:
        env.close()


def test_seeds_disjoint_from_demos_and_same_sampler(policy_run: Path) -> None:
    """Evaluation seeds live above 2**32, the demos' below; seed s gives the configuration
    the demos' planner starts from with seed s."""
    demos = [episode_seed(r, "kitchen_a", k, a) for r in (0, 7) for k in range(50) for a in (0, 1)]
    evals = [eval_seed(r, "kitchen_a", k) for r in (0, 7) for k in range(50)]
    assert max(demos) < EVAL_SEED_OFFSET <= min(evals) and len(set(evals)) == len(evals)
    for info in _store(policy_run):
        assert info.seed < EVAL_SEED_OFFSET
    vec, planner = make_vec_env(policy_run, "kitchen_a", 1, ObsSpec(cameras=()))
    try:
        seed = eval_seed(0, "kitchen_a", 0)
        for k in range(20):
            plan = planner.plan_episode(seed + k)
            if hasattr(plan, "qpos0"):
                assert np.array_equal(vec.sample_qpos(seed + k), plan.qpos0)
                break
        else:
            pytest.fail("no seed planned")
    finally:
        vec.close()


def test_vector_env_equals_single_envs(policy_run: Path) -> None:
    spec = ObsSpec(cameras=("wrist",), width=32, height=32, env_state=True)
    vec, _ = make_vec_env(policy_run, "kitchen_a", 2, spec, max_steps=6, nthread=2)
    try:
        seeds = []
        k = 0
        while len(seeds) < 2:
            try:
                vec.sample_qpos(eval_seed(3, "kitchen_a", k))
                seeds.append(eval_seed(3, "kitchen_a", k))
            except Exception:
                pass
            k += 1
        rng = np.random.default_rng(0)
        obs, _ = vec.reset(seeds=seeds)
        actions = obs["observation.state"][None] + rng.normal(0, 0.05, (6, 2, 8))
        batched = [obs]
        for a in actions:
            batched.append(vec.step(a.astype(np.float32))[0])
    finally:
        vec.close()
    for i, seed in enumerate(seeds):
        single, _ = make_vec_env(policy_run, "kitchen_a", 1, spec, max_steps=6, nthread=1)
        env = PickPlaceEnv(vec=single)
        try:
            obs, info = env.reset(seed=seed)
            assert info["seed"] == seed
            steps = [obs] + [env.step(a[i].astype(np.float32))[0] for a in actions]
            for b, s in zip(batched, steps, strict=True):
                for key in s:
                    assert np.array_equal(b[key][i], s[key]), key
        finally:
            env.close()


def test_replay_of_recorded_episodes(policy_run: Path) -> None:
    """The recorded actions from the recorded initial state succeed in the env, tracking the
    recorded joints within a few mrad (the controller and frame timing agree)."""
    store = _store(policy_run)
    ids = store.episode_ids()
    vec, _ = make_vec_env(policy_run, "kitchen_a", len(ids), ObsSpec(cameras=()), nthread=2)
    try:
        jobs, joints = [], []
        for eid in ids:
            g = store.arrays(eid)
            info = store.info(eid)
            jobs.append(
                Job(
                    scene="kitchen_a",
                    seed=info.seed,
                    episode_id=eid,
                    state=g["state"][0],
                    actions=np.asarray(g["action"][:-1], np.float32),
                    max_steps=info.n_frames - 1,
                )
            )
            joints.append(g["joint_pos"][:])
        seen: list[np.ndarray] = []  # the observation each step acts on
        base = scripted_actor(jobs)

        def actor(obs, steps):
            seen.append(obs["observation.state"])
            return base(obs, steps)

        records, _ = run_batch(vec, jobs, actor)
        # states of another set-up of the scene (a different model) are a clear error
        with pytest.raises(PolicyError, match="stage=demos force=true"):
            vec.reset(states=np.stack([j.state[:-3] for j in jobs]))
    finally:
        vec.close()
    assert [r["success"] for r in records] == [True] * len(ids), records
    # joints at the frames both ran through (an episode may succeed before its last frame)
    worst = 0.0
    for i, q in enumerate(joints):
        n = records[i]["steps"]
        got = np.stack([s[i, :7] for s in seen[:n]])
        worst = max(worst, float(np.abs(got - q[:n]).max()))
    assert worst < 0.005, worst


def test_plan_actions_are_the_recorded_ones() -> None:
    """Planner actions per frame are the targets at each frame's end, as the demos record."""
    targets = np.arange(60 * 8, dtype=float).reshape(60, 8)
    a = plan_actions(targets, 25)
    assert a.shape == (3, 8)
    assert np.array_equal(a[:, 0], targets[[24, 49, 59], 0])


def test_obs_spec_of_datasets_with_and_without_environment_state(
    policy_run: Path, tmp_path: Path
) -> None:
    merged = policy_run / "dataset" / "merged"
    spec = obs_spec_of_dataset(merged)
    assert spec.cameras == ("left", "wrist") and spec.depth and spec.env_state
    assert (spec.width, spec.height, spec.fps) == (32, 32, 20.0)
    # a dataset exported before the feature existed: the env simply does not observe it
    old = tmp_path / "old"
    (old / "meta").mkdir(parents=True)
    info = json.loads((merged / "meta" / "info.json").read_text())
    del info["features"]["observation.environment_state"]
    del info["features"]["observation.camera_poses"]
    (old / "meta" / "info.json").write_text(json.dumps(info))
    assert obs_spec_of_dataset(old).env_state is False
    assert spec.pose_cameras == ("left",) and obs_spec_of_dataset(old).pose_cameras == ()
    assert obs_spec_of_dataset(old, env_state=True).env_state is True
    assert DemosConfig().fps == spec.fps


def test_gymnasium_vector_env_autoresets(policy_run: Path) -> None:
    from factory.policy.env import PickPlaceVectorEnv

    vec, _ = make_vec_env(policy_run, "kitchen_a", 2, ObsSpec(cameras=()), max_steps=2)
    env = PickPlaceVectorEnv(vec)
    try:
        obs, infos = env.reset(seed=1)
        assert obs["observation.state"].shape == (2, 8) and env.observation_space.contains(obs)
        assert all(s >= EVAL_SEED_OFFSET for s in infos["seed"])
        first = infos["seed"].copy()
        hold = obs["observation.state"]
        obs, reward, term, trunc, infos = env.step(hold)
        assert not (term | trunc).any() and list(infos["steps"]) == [1, 1]
        obs, reward, term, trunc, infos = env.step(hold)
        assert trunc.all() and not term.any() and reward.sum() == 0
        assert list(infos["final_info"]["is_success"]) == [False, False]
        assert list(infos["final_info"]["reason"]) == ["slip", "slip"]
        assert infos["final_obs"][0]["observation.state"].shape == (8,)
        # restarted in new configurations (SAME_STEP autoreset)
        assert list(vec.steps) == [0, 0] and not vec.done.any()
        assert [vec.result(i)["seed"] for i in range(2)] != list(first)
    finally:
        env.close()
