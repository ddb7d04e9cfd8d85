"""The fixed-base pick-and-place task in the evaluation env: how an episode starts, how an
action drives the arm, and when an episode ends.

The env (:class:`~factory.policy.vector_env.PickPlaceVecEnv`) steps the task's worlds together
on one batch, as ``stage=demos`` executes the task's plans
(:class:`~factory.policy.batch_sim.BatchSim`: the simulation, the robot's signals, the
recording cameras, the objects' poses, the robot's contacts); :class:`PickPlaceRules` is what
it asks the task:

* reset: the demos' sampler (:func:`~factory.tasks.pick_place.plan.initial_configuration`) from
  a seed (:meth:`PickPlaceRules.sample_qpos`), the arm and hand held where they are
  (:meth:`PickPlaceRules.hold`);
* step: one action per env (8,) = desired arm joints (rad) + gripper command (m), held for one
  frame (``1 / fps`` s = ``per_frame`` physics steps). With ``interpolate`` (default) the arm
  target moves linearly from the previous action to this one over the frame and the
  controller adds the velocity lead the demos use (``kv/kp * (a - a_prev) * fps``); the
  recorded action of frame ``f`` is the demo's target at the end of frame ``f``, so this
  reproduces the demos' control closely. Without it the target jumps to the action at once
  (:meth:`PickPlaceRules.controls`);
* termination: success (the object in/on the target, released, at rest for 0.5 s, by
  :func:`~factory.tasks.pick_place.objects.check_success`), or a robot collision deeper than
  2 cm; truncation after the step limit, with the success check's failure reason
  (:meth:`PickPlaceRules.update`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN, PANDA
from factory.tasks.pick_place.objects import Outcome, Workspace, check_success
from factory.tasks.pick_place.plan import SceneSetup, initial_configuration, targets_to_ctrl

__all__ = [
    "ACTION_DIM",
    "CAMERAS",
    "COLLISION_DEPTH",
    "ENV_STATE_DIM",
    "LIFT_MIN",
    "OBSERVATIONS",
    "PickPlaceRules",
    "action_bounds",
]

ACTION_DIM = 8
"""The action: desired arm joints (7, rad) and the gripper command (m)."""
ENV_STATE_DIM = 14
"""``observation.environment_state``: pick object xyz (m) + quat wxyz, target xyz + quat wxyz."""
OBSERVATIONS: dict[str, tuple[tuple[int, ...], str]] = {
    "observation.state": ((8,), "float32"),
    "observation.ee_pose": ((7,), "float32"),
}
"""The env's observations besides the cameras' and the environment state: arm joints (rad) +
gripper opening (m); tool site position (m) + quaternion wxyz, world frame."""
CAMERAS = ("left", "right", "wrist")
"""The cameras the env can observe, in order."""
COLLISION_DEPTH = 0.02
"""A robot contact with the scene deeper than this (m) ends the episode (as the demos' check)."""
LIFT_MIN = 0.03
"""The object must have been lifted this high (m) before it can count as placed."""


def action_bounds() -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest action (8,) float32: arm joint targets within the Panda's limits
    (rad), the gripper command from squeezing shut to open (m)."""
    low = np.array([*PANDA.q_min, GRIP_CLOSED], np.float32)
    high = np.array([*PANDA.q_max, GRIP_OPEN], np.float32)
    return low, high


@dataclass
class _Progress:
    """What one running episode has done so far.

    Attributes:
        start_z, max_z: the pick object's height (m) at the start and its highest so far.
        worst: the deepest robot contact with the scene so far (m).
        history: the last frames' qpos, for the check that the object is at rest.
    """

    start_z: float = 0.0
    max_z: float = 0.0
    worst: float = 0.0
    history: deque[np.ndarray] = field(default_factory=deque)


class PickPlaceRules:
    """The task's side of the env for ``num_envs`` episodes of one scene (see the module
    docstring).

    Args:
        setup: the scene with the robot (:func:`factory.tasks.pick_place.demos.scene_planner`).
        planner: its planner (the sampler's workspace).
        num_envs: episodes run at once.
        fps: frames (actions) per second (Hz).
        interpolate: first-order hold of the arm target over a frame with velocity lead.
    """

    action_dim: int = ACTION_DIM

    def __init__(
        self, setup: SceneSetup, planner: Any, num_envs: int, fps: float, interpolate: bool
    ) -> None:
        m = setup.model
        self.setup = setup
        self.model = m
        self.robot = setup.robot
        self.ws: Workspace = planner.ws
        self.fps = fps
        self.interpolate = interpolate
        self.per_frame = max(1, round(1.0 / (fps * float(m.opt.timestep))))
        self.hold_frames = max(1, round(0.5 * fps))
        objs = setup.objects
        self.pick = m.body(objs.pick.id).id
        self.target = m.body(objs.target.id).id
        support = m.body(objs.support.id).id
        self.env_state_bodies = (self.pick, self.target)
        """The bodies whose poses are ``observation.environment_state``."""
        self.allowed = np.isin(m.geom_bodyid, [self.pick, self.target, support])
        """Geoms (ngeom,) a robot contact with is no collision: the task objects'."""
        self._inside_r = 0.5 * min(objs.target.dimensions.width, objs.target.dimensions.length)
        self._progress = [_Progress() for _ in range(num_envs)]

    # ---- reset and control
    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' sampler with
        ``np.random.default_rng(seed)``, as :meth:`EpisodePlanner.plan_episode` draws it.

        Raises:
            TaskError: the sampler finds no free spot for the objects with this seed.
        """
        return initial_configuration(self.setup, np.random.default_rng(seed), self.ws)

    def hold(self, qpos: np.ndarray) -> np.ndarray:
        """Controls (nu,) that hold the arm and the hand of ``qpos`` where they are."""
        robot = self.robot
        width = float(np.sum(np.abs(qpos[robot.finger_qpos])))
        a = np.concatenate([qpos[robot.qpos], [width]])
        return targets_to_ctrl(self.model, robot, a[None, :7], np.zeros((1, 7)), a[7:])[0]

    def controls(self, prev: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Per-physics-step controls (n, per_frame, nu) of one frame of actions (n, 8) after
        the previous ones (n, 8)."""
        pf, n = self.per_frame, len(actions)
        a = np.asarray(actions, np.float64)
        if self.interpolate:
            alpha = (np.arange(1, pf + 1) / pf)[None, :, None]
            arm = prev[:, None, :7] + (a[:, None, :7] - prev[:, None, :7]) * alpha
            vel = np.broadcast_to(((a[:, :7] - prev[:, :7]) * self.fps)[:, None], arm.shape)
        else:
            arm = np.broadcast_to(a[:, None, :7], (n, pf, 7))
            vel = np.zeros_like(arm)
        grip = np.repeat(a[:, 7], pf)
        ctrl = targets_to_ctrl(self.model, self.robot, arm.reshape(-1, 7), vel.reshape(-1, 7), grip)
        return ctrl.reshape(n, pf, -1)

    # ---- success and failure
    def start(self, i: int, data: mujoco.MjData, depth: float) -> None:
        """Begins env ``i``'s episode at the state in ``data`` (kinematics and contacts);
        ``depth``: the robot's deepest contact with the scene there (m)."""
        z = float(data.xpos[self.pick][2])
        self._progress[i] = _Progress(z, z, 0.0, deque(maxlen=self.hold_frames + 1))
        self._track(i, data, depth)

    def _track(self, i: int, data: mujoco.MjData, depth: float) -> _Progress:
        p = self._progress[i]
        p.max_z = max(p.max_z, float(data.xpos[self.pick][2]))
        p.worst = max(p.worst, depth)
        p.history.append(np.array(data.qpos))
        return p

    def update(
        self, i: int, data: mujoco.MjData, depth: float, steps: int, limit: int
    ) -> Outcome | None:
        """Env ``i``'s episode after a frame: its outcome when it ends (success, a collision,
        the step limit ``limit`` reached at ``steps`` frames), else None."""
        p = self._track(i, data, depth)
        if p.worst > COLLISION_DEPTH:
            return Outcome(False, "collision", self._outcome(p, data).details)
        horiz = float(np.linalg.norm(data.xpos[self.pick][:2] - data.xpos[self.target][:2]))
        settled = len(p.history) > self.hold_frames
        if settled and p.max_z - p.start_z >= LIFT_MIN and horiz < self._inside_r:
            out = self._outcome(p, data)
            if out.success:
                return Outcome(True, "", out.details)
        if steps >= limit:
            out = self._outcome(p, data)
            return Outcome(out.success, out.reason if not out.success else "", out.details)
        return None

    def _outcome(self, p: _Progress, data: mujoco.MjData) -> Outcome:
        return check_success(
            self.model,
            np.array(data.qpos),
            p.history[0],
            p.max_z,
            p.start_z,
            self.setup.objects,
            self.robot,
            p.worst,
        )
