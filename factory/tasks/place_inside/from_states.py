"""A ``task=place_inside`` episode's recording and verdict from the states the GPU simulated
(``demos.episode_physics``: :mod:`factory.demos.execute.plan_worlds` steps the plans on MuJoCo
Warp and returns each frame's integration state).

As the articulated tasks' (:mod:`factory.tasks.articulated.from_states`): the per-frame signals,
actions and ``env_state`` (F, 9) are rebuilt on the host from the recorded states with MuJoCo's
kinematics; the success check is the CPU path's
(:func:`~factory.tasks.place_inside.execute.check_outcome`), with the two readings
:func:`~factory.tasks.place_inside.execute.execute_episode` takes between frames from the
configurations kept after their steps (the plan's probes): the object's height above its start
at the end of the lift (``slip`` below :data:`~factory.tasks.place_inside.execute.LIFTED`), and
its distance from its place pose when the hand opens (``dropped``).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from factory.demos.record.from_states import PlanRun, StatesRecorder
from factory.tasks.articulated.from_states import frames_from_states
from factory.tasks.articulated.record import Recording
from factory.tasks.place_inside.execute import (
    ENV_STATE_DIM,
    Watch,
    allowed,
    check_outcome,
    env_state,
)
from factory.tasks.place_inside.plan import PlaceInsidePlan, PlaceInsideSetup

__all__ = ["PlaceInsideFromStates"]


class PlaceInsideFromStates(StatesRecorder):
    """``place_inside``: an episode recorded from its GPU-simulated states (module docstring).

    Args:
        setup: the scene (the model the device simulated).
    """

    def __init__(self, setup: PlaceInsideSetup) -> None:
        self.setup = setup
        m = setup.model
        self.robot_geom = np.zeros(m.ngeom, bool)
        self.robot_geom[setup.art.robot.geoms] = True
        self.allowed = allowed(setup)
        self._data = mujoco.MjData(m)

    def probes(self, plan: PlaceInsidePlan) -> tuple[int, ...]:
        """The last step of the lift and the step before the hand opens at the place (as
        :func:`~factory.tasks.place_inside.execute.execute_episode` reads them)."""
        steps = len(plan.ctrl)
        return (
            plan.phases.get("transport", steps) - 1,
            plan.phases.get("place_release", steps) - 1,
        )

    def recording(self, plan: PlaceInsidePlan, run: PlanRun, rec_cfg: Any) -> Recording:
        """The recording (``env_state`` (F, 9)) and its outcome."""
        setup = self.setup
        rec, data = frames_from_states(
            setup.model,
            setup.art.robot,
            run.state,
            plan.targets,
            rec_cfg,
            lambda d: env_state(setup, d),
            ENV_STATE_DIM,
            self._data,
        )
        a = setup.pick_adr
        lift, place = run.probe_qpos
        watch = Watch(
            worst=run.worst,
            lifted=float(lift[a + 2]) - float(plan.qpos0[a + 2]),
            off_place=float(np.linalg.norm(place[a : a + 3] - plan.pose_obj_place[:3, 3])),
        )
        rec.outcome = check_outcome(setup, data, watch, plan.pose_tool_in_link_close)
        return rec
