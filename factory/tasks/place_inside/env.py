"""``task=place_inside`` in the evaluation env: how an episode starts, how an action drives the
arm, when an episode ends.

The env steps the task's worlds together on one ``mujoco.batch`` as the articulated tasks' do
(:class:`~factory.policy.batch_sim.BatchSim`) with :class:`PlaceInsideRules`, the articulated
tasks' rules (:class:`~factory.tasks.articulated.env.ArticulatedRules`: the fixed task's action
and controller) with this task's start, environment state and success check:

* reset: the demos' start of a seed (:meth:`~factory.tasks.place_inside.plan.
  PlaceInsidePlanner.initial_qpos`: the part closed, the object on the container's top), or a
  recorded state (replay);
* ``observation.environment_state`` (9): the part's joint and share of range, the object's
  position and quaternion (:func:`~factory.tasks.place_inside.execute.env_state`);
* termination: success (:func:`~factory.tasks.place_inside.execute.check_outcome`: the object
  in the interior, the part closed, the hand open and away), tested every frame; a robot
  contact with the scene other than the container and the object deeper than 2 cm ends the
  episode (``collision``); truncation after the step limit with the check's reason.
  The lift and place watches of the demos are not kept in the env: ``slip`` and ``dropped``
  read as ``not_inside``.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from factory.tasks.articulated.env import ACTION_DIM, CAMERAS, OBSERVATIONS, ArticulatedRules
from factory.tasks.articulated.env import action_bounds as _bounds
from factory.tasks.pick_place.objects import Outcome
from factory.tasks.place_inside.execute import Watch, allowed, check_outcome, env_state
from factory.tasks.place_inside.plan import PlaceInsidePlanner, PlaceInsideSetup

__all__ = ["ACTION_DIM", "CAMERAS", "OBSERVATIONS", "PlaceInsideRules", "action_bounds"]


def action_bounds() -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest action (8,) float32 (the articulated tasks')."""
    return _bounds()


class PlaceInsideRules(ArticulatedRules):
    """The task's side of the env for ``num_envs`` episodes of one scene (module docstring).

    Args:
        setup: the scene with the robot (:func:`~factory.tasks.place_inside.demos.
            scene_planner`).
        planner: its planner (the start of a seed).
        num_envs: episodes run at once.
        fps: frames (actions) per second (Hz).
        interpolate: first-order hold of the arm target over a frame with velocity lead.
    """

    def __init__(
        self,
        setup: PlaceInsideSetup,
        planner: PlaceInsidePlanner,
        num_envs: int,
        fps: float,
        interpolate: bool,
    ) -> None:
        super().__init__(setup.art, planner, num_envs, fps, interpolate)
        self.inside_setup = setup
        self.setup = setup  # type: ignore[assignment]
        self.allowed = allowed(setup)

    def env_state(self, data: mujoco.MjData) -> np.ndarray:
        """``observation.environment_state`` (9,)."""
        return env_state(self.inside_setup, data)

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' start of that seed.

        Raises:
            TaskError: no spot for the object on the container's top.
        """
        planner: Any = self.planner
        return np.asarray(planner.initial_qpos(seed))

    def _outcome(self, i: int, data: mujoco.MjData) -> Outcome:
        w = self._watch[i]
        return check_outcome(self.inside_setup, data, Watch(worst=w.worst), self.grasp)
