"""LeRobot's own env factory and evaluation loop drive a factory scene (``--env.type=factory``)."""

from __future__ import annotations

from pathlib import Path

import pytest
from robot_models import require_robot_models

require_robot_models()
pytest.importorskip("lerobot")


def lerobot_eval(run: Path, model: Path, out_dir: Path, scene: str, *flags: str) -> dict:
    """Runs lerobot's own ``lerobot-eval`` on the factory env (2 episodes of 5 frames, on the
    CPU) with extra ``flags``; returns its ``eval_info.json``."""
    import json
    import os
    import subprocess
    import sys

    res = subprocess.run(
        [
            str(Path(sys.executable).parent / "lerobot-eval"),
            "--env.discover_packages_path=factory.policy.lerobot_plugin",
            "--env.type=factory",
            f"--env.run_dir={run}",
            f"--env.scene={scene}",
            "--env.episode_length=5",
            *flags,
            f"--policy.path={model}",
            "--policy.device=cpu",
            "--eval.n_episodes=2",
            "--eval.batch_size=2",
            f"--output_dir={out_dir}",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    info: dict = json.loads((out_dir / "eval_info.json").read_text())
    return info


def test_lerobot_make_env_and_eval_policy(policy_run: Path, tmp_path: Path) -> None:
    import torch
    from lerobot.envs.configs import EnvConfig
    from lerobot.envs.factory import make_env, make_env_pre_post_processors
    from lerobot.envs.utils import env_to_policy_features
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.pretrained import PreTrainedPolicy
    from lerobot.processor.converters import (
        policy_action_to_transition,
        transition_to_policy_action,
    )
    from lerobot.processor.pipeline import PolicyProcessorPipeline
    from lerobot.scripts.lerobot_eval import eval_policy

    import factory.policy.lerobot_plugin as plugin

    # what lerobot-eval's --env.type=factory resolves to once the plugin is imported
    cls = EnvConfig.get_choice_class("factory")
    assert cls is plugin.FactoryEnv
    cfg = cls(run_dir=str(policy_run), scene="kitchen_a", env_state=True, episode_length=4)
    feats = env_to_policy_features(cfg)
    assert feats["observation.state"].shape == (8,)
    assert feats["observation.environment_state"].shape == (14,)
    assert feats["observation.images.left"].shape == (3, 32, 32)  # the dataset's cameras
    assert feats["observation.images.wrist"].shape == (3, 32, 32)

    class HoldPolicy(PreTrainedPolicy):
        """Holds the arm where it is with the hand open: a trivial LeRobot policy."""

        config_class = ACTConfig
        name = "factory_test_hold"

        def __init__(self, config: ACTConfig) -> None:
            super().__init__(config)
            self.seen: set[str] = set()

        def get_optim_params(self) -> dict:
            return {}

        def reset(self) -> None:
            pass

        def forward(self, batch: dict) -> tuple:
            raise NotImplementedError

        def predict_action_chunk(self, batch: dict) -> torch.Tensor:
            return self.select_action(batch)[:, None]

        def select_action(self, batch: dict) -> torch.Tensor:
            self.seen |= set(batch)
            return batch["observation.state"].clone()

    envs = make_env(cfg, n_envs=2)
    vec = envs["factory"][0]
    try:
        policy = HoldPolicy(ACTConfig(device="cpu"))
        env_pre, env_post = make_env_pre_post_processors(cfg, policy.config)
        pre = PolicyProcessorPipeline(steps=[])
        post = PolicyProcessorPipeline(
            steps=[],
            to_transition=policy_action_to_transition,
            to_output=transition_to_policy_action,
        )
        info = eval_policy(
            vec,
            policy,
            env_pre,
            env_post,
            pre,
            post,
            n_episodes=2,
            max_episodes_rendered=1,
            videos_dir=tmp_path / "videos",
            start_seed=2**32,
        )
    finally:
        vec.close()
    assert {
        "observation.state",
        "observation.environment_state",
        "observation.images.left",
        "observation.images.wrist",
        "task",
    } <= policy.seen
    # holding still never lifts the mug: both episodes time out without success
    assert info["aggregated"]["pc_success"] == 0.0
    assert len(info["per_episode"]) == 2
    assert list((tmp_path / "videos").glob("*.mp4"))


def test_one_gym_id_per_task() -> None:
    """Every registered task has its gym id (today's ``factory/PickPlace-v0`` the default
    task's), picked by ``--env.task``; the features follow the task's env."""
    import gymnasium as gym

    import factory.policy.lerobot_plugin as plugin
    from factory.tasks import DEFAULT_TASK, TASKS

    assert sorted(plugin.GYM_IDS.values()) == sorted(TASKS)
    assert plugin.GYM_IDS[plugin.GYM_ID] == DEFAULT_TASK == "pick_place"
    assert plugin.GYM_ID == "factory/PickPlace-v0"
    assert all(i in gym.registry for i in plugin.GYM_IDS)
    cfg = plugin.FactoryEnv(task="MobilePickPlace-v0", observation_width=16)
    assert cfg.gym_id == "factory/MobilePickPlace-v0"
    assert cfg.gym_kwargs["task"] == "mobile_pick_place"
    assert cfg.features["agent_pos"].shape == (11,) and cfg.features["action"].shape == (11,)
    assert cfg.features["pixels/fisheye_front"].shape == (16, 16, 3)
    assert "environment_state" not in cfg.features
    with pytest.raises(ValueError, match="choose one of PickPlace-v0, MobilePickPlace-v0"):
        plugin.FactoryEnv(task="Push-v0")


@pytest.mark.slow
def test_lerobot_eval_command(policy_run: Path, tmp_path: Path) -> None:
    """The documented ``lerobot-eval --env.type=factory`` command with a saved LeRobot policy
    (ACT from the dataset's statistics, untrained: it only has to run)."""
    import torch
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    import factory.policy.lerobot_plugin as plugin

    torch.manual_seed(0)
    env_cfg = plugin.FactoryEnv(run_dir=str(policy_run), obs_type="agent_pos", env_state=True)
    cfg = ACTConfig(device="cpu", pretrained_backbone_weights=None)
    policy = make_policy(cfg, env_cfg=env_cfg)
    stats = LeRobotDatasetMetadata("x", root=policy_run / "dataset" / "merged").stats
    pre, post = make_pre_post_processors(cfg, dataset_stats=stats)
    model = tmp_path / "pretrained_model"
    for part in (policy, pre, post):
        part.save_pretrained(model)
    info = lerobot_eval(
        policy_run,
        model,
        tmp_path / "out",
        "kitchen_a",
        "--env.obs_type=agent_pos",
        "--env.env_state=true",
    )
    assert info["overall"]["n_episodes"] == 2


def test_policy_path_is_read_in_both_spellings() -> None:
    import factory.policy.lerobot_plugin as plugin

    argv = ["--env.type=factory", "--policy.path=a/b", "--policy.path", "c", "--policy.device=cpu"]
    assert plugin.policy_paths(argv) == ["a/b", "c"]
    assert plugin.policy_paths(["--policy.path"]) == []


@pytest.mark.slow
def test_lerobot_eval_runs_the_default_trained_policy(
    policy_run: Path, tmp_path: Path, pcli
) -> None:
    """The policy ``stage=train`` makes by default (diffusion, ``train.inputs=state``,
    ``train.action=tool``: model inputs computed from the raw state, tool-pose actions) runs
    under lerobot's own ``lerobot-eval`` with only the documented flags: the env reads the
    factory policy from ``--policy.path`` and observes and acts as ``stage=eval`` does."""
    import json
    import shutil

    import numpy as np

    import factory.policy.lerobot_plugin as plugin

    out = pcli(
        "stage=train",
        f"run_dir={policy_run}",
        "train.name=lerobot_default",
        "train.steps=2",
        "train.batch_size=2",
        "train.device=cpu",
        "train.options={diffusion: {down_dims: [16, 32], diffusion_step_embed_dim: 16}}",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    model = policy_run / "policy" / "lerobot_default" / "checkpoints" / "last" / "pretrained_model"
    info = json.loads((model / "factory_policy.json").read_text())
    assert (info["inputs"], info["action"]) == ("state", "tool")
    result = lerobot_eval(policy_run, model, tmp_path / "out", "kitchen_b")
    assert result["overall"]["n_episodes"] == 2
    # the env speaks the model's language: 17-D state, 24-D environment state, 10-D tool action
    cfg = plugin.FactoryEnv(run_dir=str(policy_run), scene="kitchen_b", policy="lerobot_default")
    shapes = {k: f.shape for k, f in cfg.features.items()}
    assert shapes == {"action": (10,), "agent_pos": (17,), "environment_state": (24,)}
    env = plugin.LeRobotPickPlaceEnv(**cfg.gym_kwargs)
    obs, _ = env.reset(seed=0)
    assert obs["agent_pos"].shape == (17,) and obs["environment_state"].shape == (24,)
    # the tool pose it starts at, held: the arm stays where it is
    joints = env._state.copy()
    obs, *_ = env.step(np.concatenate([obs["agent_pos"][8:17], [0.08]]).astype(np.float32))
    assert np.abs(env._state[:7] - joints[:7]).max() < 0.05
    env.close()
    # a policy lerobot-eval cannot serve is refused in one line naming stage=eval
    rel = tmp_path / "rel"
    shutil.copytree(model, rel)
    (rel / "factory_policy.json").write_text(json.dumps({**info, "action": "tool_rel"}))
    with pytest.raises(ValueError, match="evaluate it with python -m factory stage=eval"):
        plugin.FactoryEnv(run_dir=str(policy_run), policy=str(rel))
    with pytest.raises(ValueError, match=r"env\.policy: no policy 'nope'"):
        plugin.FactoryEnv(run_dir=str(policy_run), policy="nope")
