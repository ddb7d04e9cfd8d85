"""The gymnasium envs of a task in a scene of a run, and how they are made.

:class:`PickPlaceEnv` is one episode at a time (``gymnasium.Env``) over the batched
:class:`~factory.policy.vector_env.PickPlaceVecEnv` with one simulation, and
:class:`PickPlaceVectorEnv` a ``gymnasium.vector.VectorEnv`` over it; ``stage=eval`` uses the
batched form directly. They run any registered task (``task``, default the default task's;
:mod:`factory.tasks`), its scene loaded exactly as ``stage=demos`` records it
(:meth:`~factory.tasks.base.Task.env_scene`: composed model, robot base spot, cleared objects,
cameras, island sleeping).

Observation (dict, keyed like the dataset's features; numpy, no batch axis here;
:class:`~factory.policy.obs_spec.ObsSpec`), e.g. of ``task=pick_place``:

* ``observation.state`` float32 (8,): arm joints (rad) + gripper opening (m);
* ``observation.ee_pose`` float32 (7,): tool site position (m) + quaternion wxyz, world frame;
* ``observation.environment_state`` float32 (14,) (``env_state=True``): pick object position
  (m) + quaternion wxyz, then the target's, world frame;
* ``observation.images.<cam>`` uint8 (H, W, 3) and ``observation.depth.<cam>`` uint16 (H, W)
  millimetres for the cameras asked for.

``task=mobile_pick_place`` observes an 11-D state (+ base x, y, yaw) and ``subtask_index``,
and acts with 11-D actions (+ the base target; :mod:`factory.tasks.mobile_pick_place.env`).

Action: float32 (8,): desired arm joints (rad) at the end of the frame + gripper command (m;
0.08 open, negative squeezes), as the dataset's ``action``. ``info`` carries ``is_success``,
``reason`` (the success check's failure reason, empty on success or while running), ``seed``
and ``steps``.

Seeds: ``reset(seed=s)`` places the objects with the demos' sampler and
``np.random.default_rng(s)`` (the mobile task: the planner's spawn of seed ``s``), so seed
``s`` gives the configuration the demos would record with that seed. The demos draw 32-bit
seeds (below ``2**32``); evaluation seeds start at :data:`EVAL_SEED_OFFSET` = ``2**32``
(:func:`eval_seed`), so the two never meet.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from factory.config import DemosConfig
from factory.errors import StoreError, TaskError
from factory.policy.obs_spec import ObsSpec, obs_spec_of_dataset, obs_spec_of_demos
from factory.policy.vector_env import PickPlaceVecEnv
from factory.tasks import DEFAULT_TASK, get_task

log = logging.getLogger(__name__)

EVAL_SEED_OFFSET = 2**32
"""Evaluation seeds are >= this; the demos' seeds are 32-bit (< this)."""
RESEED_STRIDE = 2**40
"""A seed whose configuration cannot be placed is replaced by ``seed + k * RESEED_STRIDE``."""


def eval_seed(root: int, scene_id: str, index: int) -> int:
    """The seed of evaluation configuration ``index`` in a scene: a hash of (root, scene,
    index) in the evaluation namespace, offset by :data:`EVAL_SEED_OFFSET`."""
    digest = hashlib.sha256(f"eval/{root}/{scene_id}/{index}".encode()).digest()
    return EVAL_SEED_OFFSET + int.from_bytes(digest[:4], "little")


def demos_config_of(run_dir: str | Path) -> DemosConfig:
    """``demos.*`` of the run's last recorded configuration (``manifest.json``), else the
    defaults: what the env needs to compose scenes as the demos did (island sleeping)."""
    from factory.store import RunStore

    cfg = RunStore(run_dir).read_manifest().get("config", {}).get("demos", {})
    known = set(DemosConfig.__dataclass_fields__)
    values = {k: v for k, v in cfg.items() if k in known}
    return DemosConfig(**values)


def make_vec_env(
    run_dir: str | Path,
    scene_id: str,
    num_envs: int = 1,
    spec: ObsSpec | None = None,
    max_steps: int | None = None,
    nthread: int = 0,
    interpolate: bool = True,
    dc: DemosConfig | None = None,
    task: str | None = None,
    executor: str = "cpu",
) -> tuple[PickPlaceVecEnv, Any]:
    """A batched env of a scene of a run, and the scene's planner (the privileged agent), set
    up exactly as ``stage=demos task=<task>`` sets the scene up.

    Args:
        run_dir: the run directory; scene_id: a scene under ``scenes/``.
        num_envs: episodes run at once; spec: what to observe (default: the demos' cameras).
        max_steps: frames per episode before truncation (default: the task's,
            :attr:`~factory.tasks.base.Task.env_max_steps`).
        nthread: simulation threads (0: one per core) of a task stepped on one batch.
        interpolate: the controller's first-order hold (see the task's env module).
        dc: the demos' settings (default: the run's, :func:`demos_config_of`).
        task: the task (default: ``spec``'s, else the default task).
        executor: ``cpu`` (MuJoCo on a thread pool) or ``warp`` (MuJoCo Warp and its batch
            renderer, :mod:`factory.policy.warp_sim`).

    Raises:
        StoreError: no such scene; TaskError: the scene cannot host the task.
    """
    from factory.policy.vector_env import task_sim

    name = task or (spec.task if spec is not None else DEFAULT_TASK)
    t = get_task(name)
    run_dir = Path(run_dir)
    if not (run_dir / "scenes" / scene_id / "scene.json").is_file():
        raise StoreError(f"no scene {scene_id!r} in {run_dir / 'scenes'}: check the scene id")
    dc = dc or demos_config_of(run_dir)
    setup, planner = t.env_scene(run_dir, scene_id, dc)
    spec = spec or obs_spec_of_demos(dc, task=name)
    sim = task_sim(t, setup, planner, num_envs, spec, nthread, interpolate, executor)
    return PickPlaceVecEnv(sim, max_steps, t.env_instruction(setup)), planner


def _box(shape: tuple[int, ...], dtype: str) -> gym.spaces.Box:
    if dtype == "uint8":
        return gym.spaces.Box(0, 255, shape, np.uint8)
    if dtype == "uint16":
        return gym.spaces.Box(0, 65535, shape, np.uint16)
    return gym.spaces.Box(-np.inf, np.inf, shape, np.float32)


def action_space(task: str = DEFAULT_TASK) -> gym.spaces.Box:
    """The task's action (:meth:`~factory.tasks.base.Task.env_action_bounds`): of
    ``task=pick_place``, arm joint targets within the Panda's limits (rad) and the gripper
    command from squeezing shut to open (m)."""
    low, high = get_task(task).env_action_bounds()
    return gym.spaces.Box(low, high, low.shape, np.float32)


class PickPlaceEnv(gym.Env):
    """A task in a scene of a run, one episode at a time (see the module docstring).

    Args:
        run_dir: the run directory.
        scene: a scene id of the run (default: its first scene).
        cameras: cameras to observe (default: the demos' cameras); ``()`` for none.
        depth: also observe depth; env_state: also observe the environment state.
        max_steps: frames per episode (truncation; default: the task's).
        interpolate: the controller's first-order hold.
        dataset: take fps, cameras, image size and depth from this LeRobot dataset instead.
        vec: an existing one-simulation batched env to wrap (the other arguments are ignored).
        task: the task (default: the dataset's when one is given, else the default task).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 (gymnasium's)

    def __init__(
        self,
        run_dir: str | Path | None = None,
        scene: str | None = None,
        cameras: tuple[str, ...] | list[str] | None = None,
        depth: bool = True,
        env_state: bool = False,
        max_steps: int | None = None,
        interpolate: bool = True,
        dataset: str | Path | None = None,
        render_mode: str | None = "rgb_array",
        vec: PickPlaceVecEnv | None = None,
        task: str | None = None,
    ) -> None:
        if vec is None:
            if run_dir is None:
                raise StoreError("PickPlaceEnv needs run_dir (a run with scenes) or vec")
            from factory.store import RunStore

            ids = RunStore(run_dir).scene_ids()
            if not ids:
                raise StoreError(f"no scenes in {run_dir}: run stage=generate or ingest first")
            scene = scene or ids[0]
            dc = demos_config_of(run_dir)
            if dataset is not None:
                spec = obs_spec_of_dataset(dataset, env_state, task)
            else:
                spec = obs_spec_of_demos(dc, env_state, task or DEFAULT_TASK)
            cams = spec.cameras if cameras is None else tuple(cameras)
            spec = replace(spec, cameras=cams, depth=spec.depth and depth and bool(cams))
            vec, _ = make_vec_env(run_dir, scene, 1, spec, max_steps, 1, interpolate, dc)
        if vec.num_envs != 1:
            raise ValueError("PickPlaceEnv wraps a batched env of one simulation")
        self.vec = vec
        self.scene_id = vec.setup.scene.id
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": vec.spec.fps}
        self.observation_space = gym.spaces.Dict(
            {k: _box(s, d) for k, (s, d) in vec.spec.shapes().items()}
        )
        self.action_space = action_space(vec.spec.task)
        self.task = vec.instruction
        self.task_description = vec.instruction
        self._max_episode_steps = vec.max_steps

    def _first(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v[0] for k, v in obs.items()}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Starts an episode: ``options={"state": s}`` restores a recorded MuJoCo integration
        state, ``{"qpos": q}`` a configuration; otherwise the sampler with ``seed`` (or a seed
        drawn from the env's generator, in the evaluation namespace)."""
        super().reset(seed=seed)
        options = options or {}
        obs: dict[str, np.ndarray] | None = None
        if "state" in options:
            obs, _ = self.vec.reset(states=np.asarray(options["state"])[None])
        elif "qpos" in options:
            obs, _ = self.vec.reset(qpos=np.asarray(options["qpos"])[None])
        else:
            base = (
                int(seed)
                if seed is not None
                else EVAL_SEED_OFFSET + int(self.np_random.integers(2**32))
            )
            for k in range(100):
                try:
                    obs, _ = self.vec.reset(seeds=[base + k * RESEED_STRIDE])
                    break
                except TaskError as e:
                    log.info("seed %d: %s; trying the next", base + k * RESEED_STRIDE, e)
        if obs is None:
            raise TaskError(f"scene {self.scene_id!r}: no seed of 100 places the task objects")
        return self._first(obs), self._info()

    def _info(self) -> dict[str, Any]:
        r = self.vec.result(0)
        return {
            "is_success": r["success"],
            "reason": r["reason"],
            "seed": r["seed"],
            "steps": r["steps"],
        }

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, _ = self.vec.step(np.asarray(action)[None])
        return (
            self._first(obs),
            float(reward[0]),
            bool(terminated[0]),
            bool(truncated[0]),
            (self._info()),
        )

    def render(self) -> np.ndarray:
        """The task's video cameras side by side (H, k W, 3) uint8 at the observation's size
        (``task=pick_place``: left, right, wrist)."""
        return self.vec.render(0)

    def close(self) -> None:
        self.vec.close()


class PickPlaceVectorEnv(gym.vector.VectorEnv):
    """A ``gymnasium.vector.VectorEnv`` over one batched env (all simulations in one
    ``mujoco.batch.Batch``): ``SAME_STEP`` autoreset, as lerobot's vector envs; a finished
    env's last observation and info are in ``infos["final_obs"]`` / ``infos["final_info"]``
    and it restarts from the next seed of the env's generator (evaluation namespace).

    Args:
        vec: the batched env (:func:`make_vec_env`).
    """

    metadata = {  # noqa: RUF012 (gymnasium's)
        "render_modes": ["rgb_array"],
        "autoreset_mode": gym.vector.AutoresetMode.SAME_STEP,
    }

    def __init__(self, vec: PickPlaceVecEnv) -> None:
        from gymnasium.vector.utils import batch_space

        self.vec = vec
        self.num_envs = vec.num_envs
        self.single_observation_space = gym.spaces.Dict(
            {k: _box(s, d) for k, (s, d) in vec.spec.shapes().items()}
        )
        self.single_action_space = action_space(vec.spec.task)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {**self.metadata, "render_fps": vec.spec.fps}
        self.task = vec.instruction

    def _seed_reset(self, ids: list[int], seeds: list[int] | None = None) -> None:
        for k, i in enumerate(ids):
            base = (
                seeds[k]
                if seeds is not None
                else EVAL_SEED_OFFSET + int(self.np_random.integers(2**32))
            )
            for j in range(100):
                try:
                    self.vec.reset(seeds=[base + j * RESEED_STRIDE], ids=[i])
                    break
                except TaskError:
                    continue
            else:
                raise TaskError(f"scene {self.vec.setup.scene.id!r}: no seed places the objects")

    def _infos(self, ids: range | list[int]) -> dict[str, Any]:
        infos: dict[str, Any] = {}
        for i in ids:
            r = self.vec.result(i)
            info = {"is_success": r["success"], "reason": r["reason"], "seed": r["seed"]}
            infos = self._add_info(infos, {**info, "steps": r["steps"]}, i)
        return infos

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Resets every env: ``seed`` a list (one configuration seed each) or an int (seeds
        the generator the configurations are drawn from)."""
        if isinstance(seed, int) or seed is None:
            self._np_random, self._np_random_seed = gym.utils.seeding.np_random(seed)
            self._seed_reset(list(range(self.num_envs)))
        else:
            self._seed_reset(list(range(self.num_envs)), [int(s) for s in seed])
        return self.vec.observations(), self._infos(range(self.num_envs))

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        obs, reward, terminated, truncated, _ = self.vec.step(np.asarray(actions, np.float32))
        infos = self._infos(range(self.num_envs))
        ended = [i for i in range(self.num_envs) if terminated[i] or truncated[i]]
        for i in ended:
            final = {k: v[i] for k, v in obs.items()}
            r = self.vec.result(i)
            infos = self._add_info(
                infos,
                {
                    "final_obs": final,
                    "final_info": {"is_success": r["success"], "reason": r["reason"]},
                },
                i,
            )
        if ended:
            self._seed_reset(ended)
            obs = self.vec.observations()
        return obs, reward.astype(np.float64), terminated, truncated, infos

    def render(self) -> tuple[np.ndarray, ...]:
        return tuple(self.vec.render(i) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        self.vec.close()
