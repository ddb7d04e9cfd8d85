"""LeRobot plugin: factory scenes as a LeRobot env (``--env.type=factory``).

Importing this package registers :class:`FactoryEnv` with LeRobot's ``EnvConfig`` choices
(``factory``) and one gymnasium id per registered task (:data:`GYM_IDS`:
``factory/PickPlace-v0``, ``factory/MobilePickPlace-v0``; ``--env.task=MobilePickPlace-v0``
picks one, the default task's by default), so LeRobot's own evaluation entry point runs any
LeRobot policy in a scene of a factory run::

    lerobot-eval --env.discover_packages_path=factory.policy.lerobot_plugin \\
        --env.type=factory --env.run_dir=runs/small --env.scene=<scene_id> \\
        --policy.path=runs/small/policy/<name>/checkpoints/last/pretrained_model \\
        --eval.n_episodes=10 --eval.batch_size=2 --policy.device=cpu

(``--env.discover_packages_path`` is lerobot's plugin switch: it imports this package before
the command line is parsed.) Observations follow LeRobot's raw env convention, which
``lerobot.envs.utils.preprocess_observation`` turns into the dataset's keys: ``agent_pos`` ->
``observation.state``, ``environment_state`` -> ``observation.environment_state``,
``pixels/<cam>`` -> ``observation.images.<cam>`` (a task's other observations, such as the
mobile task's ``subtask_index`` and the fixed-base task's ``observation.camera_poses``, have no
LeRobot key and are left out; the perception policies that read the latter are refused, below).
LeRobot's env pipeline has no depth input, so depth policies are evaluated with ``stage=eval``
instead.
``info["is_success"]`` is the demos' success check. LeRobot's seed ``s`` (``--seed`` plus the
episode number) becomes the evaluation seed ``2**32 + s`` of the demos' sampler, disjoint from
the demos' own seeds.

A policy trained by ``stage=train`` (its ``pretrained_model`` holds ``factory_policy.json``)
reads the model's inputs (the tool pose and the tool-to-object offsets computed from the raw
state) and, by default (``train.action=tool``), predicts tool poses: the env speaks that policy's
language (:class:`PolicyAdapter`) when ``--env.policy`` names it (a policy name of the run or a
path) or, by default, when lerobot-eval's own ``--policy.path`` is such a folder. Its
observations are then the model's (``agent_pos`` = the model's ``observation.state``,
``environment_state`` = the model's), converted as ``stage=eval`` converts them
(:func:`factory.policy.inputs.convert_observation`), and its actions the model's, turned into
joint targets by ``stage=eval``'s IK tracker (:class:`factory.policy.inputs.ToolActionTracker`).
Policies whose actions are relative to the state at each chunk's start (``train.action=tool_rel``
and the mobile task's base targets) or that read depth cannot be given what they need through
LeRobot's env interface: the env refuses them in one line that names ``stage=eval``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig

from factory.tasks import DEFAULT_TASK, get_task, task_names

if TYPE_CHECKING:
    from factory.policy.inputs import InputSpec

STATE = "observation.state"
ENV_STATE = "observation.environment_state"
GYM_NAMESPACE = "factory"


def gym_name(task: str) -> str:
    """The gymnasium name of a registered task: ``pick_place`` -> ``PickPlace-v0``."""
    return "".join(part.capitalize() for part in task.split("_")) + "-v0"


GYM_IDS: dict[str, str] = {f"{GYM_NAMESPACE}/{gym_name(t)}": t for t in task_names()}
"""Gymnasium id -> registered task."""
GYM_ID = f"{GYM_NAMESPACE}/{gym_name(DEFAULT_TASK)}"
"""The default task's id (``factory/PickPlace-v0``)."""
POLICY_FLAG = "--policy.path"
"""lerobot-eval's policy option: a factory policy there sets the env's inputs and actions."""


def policy_paths(argv: list[str]) -> list[str]:
    """The values of lerobot-eval's ``--policy.path`` in ``argv`` (``--policy.path=P`` or
    ``--policy.path P``)."""
    out = []
    for i, arg in enumerate(argv):
        if arg.startswith(POLICY_FLAG + "="):
            out.append(arg[len(POLICY_FLAG) + 1 :])
        elif arg == POLICY_FLAG and i + 1 < len(argv):
            out.append(argv[i + 1])
    return out


def factory_policy(ref: str | None, run_dir: str) -> Path | None:
    """The ``pretrained_model`` folder of a policy trained by ``stage=train`` that the env
    should serve, or None (a LeRobot policy on the dataset's raw features).

    Args:
        ref: ``--env.policy``: a policy name of the run or a path
            (:func:`factory.policy.checkpoint.resolve_ref`); None: lerobot-eval's
            ``--policy.path`` when that folder holds ``factory_policy.json``.
        run_dir: the run directory.

    Raises:
        ValueError: ``ref`` names no loadable policy, or one not trained by the factory.
    """
    from factory.errors import PolicyError
    from factory.policy.checkpoint import INFO_IN_MODEL, resolve_ref

    if ref is None:
        given = policy_paths(sys.argv[1:])
        found = [Path(g) for g in given if (Path(g) / INFO_IN_MODEL).is_file()]
        return found[-1] if found else None
    try:
        path = resolve_ref(ref, Path(run_dir) if run_dir else None)
    except PolicyError as err:
        raise ValueError(f"env.policy: {err}") from None
    if not (path / INFO_IN_MODEL).is_file():
        raise ValueError(
            f"env.policy={ref!r}: {path} has no {INFO_IN_MODEL} (not trained by stage=train); "
            "leave env.policy unset for a LeRobot policy on the dataset's features"
        )
    return path


class PolicyAdapter:
    """What a factory-trained policy reads and predicts, in LeRobot's env terms: the model's
    observations from the env's raw ones, and the env's joint targets from its actions.

    Args:
        path: the policy's ``pretrained_model`` folder (with ``factory_policy.json``).

    Raises:
        ValueError: a policy that LeRobot's env interface cannot serve (names ``stage=eval``).
    """

    def __init__(self, path: Path) -> None:
        from factory.policy.checkpoint import INFO_IN_MODEL, read_info
        from factory.policy.inputs import spec_from_features

        info = read_info(path / INFO_IN_MODEL)
        self.path = path
        self.spec: InputSpec = spec_from_features(
            info.inputs, info.features, info.depth_max_m, info.action
        )
        why = ""
        if self.spec.mobile:
            why = "a mobile policy's base targets are relative to the base at each chunk's start"
        elif self.spec.action == "tool_rel":
            why = "a train.action=tool_rel policy's positions are relative to each chunk's start"
        elif info.vision == "perception":
            why = (
                "a train.vision=perception policy reads the object poses from its perception "
                "network, which lerobot's policy does not hold"
            )
        elif self.spec.depth:
            why = "LeRobot's env pipeline has no depth input (train.inputs=rgbd)"
        if why:
            raise ValueError(
                f"{path}: {why}, which lerobot-eval cannot pass to the env: evaluate it with "
                f"python -m factory stage=eval eval.policy={path}"
            )
        self._tracker: Any = None
        if self.spec.action == "tool":
            from factory.policy.inputs import ToolActionTracker

            self._tracker = ToolActionTracker()

    def shapes(self) -> dict[str, tuple[int, ...]]:
        """The model's vector inputs and action: key -> shape."""
        from factory.policy.inputs import ACTION

        out = {
            k: tuple(v)
            for k, v in self.spec.model_features().items()
            if not k.startswith("observation.images.")
        }
        out[ACTION] = (self.spec.action_dim,)
        return out

    def observe(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The env's raw observation (no batch axis) -> the model's vector inputs (float32)."""
        from factory.policy.inputs import convert_observation

        raw = {k: np.asarray(obs[k])[None] for k in self.spec.raw_features() if k in obs}
        model = convert_observation(self.spec, raw)
        return {k: model[k][0].numpy() for k in self.shapes() if k in model}

    def reset(self) -> None:
        """New episode: the IK tracker forgets its previous command."""
        if self._tracker is not None:
            self._tracker.reset()

    def act(self, action: np.ndarray, state: np.ndarray) -> np.ndarray:
        """The model's action (its :meth:`shapes` ``action``) -> the env's (8,) joint targets
        (rad) + gripper (m), given the env's raw ``observation.state`` (8,)."""
        if self._tracker is None:
            return np.asarray(action, np.float32)
        arm = self._tracker.joints(
            np.asarray(action, np.float32)[None, :10], np.asarray(state)[None]
        )
        return arm[0]


@EnvConfig.register_subclass("factory")
@dataclass
class FactoryEnv(EnvConfig):
    """``--env.type=factory``: a task in a scene of a factory run.

    Attributes:
        task: the gymnasium name of the task (``PickPlace-v0``, ``MobilePickPlace-v0``: one per
            registered task, :data:`GYM_IDS`).
        run_dir: the run directory (``scenes/``, ``dataset/merged``).
        scene: a scene id of the run (default: the run's first scene).
        dataset: the dataset whose fps, cameras and image size the env matches (default:
            ``<run_dir>/dataset/merged`` when it exists, else the demos' settings).
        obs_type: ``pixels_agent_pos`` (cameras + state) or ``agent_pos`` (state only).
        cameras: comma-separated cameras (default: the dataset's).
        env_state: also observe ``environment_state`` (object poses).
        episode_length: frames before an episode times out.
        policy: a policy trained by ``stage=train`` (a policy name of the run or a path) whose
            inputs and actions the env speaks (:class:`PolicyAdapter`); default: lerobot-eval's
            ``--policy.path`` when it is one, else none (the dataset's raw features and joint
            actions).
    """

    task: str | None = gym_name(DEFAULT_TASK)
    fps: int = 20
    run_dir: str = ""
    scene: str | None = None
    dataset: str | None = None
    obs_type: str = "pixels_agent_pos"
    cameras: str | None = None
    env_state: bool = False
    episode_length: int = 400
    policy: str | None = None
    observation_height: int = 128
    observation_width: int = 128
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from factory.policy.env import action_space

        spec = self.obs_spec()
        shapes = spec.shapes()
        self.fps = round(spec.fps)
        self.observation_height, self.observation_width = spec.height, spec.width
        vectors = {"action": action_space(spec.task).shape, STATE: shapes[STATE][0]}
        if ENV_STATE in shapes:
            vectors[ENV_STATE] = shapes[ENV_STATE][0]
        adapter = self.adapter()
        if adapter is not None:  # the model's inputs and action
            vectors = adapter.shapes()
        self.features = {
            "action": PolicyFeature(type=FeatureType.ACTION, shape=vectors["action"]),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=vectors[STATE]),
        }
        self.features_map = {"action": "action", "agent_pos": STATE}
        if ENV_STATE in vectors:
            self.features["environment_state"] = PolicyFeature(
                type=FeatureType.ENV, shape=vectors[ENV_STATE]
            )
            self.features_map["environment_state"] = ENV_STATE
        for cam in spec.cameras:
            key = f"pixels/{cam}"
            self.features[key] = PolicyFeature(
                type=FeatureType.VISUAL, shape=shapes[f"observation.images.{cam}"][0]
            )
            self.features_map[key] = f"observation.images.{cam}"

    def task_name(self) -> str:
        """The registered task of :attr:`task`.

        Raises:
            ValueError: no registered task has that gymnasium name (lists them).
        """
        gym_id = f"{GYM_NAMESPACE}/{self.task}"
        if gym_id not in GYM_IDS:
            names = ", ".join(i.partition("/")[2] for i in GYM_IDS)
            raise ValueError(f"env.task={self.task!r} is not a factory task: choose one of {names}")
        return GYM_IDS[gym_id]

    def adapter(self) -> PolicyAdapter | None:
        """The :class:`PolicyAdapter` of :attr:`policy` (or lerobot-eval's factory policy)."""
        path = factory_policy(self.policy, self.run_dir)
        return None if path is None else PolicyAdapter(path)

    def _dataset(self) -> Path | None:
        if self.dataset:
            return Path(self.dataset)
        merged = Path(self.run_dir) / "dataset" / "merged"
        return merged if self.run_dir and (merged / "meta" / "info.json").is_file() else None

    def obs_spec(self) -> Any:
        """The :class:`~factory.policy.obs_spec.ObsSpec` these settings ask for."""
        from dataclasses import replace

        from factory.policy.env import demos_config_of
        from factory.policy.obs_spec import ObsSpec, obs_spec_of_dataset, obs_spec_of_demos

        task = self.task_name()
        dataset = self._dataset()
        if dataset is not None:
            spec = obs_spec_of_dataset(dataset, self.env_state, task)
        elif self.run_dir and Path(self.run_dir).is_dir():
            spec = obs_spec_of_demos(demos_config_of(self.run_dir), self.env_state, task)
        else:
            spec = ObsSpec(
                cameras=get_task(task).env_cameras(),
                width=self.observation_width,
                height=self.observation_height,
                env_state=self.env_state,
                task=task,
            )
        cams = spec.cameras if self.cameras is None else tuple(self.cameras.split(","))
        if self.obs_type == "agent_pos":
            cams = ()
        elif self.obs_type != "pixels_agent_pos":
            raise ValueError(f"env.obs_type must be pixels_agent_pos or agent_pos: {self.obs_type}")
        adapter = self.adapter()
        if adapter is not None:  # what the policy reads: its cameras, and the raw env state
            return replace(
                spec,
                cameras=adapter.spec.cameras,
                depth=False,
                env_state=ENV_STATE in adapter.spec.raw_features(),
            )
        return replace(spec, cameras=cams, depth=False)

    @property
    def package_name(self) -> str:
        return __name__

    @property
    def gym_id(self) -> str:
        return f"{GYM_NAMESPACE}/{self.task}"

    @property
    def gym_kwargs(self) -> dict[str, Any]:
        spec = self.obs_spec()
        dataset = self._dataset()
        policy = factory_policy(self.policy, self.run_dir)
        return {
            "task": self.task_name(),
            "run_dir": self.run_dir,
            "scene": self.scene,
            "dataset": None if dataset is None else str(dataset),
            "cameras": ",".join(spec.cameras),
            "env_state": spec.env_state,
            "max_steps": self.episode_length,
            "policy": None if policy is None else str(policy),
        }


class LeRobotPickPlaceEnv(gym.Env):
    """:class:`~factory.policy.env.PickPlaceEnv` of a task with LeRobot's raw observation keys
    (``agent_pos``, ``environment_state``, ``pixels``: {camera: image}); the gymnasium ids of
    :data:`GYM_IDS` make it with their task. With ``policy`` (a factory policy's
    ``pretrained_model`` folder) it observes and acts as that policy does
    (:class:`PolicyAdapter`)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 (gymnasium's)

    def __init__(
        self,
        run_dir: str,
        scene: str | None = None,
        dataset: str | None = None,
        cameras: str = "",
        env_state: bool = False,
        max_steps: int = 400,
        render_mode: str | None = "rgb_array",
        task: str = DEFAULT_TASK,
        policy: str | None = None,
    ) -> None:
        from factory.policy.env import PickPlaceEnv

        self.adapter = None if policy is None else PolicyAdapter(Path(policy))
        cams = tuple(c for c in cameras.split(",") if c)
        self.env = PickPlaceEnv(
            run_dir,
            scene,
            cameras=cams,
            depth=False,
            env_state=env_state,
            max_steps=max_steps,
            dataset=dataset,
            render_mode=render_mode,
            task=task,
        )
        self.cameras = cams
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.env.metadata["render_fps"]}
        inner = self.env.observation_space
        assert isinstance(inner, gym.spaces.Dict)
        self.env_state = ENV_STATE in inner.spaces
        spaces: dict[str, gym.Space[Any]] = {"agent_pos": inner[STATE]}
        if self.env_state:
            spaces["environment_state"] = inner[ENV_STATE]
        self.action_space = self.env.action_space
        self._state: np.ndarray | None = None
        if self.adapter is not None:  # the model's vectors
            shapes = self.adapter.shapes()
            self.env_state = ENV_STATE in shapes
            spaces = {"agent_pos": _box(shapes[STATE])}
            if self.env_state:
                spaces["environment_state"] = _box(shapes[ENV_STATE])
            self.action_space = _box(shapes["action"])
        if cams:
            spaces["pixels"] = gym.spaces.Dict({c: inner[f"observation.images.{c}"] for c in cams})
        self.observation_space = gym.spaces.Dict(spaces)
        self.task = self.env.task
        self.task_description = self.env.task_description
        self._max_episode_steps = max_steps

    def _convert(self, obs: dict[str, np.ndarray]) -> dict[str, Any]:
        self._state = obs[STATE]
        if self.adapter is not None:
            obs = {**obs, **self.adapter.observe(obs)}
        out: dict[str, Any] = {"agent_pos": obs[STATE]}
        if self.env_state:
            out["environment_state"] = obs[ENV_STATE]
        if self.cameras:
            out["pixels"] = {c: obs[f"observation.images.{c}"] for c in self.cameras}
        return out

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """``seed`` s below ``2**32`` (lerobot-eval's ``--seed`` + episode number) becomes the
        evaluation seed ``2**32 + s``, so LeRobot's evaluations never draw the demos' seeds."""
        from factory.policy.env import EVAL_SEED_OFFSET

        super().reset(seed=seed)
        if seed is not None and seed < EVAL_SEED_OFFSET:
            seed = EVAL_SEED_OFFSET + seed
        if self.adapter is not None:
            self.adapter.reset()
        obs, info = self.env.reset(seed=seed, options=options)
        return self._convert(obs), info

    def step(self, action: np.ndarray) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        action = np.asarray(action, np.float32).reshape(self.action_space.shape)
        if self.adapter is not None:
            assert self._state is not None, "step() before reset()"
            action = self.adapter.act(action, self._state)
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._convert(obs), reward, terminated, truncated, info

    def render(self) -> np.ndarray:
        return self.env.render()

    def close(self) -> None:
        self.env.close()


def _box(shape: tuple[int, ...]) -> gym.spaces.Box:
    return gym.spaces.Box(-np.inf, np.inf, shape, np.float32)


for _id, _task in GYM_IDS.items():
    if _id not in gym.registry:
        gym.register(
            id=_id,
            entry_point=f"{__name__}:LeRobotPickPlaceEnv",
            kwargs={"task": _task},
            order_enforce=False,
            disable_env_checker=True,
        )
