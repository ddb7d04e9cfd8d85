"""The articulated tasks in the evaluation env: how an episode starts, how an action drives the
arm, when an episode ends.

The env steps the task's worlds together on one ``mujoco.batch`` as the fixed task's does
(:class:`~factory.policy.batch_sim.BatchSim`) with :class:`ArticulatedRules`, whose
:meth:`~ArticulatedRules.env_state` makes ``observation.environment_state`` the part's joint,
share of range and handle (seen from the robot) instead of two objects' poses:

* reset: the demos' start of a seed (:meth:`~factory.tasks.articulated.plan.
  ArticulatedPlanner.start_and_goal` with ``np.random.default_rng(seed)``: the part closed for
  ``open``, 60-100 % of its span open for ``close``; the arm at the tucked start posture, the
  hand open), or a recorded state (replay);
* step: the fixed task's action and controller (8: desired arm joints rad + gripper command m,
  first-order hold over the frame with the velocity lead:
  :meth:`~factory.tasks.pick_place.env.PickPlaceRules.controls`);
* termination: success (the demos' check, :func:`~factory.tasks.articulated.execute.
  check_outcome`: the joint past the threshold, the hand open and 5 cm from the handle, no
  deep collision), tested every frame; a robot contact with the scene other than the part
  deeper than 2 cm ends the episode (``collision``); truncation after the step limit with the
  check's reason (``not_open``, ``not_closed``, ``not_released``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN, PANDA
from factory.tasks.articulated.execute import (
    COLLISION_DEPTH,
    Watch,
    allowed_geoms,
    check_outcome,
    env_state,
    grasp_distance,
)
from factory.tasks.articulated.plan import ArticulatedSetup, grasps_in_link, initial_state
from factory.tasks.pick_place.objects import Outcome
from factory.tasks.pick_place.plan import targets_to_ctrl

__all__ = [
    "ACTION_DIM",
    "CAMERAS",
    "OBSERVATIONS",
    "ArticulatedRules",
    "action_bounds",
]

ACTION_DIM = 8
"""The action: desired arm joints (7, rad) and the gripper command (m)."""
OBSERVATIONS: dict[str, tuple[tuple[int, ...], str]] = {
    "observation.state": ((8,), "float32"),
    "observation.ee_pose": ((7,), "float32"),
}
"""The env's observations besides the cameras' and the environment state."""
CAMERAS = ("left", "right", "wrist")
"""The cameras the env can observe, in order."""


def action_bounds() -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest action (8,) float32: arm joints within the Panda's limits (rad), the
    gripper command from squeezing shut to open (m)."""
    low = np.array([*PANDA.q_min, GRIP_CLOSED], np.float32)
    high = np.array([*PANDA.q_max, GRIP_OPEN], np.float32)
    return low, high


class ArticulatedRules:
    """The task's side of the env for ``num_envs`` episodes of one scene (module docstring).

    Args:
        setup: the scene with the robot (:func:`~factory.tasks.articulated.demos.
            scene_planner`).
        planner: its planner (the start of a seed).
        num_envs: episodes run at once.
        fps: frames (actions) per second (Hz).
        interpolate: first-order hold of the arm target over a frame with velocity lead.
    """

    action_dim: int = ACTION_DIM

    def __init__(
        self, setup: ArticulatedSetup, planner: Any, num_envs: int, fps: float, interpolate: bool
    ) -> None:
        m = setup.model
        self.setup = setup
        self.planner = planner
        self.model = m
        self.robot = setup.robot
        self.fps = fps
        self.interpolate = interpolate
        self.per_frame = max(1, round(1.0 / (fps * float(m.opt.timestep))))
        self.allowed = allowed_geoms(setup)
        """Geoms (ngeom,) a robot contact with is no collision: the articulated object's."""
        self.env_state_bodies = (setup.body, setup.body)
        """Unused: the env observes :meth:`env_state`, not body poses."""
        self.grasp = grasps_in_link(setup.part)[0]
        self._watch = [Watch() for _ in range(num_envs)]

    def env_state(self, data: mujoco.MjData) -> np.ndarray:
        """``observation.environment_state`` (11,): the part's joint position (rad or m), its
        share of the range and its handle in the robot's base frame
        (:func:`~factory.tasks.articulated.execute.env_state`)."""
        return env_state(self.setup, data)

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' start of that seed."""
        q_start, _ = self.planner.start_and_goal(np.random.default_rng(seed))
        return initial_state(self.setup, q_start)

    def hold(self, qpos: np.ndarray) -> np.ndarray:
        """Controls (nu,) that hold the arm and the hand of ``qpos`` where they are."""
        robot = self.robot
        width = float(np.sum(np.abs(qpos[robot.finger_qpos])))
        a = np.concatenate([qpos[robot.qpos], [width]])
        return targets_to_ctrl(self.model, robot, a[None, :7], np.zeros((1, 7)), a[7:])[0]

    def controls(self, prev: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Per-physics-step controls (n, per_frame, nu) of one frame of actions (n, 8) after
        the previous ones (n, 8), as the fixed task's env."""
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

    def start(self, i: int, data: mujoco.MjData, depth: float) -> None:
        """Begins env ``i``'s episode at the state in ``data``."""
        self._watch[i] = Watch(worst=depth)

    def _outcome(self, i: int, data: mujoco.MjData) -> Outcome:
        robot = self.robot
        fingers = data.qpos[robot.finger_qpos]
        return check_outcome(
            self.setup,
            float(data.qpos[self.setup.qadr]),
            self._watch[i],
            grasp_distance(self.setup, data, self.grasp),
            float(fingers[0] - fingers[1]),
        )

    def update(
        self, i: int, data: mujoco.MjData, depth: float, steps: int, limit: int
    ) -> Outcome | None:
        """Env ``i``'s episode after a frame: its outcome when it ends, else None."""
        w = self._watch[i]
        w.worst = max(w.worst, depth)
        if w.worst > COLLISION_DEPTH:
            return self._outcome(i, data)
        out = self._outcome(i, data)
        if out.success or steps >= limit:
            return out
        return None
