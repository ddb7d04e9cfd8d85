"""The gymnasium env of ``task=pick_place`` in a scene of a run, and how it is made.

:class:`PickPlaceEnv` is one episode at a time (``gymnasium.Env``) over the batched
:class:`~factory.policy.vector_env.PickPlaceVecEnv` with one simulation; ``stage=eval`` uses the
batched form directly. Both load a scene of a run exactly as ``stage=demos`` records it
(:func:`factory.demos.stage.scene_planner`): composed model, robot base spot, cleared objects,
cameras, island sleeping.

Observation (dict, keyed like the dataset's features; numpy, no batch axis here):

* ``observation.state`` float32 (8,): arm joints (rad) + gripper opening (m);
* ``observation.ee_pose`` float32 (7,): tool site position (m) + quaternion wxyz, world frame;
* ``observation.environment_state`` float32 (14,) (``env_state=True``): pick object position
  (m) + quaternion wxyz, then the target's, world frame;
* ``observation.images.<cam>`` uint8 (H, W, 3) and ``observation.depth.<cam>`` uint16 (H, W)
  millimetres for the cameras asked for.

Action: float32 (8,): desired arm joints (rad) at the end of the frame + gripper command (m;
0.08 open, negative squeezes), as the dataset's ``action``. ``info`` carries ``is_success``,
``reason`` (the success check's failure reason, empty on success or while running), ``seed``
and ``steps``.

Seeds: ``reset(seed=s)`` places the objects with the demos' sampler and
``np.random.default_rng(s)``, so seed ``s`` gives the configuration the demos would record
with that seed. The demos draw 32-bit seeds (below ``2**32``); evaluation seeds start at
:data:`EVAL_SEED_OFFSET` = ``2**32`` (:func:`eval_seed`), so the two never meet.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from factory.config import DemosConfig
from factory.errors import StoreError, TaskError
from factory.policy.vector_env import ObsSpec, PickPlaceVecEnv

log = logging.getLogger(__name__)

EVAL_SEED_OFFSET = 2**32
"""Evaluation seeds are >= this; the demos' seeds are 32-bit (< this)."""
RESEED_STRIDE = 2**40
"""A seed whose configuration cannot be placed is replaced by ``seed + k * RESEED_STRIDE``."""
CAMERAS = ("left", "right", "wrist")


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


def dataset_features(root: str | Path) -> dict[str, Any]:
    """``features`` and ``fps`` of a LeRobot dataset (``meta/info.json``), without lerobot.

    Raises:
        StoreError: the folder holds no LeRobot dataset.
    """
    path = Path(root) / "meta" / "info.json"
    if not path.is_file():
        raise StoreError(f"{root} is not a LeRobot dataset (no meta/info.json): run stage=dataset")
    info = json.loads(path.read_text())
    return {"fps": info["fps"], "features": info["features"]}


def obs_spec_of_dataset(root: str | Path, env_state: bool | None = None) -> ObsSpec:
    """The observation spec matching a dataset's features (fps, cameras, image size, depth).

    Args:
        root: the dataset folder (``dataset/merged``).
        env_state: observe ``observation.environment_state``; None: when the dataset has it.
    """
    meta = dataset_features(root)
    feats = meta["features"]
    cams = tuple(c for c in CAMERAS if f"observation.images.{c}" in feats)
    h, w = (feats[f"observation.images.{cams[0]}"]["shape"][:2]) if cams else (128, 128)
    depth = any(f"observation.depth.{c}" in feats for c in cams)
    has_env = "observation.environment_state" in feats
    return ObsSpec(
        fps=float(meta["fps"]),
        cameras=cams,
        width=int(w),
        height=int(h),
        depth=depth,
        env_state=has_env if env_state is None else env_state,
    )


def obs_spec_of_demos(dc: DemosConfig, env_state: bool = False) -> ObsSpec:
    """The observation spec of what ``stage=demos`` records with ``dc``."""
    return ObsSpec(
        fps=dc.fps,
        cameras=tuple(dc.cameras) if dc.render else (),
        width=dc.width,
        height=dc.height,
        depth=dc.render,
        env_state=env_state,
    )


def instruction_of(setup: Any) -> str:
    """The task instruction the demos record for a scene's setup."""
    scene, objects = setup.scene, setup.objects
    if scene.task and scene.task.instruction:
        return str(scene.task.instruction)
    pick = objects.pick.category.replace("_", " ")
    target = objects.target.category.replace("_", " ")
    return f"put the {pick} {objects.relation} the {target}"


def make_vec_env(
    run_dir: str | Path,
    scene_id: str,
    num_envs: int = 1,
    spec: ObsSpec | None = None,
    max_steps: int = 400,
    nthread: int = 0,
    interpolate: bool = True,
    dc: DemosConfig | None = None,
) -> tuple[PickPlaceVecEnv, Any]:
    """A batched env of a scene of a run, and the scene's planner (the privileged agent).

    Args:
        run_dir: the run directory; scene_id: a scene under ``scenes/``.
        num_envs: episodes run at once; spec: what to observe (default: the demos' cameras).
        max_steps: frames per episode before truncation.
        nthread: simulation threads (0: one per core).
        interpolate: the controller's first-order hold (see :mod:`factory.policy.vector_env`).
        dc: the demos' settings (default: the run's, :func:`demos_config_of`).

    Raises:
        StoreError: no such scene; TaskError: the scene cannot host the task.
    """
    from factory.demos.stage import scene_planner

    run_dir = Path(run_dir)
    if not (run_dir / "scenes" / scene_id / "scene.json").is_file():
        raise StoreError(f"no scene {scene_id!r} in {run_dir / 'scenes'}: check the scene id")
    dc = dc or demos_config_of(run_dir)
    setup, planner = scene_planner(run_dir, scene_id, dc)
    env = PickPlaceVecEnv(
        setup,
        num_envs,
        spec or obs_spec_of_demos(dc),
        max_steps=max_steps,
        nthread=nthread,
        interpolate=interpolate,
        ws=planner.ws,
        instruction=instruction_of(setup),
    )
    return env, planner


def _box(shape: tuple[int, ...], dtype: str) -> gym.spaces.Box:
    if dtype == "uint8":
        return gym.spaces.Box(0, 255, shape, np.uint8)
    if dtype == "uint16":
        return gym.spaces.Box(0, 65535, shape, np.uint16)
    return gym.spaces.Box(-np.inf, np.inf, shape, np.float32)


def action_space() -> gym.spaces.Box:
    """The 8-D action: arm joint targets within the Panda's limits (rad), gripper command
    from squeezing shut to open (m)."""
    from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN, PANDA

    low = np.array([*PANDA.q_min, GRIP_CLOSED], np.float32)
    high = np.array([*PANDA.q_max, GRIP_OPEN], np.float32)
    return gym.spaces.Box(low, high, (8,), np.float32)


class PickPlaceEnv(gym.Env):
    """Pick-and-place in a scene of a run, one episode at a time (see the module docstring).

    Args:
        run_dir: the run directory.
        scene: a scene id of the run (default: its first scene).
        cameras: cameras to observe (default: the demos' cameras); ``()`` for none.
        depth: also observe depth; env_state: also observe the environment state.
        max_steps: frames per episode (truncation).
        interpolate: the controller's first-order hold.
        dataset: take fps, cameras, image size and depth from this LeRobot dataset instead.
        vec: an existing one-simulation batched env to wrap (the other arguments are ignored).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 (gymnasium's)

    def __init__(
        self,
        run_dir: str | Path | None = None,
        scene: str | None = None,
        cameras: tuple[str, ...] | list[str] | None = None,
        depth: bool = True,
        env_state: bool = False,
        max_steps: int = 400,
        interpolate: bool = True,
        dataset: str | Path | None = None,
        render_mode: str | None = "rgb_array",
        vec: PickPlaceVecEnv | None = None,
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
                spec = obs_spec_of_dataset(dataset, env_state)
            else:
                spec = obs_spec_of_demos(dc, env_state)
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
        self.action_space = action_space()
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
        """The three cameras side by side (H, 3 W, 3) uint8 at the observation's size."""
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
        self.single_action_space = action_space()
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
