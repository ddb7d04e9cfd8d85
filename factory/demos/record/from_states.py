"""A task's episode recorded from the states the GPU simulated: the hook between the ``episode``
execution's GPU physics (:mod:`factory.demos.execute.plan_worlds`, task-agnostic) and a task
that simulates its episodes itself.

A :class:`~factory.demos.record.scene.SimulatingScene` whose episodes can run on MuJoCo Warp
returns a :class:`StatesRecorder` (:meth:`~factory.demos.record.scene.SimulatingScene.
states_recorder`): which geoms its robot may touch, which physics steps of a plan its success
check reads between frames (*probes*), and how its recording (per-frame signals, actions,
``env_state``) and verdict follow from the recorded states, on the host, with the same
functions as its CPU simulation.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from factory.demos.execute.plan_worlds import PlanRun

__all__ = ["StatesRecorder"]


class StatesRecorder(ABC):
    """A scene's recording of an episode from its simulated states.

    Attributes:
        robot_geom: (ngeom,) bool, the robot's geoms.
        allowed: (ngeom,) bool, the geoms a robot contact with is no collision (the
            penetration the verdict reads is the deepest contact with any other).
    """

    robot_geom: np.ndarray
    allowed: np.ndarray

    @abstractmethod
    def probes(self, plan: Any) -> tuple[int, ...]:
        """The physics steps of ``plan`` (0-based) after which its success check reads the
        configuration (``qpos``), in the order :meth:`recording` reads them."""

    @abstractmethod
    def recording(self, plan: Any, run: PlanRun, rec_cfg: Any) -> Any:
        """The task's recording of ``plan`` (no images; ``state`` the run's) and its outcome,
        rebuilt from ``run`` (:class:`~factory.demos.execute.plan_worlds.PlanRun`: the states
        per frame, the probes' configurations, the deepest penetration) with the settings
        ``rec_cfg``."""
