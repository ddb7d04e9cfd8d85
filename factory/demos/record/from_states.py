"""A task's episode recorded from the states the GPU simulated: the hook between the ``episode``
execution's GPU physics (:mod:`factory.demos.execute.plan_worlds`, task-agnostic) and a task
that simulates its episodes itself.

A :class:`~factory.demos.record.scene.SimulatingScene` whose episodes can run on MuJoCo Warp
returns a :class:`StatesRecorder` (:meth:`~factory.demos.record.scene.SimulatingScene.
states_recorder`): which geoms its robot may touch, which physics steps of a plan its success
check reads between frames (*probes*), and how its recording (per-frame signals, actions,
``env_state``) and verdict follow from the recorded states, on the host, with the same
functions as its CPU simulation. :class:`WorldPlan` (what a world runs) and :class:`PlanRun`
(what comes back) are the types between the two.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["PlanRun", "StatesRecorder", "WorldPlan"]


@dataclass(frozen=True)
class WorldPlan:
    """What a world runs: an open-loop plan.

    Attributes:
        qpos0: (nq,) the initial configuration.
        ctrl: (T, nu) the controls, one row per physics step.
        probes: physics steps (0-based, each < T) after which the configuration is kept.
    """

    qpos0: np.ndarray
    ctrl: np.ndarray
    probes: tuple[int, ...] = ()


@dataclass
class PlanRun:
    """A plan's run on the device.

    Attributes:
        state: (F, nstate) the MuJoCo integration state (``mj_getState`` layout, the CPU
            executor's ``STATE_SPEC``) at each recorded frame: frame 0 the initial state, frame
            ``f`` after ``min(f * per_frame, T)`` steps rounded up to whole periods, F =
            ``ceil(T / per_frame) + 1``.
        probe_qpos: (P, nq) the configuration after each probe step, in the plan's order.
        worst: deepest penetration (m, >= 0) of a robot geom into a geom it may not touch,
            over the recorded frames.
        overflow: MuJoCo Warp's overflow bits of the world (0: its buffers held; otherwise the
            run is not to be trusted).
    """

    state: np.ndarray
    probe_qpos: np.ndarray
    worst: float = 0.0
    overflow: int = 0


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
        rebuilt from ``run`` (:class:`PlanRun`: the states
        per frame, the probes' configurations, the deepest penetration) with the settings
        ``rec_cfg``."""
