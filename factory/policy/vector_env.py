"""Batched closed-loop pick-and-place episodes of one scene: the simulation behind the env.

:class:`PickPlaceVecEnv` runs ``n`` episodes of one scene together in one persistent
``mujoco.batch.Batch`` (a thread pool over simulations, as ``stage=demos`` executes its
plans), with the demos' own composed model (robot base spot, cleared chairs, cameras), the same
controller, the same renderer and the same success check:

* reset: the demos' sampler (:func:`~factory.tasks.pick_place.plan.initial_configuration`) from a
  seed, or a recorded MuJoCo integration state (replay);
* step: one action per env (8,) = desired arm joints (rad) + gripper command (m), held for one
  frame (``1 / fps`` s = ``per_frame`` physics steps). With ``interpolate`` (default) the arm
  target moves linearly from the previous action to this one over the frame and the
  controller adds the velocity lead the demos use (``kv/kp * (a - a_prev) * fps``); the
  recorded action of frame ``f`` is the demo's target at the end of frame ``f``, so this
  reproduces the demos' control closely. Without it the target jumps to the action at once;
* observations keyed like the dataset's features, with a leading batch axis;
* termination: success (the object in/on the target, released, at rest for 0.5 s, by
  :func:`~factory.tasks.pick_place.objects.check_success`), or a robot collision deeper than 2 cm;
  truncation
  after ``max_steps`` frames, with the success check's failure reason.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass
from typing import Any

from factory.sim.gl import configure_gl

configure_gl("auto")  # before mujoco is imported: the env renders offscreen

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from factory.demos.execute.cpu import (  # noqa: E402
    STATE_SPEC,
    FrameRenderer,
    RecordConfig,
    object_poses,
    robot_penetration,
    robot_signals,
)
from factory.policy.env_common import Episode, EpisodeEnv  # noqa: E402
from factory.tasks.pick_place.objects import Outcome, Workspace, check_success  # noqa: E402
from factory.tasks.pick_place.plan import (  # noqa: E402
    SceneSetup,
    initial_configuration,
    targets_to_ctrl,
)

log = logging.getLogger(__name__)

ENV_STATE_DIM = 14
"""``observation.environment_state``: pick object xyz (m) + quat wxyz, target xyz + quat wxyz."""
COLLISION_DEPTH = 0.02
"""A robot contact with the scene deeper than this (m) ends the episode (as the demos' check)."""
LIFT_MIN = 0.03
"""The object must have been lifted this high (m) before it can count as placed."""


@dataclass(frozen=True)
class ObsSpec:
    """What the env observes and how fast it steps.

    Attributes:
        fps: frames (actions) per second (Hz); the dataset's fps.
        cameras: cameras rendered as ``observation.images.<cam>`` (``left``, ``right``,
            ``wrist``); empty for no images.
        width, height: image size (px).
        depth: also ``observation.depth.<cam>`` (uint16 mm).
        env_state: also ``observation.environment_state``.
    """

    fps: float = 20.0
    cameras: tuple[str, ...] = ("left", "right", "wrist")
    width: int = 128
    height: int = 128
    depth: bool = True
    env_state: bool = False

    def keys(self) -> list[str]:
        """Observation keys, as the dataset's feature names."""
        out = ["observation.state", "observation.ee_pose"]
        if self.env_state:
            out.append("observation.environment_state")
        out += [f"observation.images.{c}" for c in self.cameras]
        if self.depth:
            out += [f"observation.depth.{c}" for c in self.cameras]
        return out

    def shapes(self) -> dict[str, tuple[tuple[int, ...], str]]:
        """Key -> (shape, dtype) of one env's observation."""
        out: dict[str, tuple[tuple[int, ...], str]] = {
            "observation.state": ((8,), "float32"),
            "observation.ee_pose": ((7,), "float32"),
        }
        if self.env_state:
            out["observation.environment_state"] = ((ENV_STATE_DIM,), "float32")
        for c in self.cameras:
            out[f"observation.images.{c}"] = ((self.height, self.width, 3), "uint8")
        if self.depth:
            for c in self.cameras:
                out[f"observation.depth.{c}"] = ((self.height, self.width), "uint16")
        return out


@dataclass
class _Episode(Episode):
    """Book-keeping of one env's running episode: the deepest robot contact (m) too."""

    worst: float = 0.0


class PickPlaceVecEnv(EpisodeEnv[_Episode, FrameRenderer]):
    """``num_envs`` pick-and-place episodes of one scene, stepped together.

    Args:
        setup: the scene with the robot (:func:`factory.demos.stage.scene_planner`).
        num_envs: episodes run at once.
        spec: what to observe.
        max_steps: frames before an episode is truncated.
        nthread: simulation threads (0: one per core).
        interpolate: first-order hold of the arm target over a frame with velocity lead
            (see the module docstring); False holds the action as it is.
        ws: where the sampler puts the task objects (the demos' default).
        instruction: the task's language instruction (``task`` of the dataset).
    """

    def __init__(
        self,
        setup: SceneSetup,
        num_envs: int = 1,
        spec: ObsSpec | None = None,
        max_steps: int = 400,
        nthread: int = 0,
        interpolate: bool = True,
        ws: Workspace | None = None,
        instruction: str = "",
    ) -> None:
        from mujoco.batch import Batch

        self.setup = setup
        self.model = setup.model
        self.robot = setup.robot
        self.spec = spec or ObsSpec()
        self.num_envs = num_envs
        self.max_steps = max_steps
        self.interpolate = interpolate
        self.ws = ws or Workspace()
        self.instruction = instruction
        m = self.model
        self.dt = float(m.opt.timestep)
        self.per_frame = max(1, round(1.0 / (self.spec.fps * self.dt)))
        self.hold_frames = max(1, round(0.5 * self.spec.fps))
        self.batch = Batch(m, num_envs, nthread, persistent=True)
        self._data = mujoco.MjData(m)
        robot_geom = np.zeros(m.ngeom, bool)
        robot_geom[self.robot.geoms] = True
        self._robot_geom = robot_geom
        objs = setup.objects
        self.pick = m.body(objs.pick.id).id
        self.target = m.body(objs.target.id).id
        support = m.body(objs.support.id).id
        self._allowed = np.isin(m.geom_bodyid, [self.pick, self.target, support])
        self._inside_r = 0.5 * min(objs.target.dimensions.width, objs.target.dimensions.length)
        self.renderer: FrameRenderer | None = None
        if self.spec.cameras:
            self.renderer = FrameRenderer(m, self._record_cfg(self.spec.cameras))
        self._video: FrameRenderer | None = None
        self._episodes = [_Episode(done=True) for _ in range(num_envs)]  # none started
        self._prev = np.zeros((num_envs, 8))
        self._obs = self._empty_obs(self.spec.shapes())

    # ---- set-up helpers
    def _record_cfg(self, cameras: tuple[str, ...]) -> RecordConfig:
        s = self.spec
        return RecordConfig(s.fps, s.width, s.height, cameras, "uint16_mm", True)

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' sampler with
        ``np.random.default_rng(seed)``, as :meth:`EpisodePlanner.plan_episode` draws it.

        Raises:
            TaskError: the sampler finds no free spot for the objects with this seed.
        """
        return initial_configuration(self.setup, np.random.default_rng(seed), self.ws)

    # ---- episodes
    def reset(
        self,
        seeds: list[int] | None = None,
        states: np.ndarray | None = None,
        qpos: np.ndarray | None = None,
        ids: list[int] | None = None,
        max_steps: list[int] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Starts new episodes in envs ``ids`` (default all).

        Exactly one of ``seeds`` (the demos' sampler), ``states`` (recorded MuJoCo integration
        states, (len(ids), nstate): replay) or ``qpos`` ((len(ids), nq)) gives the initial
        configurations; ``max_steps`` (per env) overrides the env's step limit.

        Returns:
            observations of every env (n, ...) and ``{"seed": [...]}``.

        Raises:
            TaskError: a seed the sampler cannot place the objects with.
        """
        ids = self._reset_ids(ids, seeds, states, qpos)
        if seeds is not None:
            qpos = np.stack([self.sample_qpos(int(s)) for s in seeds])
        b = self.batch
        b.reset(ids=ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        robot = self.robot
        for k, i in enumerate(ids):
            if states is not None:
                b.state[i] = states[k]
            else:
                assert qpos is not None
                b.bind("qpos")[i] = qpos[k]
                q = qpos[k][robot.qpos]
                width = float(np.sum(np.abs(qpos[k][robot.finger_qpos])))
                a = np.concatenate([q, [width]])
                b.bind("ctrl")[i] = targets_to_ctrl(
                    self.model, robot, a[None, :7], np.zeros((1, 7)), a[7:]
                )[0]
        b.forward(ids=ids)
        for k, i in enumerate(ids):
            seed, limit = self._episode_start(k, seeds, max_steps, self.max_steps)
            self._episodes[i] = _Episode(seed=seed, limit=limit)
            self._observe(i, first=True)
        return self.observations(), self._reset_info()

    def _load(self, i: int) -> mujoco.MjData:
        """Env ``i``'s current state in the scratch data, with kinematics and contacts."""
        d = self._data
        mujoco.mj_setState(self.model, d, self.batch.state[i], STATE_SPEC)
        mujoco.mj_forward(self.model, d)
        return d

    def _observe(self, i: int, first: bool = False) -> None:
        """Observes env ``i`` and updates its episode's book-keeping."""
        m, d = self.model, self._load(i)
        q, width, ee = robot_signals(m, d, self.robot)
        obs = self._obs
        obs["observation.state"][i, :7] = q
        obs["observation.state"][i, 7] = width
        obs["observation.ee_pose"][i] = ee
        if self.spec.env_state:
            obs["observation.environment_state"][i] = object_poses(d, (self.pick, self.target))
        if self.renderer is not None:
            rgbs, depths = self.renderer.render(d)
            for c, im, dp in zip(self.spec.cameras, rgbs, depths, strict=True):
                obs[f"observation.images.{c}"][i] = im
                if self.spec.depth:
                    obs[f"observation.depth.{c}"][i] = dp
        ep = self._episodes[i]
        z = float(d.xpos[self.pick][2])
        if first:
            self._prev[i, :7] = q
            self._prev[i, 7] = width
            ep.start_z = ep.max_z = z
            ep.history = deque(maxlen=self.hold_frames + 1)
        ep.max_z = max(ep.max_z, z)
        ep.worst = max(ep.worst, robot_penetration(m, d, self._robot_geom, self._allowed))
        ep.history.append(np.array(d.qpos))
        if not first:
            self._judge(i, d)

    def _outcome(self, i: int, qpos: np.ndarray) -> Outcome:
        ep = self._episodes[i]
        return check_success(
            self.model,
            qpos,
            ep.history[0],
            ep.max_z,
            ep.start_z,
            self.setup.objects,
            self.robot,
            ep.worst,
        )

    def _judge(self, i: int, d: mujoco.MjData) -> None:
        """Ends env ``i``'s episode on success, collision or the step limit."""
        ep = self._episodes[i]
        if ep.worst > COLLISION_DEPTH:
            out = self._outcome(i, np.array(d.qpos))
            ep.done, ep.success, ep.reason, ep.details = True, False, "collision", out.details
            return
        horiz = float(np.linalg.norm(d.xpos[self.pick][:2] - d.xpos[self.target][:2]))
        settled = len(ep.history) > self.hold_frames
        if settled and ep.max_z - ep.start_z >= LIFT_MIN and horiz < self._inside_r:
            out = self._outcome(i, np.array(d.qpos))
            if out.success:
                ep.done, ep.success, ep.reason, ep.details = True, True, "", out.details
                return
        if ep.steps >= ep.limit:
            out = self._outcome(i, np.array(d.qpos))
            ep.done, ep.success, ep.details = True, out.success, out.details
            ep.reason = out.reason if not out.success else ""

    def _controls(self, actions: np.ndarray, ids: list[int]) -> np.ndarray:
        """Per-substep controls (len(ids), per_frame, nu) for one frame of actions."""
        pf, n = self.per_frame, len(ids)
        a = np.asarray(actions, np.float64)
        prev = self._prev[ids]
        if self.interpolate:
            alpha = (np.arange(1, pf + 1) / pf)[None, :, None]
            arm = prev[:, None, :7] + (a[:, None, :7] - prev[:, None, :7]) * alpha
            vel = np.broadcast_to(((a[:, :7] - prev[:, :7]) * self.spec.fps)[:, None], arm.shape)
        else:
            arm = np.broadcast_to(a[:, None, :7], (n, pf, 7))
            vel = np.zeros_like(arm)
        grip = np.repeat(a[:, 7], pf)
        ctrl = targets_to_ctrl(self.model, self.robot, arm.reshape(-1, 7), vel.reshape(-1, 7), grip)
        return ctrl.reshape(n, pf, -1)

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Applies one action per env (n, 8) for one frame; finished envs do not move.

        Returns:
            observations (n, ...), rewards (n,) (1 on the step of success), terminated (n,)
            (success or collision), truncated (n,) (step limit), info with ``success`` (n,)
            bool, ``reason`` (n,) str (empty on success or while running), ``steps`` (n,).
        """
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs, 8):
            raise ValueError(f"actions must be ({self.num_envs}, 8), got {actions.shape}")
        ids = [i for i, e in enumerate(self._episodes) if not e.done]
        was_done = self.done
        if ids:
            ctrl = self._controls(actions[ids], ids)
            self.batch.rollout(self.per_frame, control=ctrl, ids=ids, record=())
            self._prev[ids] = actions[ids]
            for i in ids:
                self._episodes[i].steps += 1
                self._observe(i)
        reward, terminated, truncated, info = self._step_outcome(was_done)
        return self.observations(), reward, terminated, truncated, info

    def result(self, i: int) -> dict[str, Any]:
        """Env ``i``'s episode so far: success, reason, steps, seed and the check's numbers."""
        return self._result(i)

    def render(self, i: int, cameras: tuple[str, ...] = ("left", "right", "wrist")) -> np.ndarray:
        """RGB frame (H, len(cameras) * W, 3) of env ``i``'s current state, cameras side by
        side (for videos)."""
        video = self._video_renderer(
            cameras, lambda: FrameRenderer(self.model, self._record_cfg(cameras))
        )
        rgbs, _ = video.render(self._load(i))
        return np.concatenate(rgbs, axis=1)
