"""Batched closed-loop episodes of one scene of a task: the env behind ``stage=eval`` and the
gymnasium envs, one class for every registered task.

:class:`PickPlaceVecEnv` keeps what does not depend on the task: one episode record per env
(:class:`Episode`: seed, step limit, frames, outcome), the latest observations in one buffer
per key with a leading batch axis (:class:`~factory.policy.obs_spec.ObsSpec`), resets by seed,
recorded MuJoCo integration state (replay) or qpos, one action per env and frame, the step
outcome (rewards, termination, truncation, info), the results, and the renderers of the
observed cameras and of videos, and ``observation.camera_poses`` (the task's calibration of its
cameras fixed in the scene, :meth:`~factory.tasks.base.Task.camera_calibration`: a constant of
the scene, set once). The task's simulation (:class:`TaskSim`, :func:`task_sim`)
does the rest as ``stage=demos`` does it for the task: the worlds stepped together on one batch
(:class:`~factory.policy.batch_sim.BatchSim` with the task's rules, the fixed-base task) or the
task's own simulation (:class:`~factory.tasks.mobile_pick_place.env.MobileSim`): the initial
configurations, the controller, the observations other than the images, and when an episode
ends and why.

Termination: success, or a failure the task ends an episode with (a deep collision, a drop);
truncation after the step limit, with the task's failure reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from factory.sim.gl import configure_gl

configure_gl("auto")  # before the tasks' simulations import mujoco: the env renders offscreen

import numpy as np  # noqa: E402

from factory.demos.record.calibration import CAMERA_POSES_KEY  # noqa: E402
from factory.policy.obs_spec import ObsSpec  # noqa: E402

if TYPE_CHECKING:
    import mujoco

    from factory.tasks.base import Task
    from factory.tasks.pick_place.objects import Outcome


@dataclass
class Episode:
    """Book-keeping of one env's running episode.

    Attributes:
        seed: the seed it was reset from (None for a state or qpos reset).
        limit: frames before it is truncated; steps: frames stepped so far.
        done: whether it has ended; success: whether it ended in success.
        reason: the failure reason (empty on success or while running).
        details: the success check's numbers.
    """

    seed: int | None = None
    limit: int = 0
    steps: int = 0
    done: bool = False
    success: bool = False
    reason: str = ""
    details: dict[str, float] = field(default_factory=dict)


class Renderer(Protocol):
    """A renderer of some cameras of a scene (the demos' recording renderers)."""

    @property
    def cfg(self) -> Any: ...

    def close(self) -> None: ...


class TaskSim(Protocol):
    """The simulation of ``num_envs`` episodes of one scene of a task (what the env asks it).

    Attributes:
        setup: the scene set up as the demos record it (``scene``, ``model``, ``robot``).
        spec: what is observed; num_envs: its simulations; action_dim: the action's size.
        per_frame: physics steps per frame.
        terminal: failure reasons that end an episode as terminated even on its last frame.
        video_cameras: the cameras a video shows side by side by default.
        last_actions: (n, action_dim) each env's last action (at a reset: the targets it
            rests at).
    """

    setup: Any
    spec: ObsSpec
    num_envs: int
    action_dim: int
    per_frame: int
    terminal: tuple[str, ...]
    video_cameras: tuple[str, ...]

    @property
    def last_actions(self) -> np.ndarray: ...

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos of seed ``seed``; raises TaskError when there is none."""
        ...

    def reset(
        self, ids: list[int], states: np.ndarray | None, qpos: np.ndarray | None, spawned: bool
    ) -> None:
        """Sets envs ``ids`` to recorded integration states or to ``qpos`` (``spawned``: drawn
        by :meth:`sample_qpos`)."""
        ...

    def load(self, i: int) -> mujoco.MjData:
        """Env ``i``'s current state with kinematics and contacts (a scratch ``MjData``)."""
        ...

    def advance(self, ids: list[int], actions: np.ndarray) -> None:
        """Simulates one frame of envs ``ids`` under their actions (len(ids), A)."""
        ...

    def end_frame(self, ids: list[int], actions: np.ndarray) -> None:
        """The frame's actions become the targets the next frame starts from."""
        ...

    def observe(
        self,
        i: int,
        data: mujoco.MjData,
        obs: dict[str, np.ndarray],
        ep: Episode,
        action: np.ndarray | None,
    ) -> Outcome | None:
        """Writes env ``i``'s observations but the images into ``obs`` (after the frame's
        ``action``; None: the episode's first observation); the outcome once it ends."""
        ...

    def renderer(self, cameras: tuple[str, ...]) -> Renderer: ...

    def draw(
        self, renderer: Any, data: mujoco.MjData, i: int
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB, depth) of env ``i``'s state, loaded in ``data`` (:meth:`load`)."""
        ...

    def step_info(self) -> dict[str, np.ndarray]:
        """What the task adds to a step's info, (n,) per key."""
        ...

    def result(self, i: int) -> dict[str, Any]:
        """What the task adds to env ``i``'s result."""
        ...


def task_sim(
    task: Task,
    setup: Any,
    planner: Any,
    num_envs: int,
    spec: ObsSpec,
    nthread: int = 0,
    interpolate: bool = True,
    executor: str = "cpu",
) -> TaskSim:
    """The simulation of ``num_envs`` episodes of a scene of ``task``: the task's own
    (:meth:`~factory.tasks.base.Task.env_sim`), else its worlds stepped together by its rules
    (:meth:`~factory.tasks.base.Task.env_rules`): on one CPU batch (``executor="cpu"``,
    ``nthread`` simulation threads, 0: one per core) or on MuJoCo Warp (``"warp"``, or
    ``"warp_opengl"`` with OpenGL's cameras: :class:`~factory.policy.warp_sim.WarpBatchSim`).

    Raises:
        ConfigError: ``executor="warp"`` for a task that simulates its episodes itself.
    """
    sim: TaskSim | None = task.env_sim(setup, planner, num_envs, spec, interpolate)
    if sim is not None:
        if executor != "cpu":
            from factory.errors import ConfigError

            raise ConfigError(
                f"eval.executor={executor} runs tasks stepped on one batch; task "
                f"{task.name!r} simulates its episodes itself: use eval.executor=cpu"
            )
        return sim
    rules = task.env_rules(setup, planner, num_envs, spec, interpolate)
    if executor != "cpu":
        from factory.policy.warp_sim import WARP_EXECUTORS, WarpBatchSim

        if executor not in WARP_EXECUTORS:
            from factory.errors import ConfigError

            raise ConfigError(
                f"eval.executor={executor!r} is unknown: use one of cpu, "
                f"{', '.join(WARP_EXECUTORS)}"
            )
        return WarpBatchSim(rules, num_envs, spec, images=WARP_EXECUTORS[executor])
    from factory.policy.batch_sim import BatchSim

    return BatchSim(rules, num_envs, spec, nthread)


class PickPlaceVecEnv:
    """``num_envs`` episodes of one scene of a task, stepped together (module docstring).

    Args:
        sim: the task's simulation of the scene (:func:`task_sim`).
        max_steps: frames before an episode is truncated (default: the task's,
            :attr:`~factory.tasks.base.Task.env_max_steps`).
        instruction: the task's language instruction (``task`` of the dataset).
    """

    def __init__(self, sim: TaskSim, max_steps: int | None = None, instruction: str = "") -> None:
        from factory.tasks import get_task

        self.sim = sim
        self.setup = sim.setup
        self.model = sim.setup.model
        self.spec = sim.spec
        self.num_envs = sim.num_envs
        self.action_dim = sim.action_dim
        self.per_frame = sim.per_frame
        self.max_steps = get_task(sim.spec.task).env_max_steps if max_steps is None else max_steps
        self.instruction = instruction
        self.renderer: Renderer | None = None
        if self.spec.cameras:
            self.renderer = sim.renderer(self.spec.cameras)
        self._video: Renderer | None = None
        self._episodes = [Episode(done=True) for _ in range(self.num_envs)]  # none started
        self._obs = {
            k: np.zeros((self.num_envs, *shape), dtype)
            for k, (shape, dtype) in self.spec.shapes().items()
        }
        if self.spec.pose_cameras:  # the cameras' calibration: a constant of the scene
            self._obs[CAMERA_POSES_KEY][:] = self._calibration()

    def _calibration(self) -> np.ndarray:
        """``observation.camera_poses`` of the scene (13 per camera of the spec's
        ``pose_cameras``): the task's cameras as the scene placed them (no appearance jitter).

        Raises:
            PolicyError: a camera whose calibration the task does not know.
        """
        from factory.demos.record.calibration import calibration_vector
        from factory.schema.errors import PolicyError
        from factory.tasks import get_task

        cams = self.spec.pose_cameras
        poses, fovy = get_task(self.spec.task).camera_calibration(self.setup, cams)
        missing = [c for c in cams if c not in poses]
        if missing:
            raise PolicyError(
                f"task {self.spec.task!r} knows no calibration of the {', '.join(missing)} "
                f"camera(s) for {CAMERA_POSES_KEY}: observe the cameras it calibrates, or "
                "evaluate where the dataset came from"
            )
        return calibration_vector(poses, fovy, cams)

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' sampler or spawn (seed ``s``
        starts where the demos' planner starts episode ``s``).

        Raises:
            TaskError: no initial configuration with this seed.
        """
        return self.sim.sample_qpos(seed)

    # ---- episodes
    def _check_states(self, states: np.ndarray) -> None:
        """Recorded integration states (n, nstate) must be of this scene's model."""
        import mujoco

        from factory.demos.record.payload import STATE_SPEC
        from factory.schema.errors import PolicyError

        size = mujoco.mj_stateSize(self.model, STATE_SPEC)
        if states.ndim != 2 or states.shape[1] != size:
            raise PolicyError(
                f"recorded states of {states.shape[-1]} values do not fit this scene's model "
                f"({size}): the episodes were recorded with another set-up of the scene (e.g. "
                "before the task took look-alike objects out); re-record them with "
                "stage=demos force=true"
            )

    def reset(
        self,
        seeds: list[int] | None = None,
        states: np.ndarray | None = None,
        qpos: np.ndarray | None = None,
        ids: list[int] | None = None,
        max_steps: list[int] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Starts new episodes in envs ``ids`` (default all).

        Exactly one of ``seeds`` (:meth:`sample_qpos`), ``states`` (recorded MuJoCo
        integration states, (len(ids), nstate): replay) or ``qpos`` ((len(ids), nq): the robot
        at rest there) gives the initial configurations; ``max_steps`` (per env) overrides the
        env's step limit.

        Returns:
            observations of every env (n, ...) and ``{"seed": [...]}``.

        Raises:
            ValueError: none or more than one of seeds, states and qpos.
            TaskError: a seed without an initial configuration.
        """
        ids = list(range(self.num_envs)) if ids is None else list(ids)
        if sum(x is not None for x in (seeds, states, qpos)) != 1:
            raise ValueError("reset needs exactly one of seeds, states or qpos")
        if seeds is not None:
            qpos = np.stack([self.sample_qpos(int(s)) for s in seeds])
        if states is not None:
            self._check_states(states)
        self.sim.reset(ids, states, qpos, seeds is not None)
        for k, i in enumerate(ids):
            seed = None if seeds is None else int(seeds[k])
            limit = self.max_steps if max_steps is None else int(max_steps[k])
            self._episodes[i] = Episode(seed=seed, limit=limit)
            self._observe(i, None)
        return self.observations(), {"seed": [e.seed for e in self._episodes]}

    def _observe(self, i: int, action: np.ndarray | None) -> None:
        """Observes env ``i`` (after the frame's ``action``; None: its first observation) and
        ends its episode when the task says so."""
        data = self.sim.load(i)
        if self.renderer is not None:
            for c, (im, dp) in self.sim.draw(self.renderer, data, i).items():
                self._obs[f"observation.images.{c}"][i] = im
                if self.spec.depth:
                    self._obs[f"observation.depth.{c}"][i] = dp
        ep = self._episodes[i]
        out = self.sim.observe(i, data, self._obs, ep, action)
        if out is not None:
            ep.done, ep.success, ep.reason, ep.details = True, out.success, out.reason, out.details

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Applies one action per env (n, A) for one frame; finished envs do not move.

        Returns:
            observations (n, ...), rewards (n,) (1 on the step of success), terminated (n,)
            (success or a failure that ends the episode), truncated (n,) (step limit), info
            with ``success`` (n,) bool, ``reason`` (n,) str (empty on success or while
            running), ``steps`` (n,) and what the task adds (the mobile task's ``subtask``).

        Raises:
            ValueError: actions of another shape.
        """
        actions = np.asarray(actions)
        n, a = self.num_envs, self.action_dim
        if actions.shape != (n, a):
            raise ValueError(f"actions must be ({n}, {a}), got {actions.shape}")
        actions = actions.astype(np.float64)
        ids = [i for i, e in enumerate(self._episodes) if not e.done]
        was_done = self.done
        if ids:
            self.sim.advance(ids, actions[ids])
            for i in ids:
                self._episodes[i].steps += 1
                self._observe(i, actions[i])
            self.sim.end_frame(ids, actions[ids])
        eps = self._episodes
        success = np.array([e.success for e in eps])
        new = self.done & ~was_done
        truncated = new & np.array([e.steps >= e.limit and not e.success for e in eps])
        if self.sim.terminal:
            truncated &= np.array([e.reason not in self.sim.terminal for e in eps])
        terminated = new & ~truncated
        info = {
            "success": success,
            "reason": np.array([e.reason for e in eps], dtype=object),
            "steps": self.steps,
            **self.sim.step_info(),
        }
        reward = (new & success).astype(np.float32)
        return self.observations(), reward, terminated, truncated, info

    def observations(self) -> dict[str, np.ndarray]:
        """The latest observation of every env (copies), (n, ...) per key."""
        return {k: v.copy() for k, v in self._obs.items()}

    @property
    def steps(self) -> np.ndarray:
        """(n,) int: frames stepped in each env's episode."""
        return np.array([e.steps for e in self._episodes])

    @property
    def done(self) -> np.ndarray:
        """(n,) bool: which envs' episodes have ended."""
        return np.array([e.done for e in self._episodes])

    @property
    def last_actions(self) -> np.ndarray:
        """(n, A): each env's last action (at a reset: the targets it rests at), a copy."""
        return self.sim.last_actions

    def result(self, i: int) -> dict[str, Any]:
        """Env ``i``'s episode so far: success, reason, steps, seed, the check's numbers and
        what the task adds (the mobile task: the sub-task it is in, how many it completed,
        the frames it switched at)."""
        e = self._episodes[i]
        return {
            "success": e.success,
            "reason": e.reason,
            "steps": e.steps,
            "seed": e.seed,
            "details": dict(e.details),
            **self.sim.result(i),
        }

    # ---- rendering
    def render(self, i: int, cameras: tuple[str, ...] | None = None) -> np.ndarray:
        """RGB frame of env ``i``'s current state, ``cameras`` (default: the task's video
        cameras) side by side at the spec's size (shorter views padded with black), for
        videos."""
        cameras = self.sim.video_cameras if cameras is None else tuple(cameras)
        if self._video is None or self._video.cfg.cameras != cameras:
            if self._video is not None:
                self._video.close()
            self._video = self.sim.renderer(cameras)
        views = self.sim.draw(self._video, self.sim.load(i), i)
        ims = [views[c][0] for c in cameras]
        h = max(im.shape[0] for im in ims)
        ims = [np.pad(im, ((0, h - im.shape[0]), (0, 0), (0, 0))) for im in ims]
        return np.concatenate(ims, axis=1)

    def close(self) -> None:
        """Closes the renderers (their GL contexts)."""
        for r in (self.renderer, self._video):
            if r is not None:
                r.close()
        self.renderer = self._video = None
