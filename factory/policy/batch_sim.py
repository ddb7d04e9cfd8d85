"""The env's simulation of a task whose worlds are stepped together on one batch, as
``stage=demos`` executes its plans (the fixed-base task).

:class:`BatchSim` runs ``n`` episodes of one scene in one persistent ``mujoco.batch.Batch`` (a
thread pool over simulations), with the demos' recording pieces: the robot's signals
(:func:`~factory.demos.execute.cpu.robot_signals`), the recording cameras
(:class:`~factory.demos.execute.cpu.FrameRenderer`), the objects' poses
(:func:`~factory.tasks.pick_place.objects.object_poses`) and the robot's deepest contact with the
scene after each frame (:func:`~factory.demos.execute.cpu.robot_penetration`). What belongs to
the task comes from its rules (:meth:`~factory.tasks.base.Task.env_rules`, e.g.
:class:`~factory.tasks.pick_place.env.PickPlaceRules`): the initial configurations, the
controller, the contacts that are no collision, and when an episode ends.

Observations: ``observation.state`` (arm joints, gripper opening), ``observation.ee_pose``,
``observation.environment_state`` (the rules' two bodies' poses) and the cameras'.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import mujoco
import numpy as np

from factory.demos.execute.cpu import (
    FrameRenderer,
    RecordConfig,
    robot_penetration,
    robot_signals,
)
from factory.demos.record.payload import STATE_SPEC
from factory.robots.panda import CAMERAS
from factory.tasks.pick_place.objects import object_poses

if TYPE_CHECKING:
    from factory.tasks.pick_place.objects import Outcome


class BatchRules(Protocol):
    """What :class:`BatchSim` asks a task (see
    :class:`~factory.tasks.pick_place.env.PickPlaceRules`). Rules with a method
    ``env_state(data) -> (d,)`` give ``observation.environment_state`` themselves (e.g.
    :class:`~factory.tasks.articulated.env.ArticulatedRules`: a joint's position); the others'
    is the poses of their ``env_state_bodies``."""

    setup: Any
    action_dim: int
    per_frame: int
    allowed: np.ndarray
    env_state_bodies: tuple[int, int]

    def sample_qpos(self, seed: int) -> np.ndarray: ...

    def hold(self, qpos: np.ndarray) -> np.ndarray: ...

    def controls(self, prev: np.ndarray, actions: np.ndarray) -> np.ndarray: ...

    def start(self, i: int, data: mujoco.MjData, depth: float) -> None: ...

    def update(
        self, i: int, data: mujoco.MjData, depth: float, steps: int, limit: int
    ) -> Outcome | None: ...


class BatchSim:
    """``num_envs`` worlds of one scene stepped together (see the module docstring).

    Args:
        rules: the task's rules for this scene.
        num_envs: episodes run at once.
        spec: what to observe (:class:`~factory.policy.obs_spec.ObsSpec`).
        nthread: simulation threads (0: one per core).
    """

    terminal: tuple[str, ...] = ()
    video_cameras: tuple[str, ...] = tuple(CAMERAS)

    def __init__(self, rules: BatchRules, num_envs: int, spec: Any, nthread: int = 0) -> None:
        from mujoco.batch import Batch

        self._bind(rules, num_envs, spec)
        self.batch = Batch(self.model, num_envs, nthread, persistent=True)

    def _bind(self, rules: BatchRules, num_envs: int, spec: Any) -> None:
        """What every simulation of the rules' worlds holds, whatever steps them: the scene,
        the observed spec, a scratch ``MjData``, the robot's geoms and the last actions."""
        self.rules = rules
        self.setup = rules.setup
        self.model = m = rules.setup.model
        self.robot = rules.setup.robot
        self.spec = spec
        self.num_envs = num_envs
        self.action_dim = rules.action_dim
        self.per_frame = rules.per_frame
        self._data = mujoco.MjData(m)
        self._robot_geom = np.zeros(m.ngeom, bool)
        self._robot_geom[self.robot.geoms] = True
        self._prev = np.zeros((num_envs, self.action_dim))

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed`` (the rules' sampler).

        Raises:
            TaskError: the sampler cannot place the task's objects with this seed.
        """
        return self.rules.sample_qpos(seed)

    def reset(
        self, ids: list[int], states: np.ndarray | None, qpos: np.ndarray | None, spawned: bool
    ) -> None:
        """Sets envs ``ids`` to recorded integration states or to ``qpos`` held still."""
        b = self.batch
        b.reset(ids=ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        for k, i in enumerate(ids):
            if states is not None:
                b.state[i] = states[k]
            else:
                assert qpos is not None
                b.bind("qpos")[i] = qpos[k]
                b.bind("ctrl")[i] = self.rules.hold(qpos[k])
        b.forward(ids=ids)

    def load(self, i: int) -> mujoco.MjData:
        """Env ``i``'s current state in the scratch data, with kinematics and contacts."""
        d = self._data
        mujoco.mj_setState(self.model, d, self.batch.state[i], STATE_SPEC)
        mujoco.mj_forward(self.model, d)
        return d

    def advance(self, ids: list[int], actions: np.ndarray) -> None:
        """Simulates one frame of envs ``ids`` under their actions (len(ids), A)."""
        ctrl = self.rules.controls(self._prev[ids], actions)
        self.batch.rollout(self.per_frame, control=ctrl, ids=ids, record=())

    def end_frame(self, ids: list[int], actions: np.ndarray) -> None:
        """The frame's actions (len(ids), A) become the targets the next frame starts from."""
        self._prev[ids] = actions

    def observe(
        self,
        i: int,
        data: mujoco.MjData,
        obs: dict[str, np.ndarray],
        ep: Any,
        action: np.ndarray | None,
    ) -> Outcome | None:
        """Writes env ``i``'s observations but the images (``action``: the frame's, None at
        the episode's first observation); its episode's outcome once it ends (``ep``: its
        steps and step limit)."""
        m = self.model
        q, width, ee = robot_signals(m, data, self.robot)
        obs["observation.state"][i, :7] = q
        obs["observation.state"][i, 7] = width
        obs["observation.ee_pose"][i] = ee
        if self.spec.env_state:
            own = getattr(self.rules, "env_state", None)  # a task's own environment state
            if own is not None:
                obs["observation.environment_state"][i] = own(data)
            else:
                bodies = self.rules.env_state_bodies
                obs["observation.environment_state"][i] = object_poses(data, bodies)
        depth = robot_penetration(m, data, self._robot_geom, self.rules.allowed)
        if action is None:
            self._prev[i, :7] = q
            self._prev[i, 7] = width
            self.rules.start(i, data, depth)
            return None
        return self.rules.update(i, data, depth, ep.steps, ep.limit)

    def renderer(self, cameras: tuple[str, ...]) -> FrameRenderer:
        """A renderer of ``cameras`` at the spec's size (depth in millimetres)."""
        s = self.spec
        cfg = RecordConfig(s.fps, s.width, s.height, cameras, "uint16_mm")
        return FrameRenderer(self.model, cfg)

    def draw(
        self, renderer: FrameRenderer, data: mujoco.MjData, i: int = -1
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB, depth) of the state in ``data`` (env ``i``'s, loaded)."""
        rgbs, depths = renderer.render(data)
        return dict(zip(renderer.cfg.cameras, zip(rgbs, depths, strict=True), strict=True))

    def step_info(self) -> dict[str, np.ndarray]:
        """Nothing the task adds to a step's info."""
        return {}

    def result(self, i: int) -> dict[str, Any]:
        """Nothing the task adds to an episode's result."""
        return {}

    @property
    def last_actions(self) -> np.ndarray:
        """(n, A): each env's last action (at a reset: the arm and hand where they are)."""
        return self._prev.copy()
