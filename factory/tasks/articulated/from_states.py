"""An articulated episode's recording and verdict from the states the GPU simulated
(``demos.episode_physics=gpu``: :mod:`factory.demos.execute.plan_worlds` steps the plans on
MuJoCo Warp and returns each frame's integration state).

The host rebuilds what :func:`~factory.tasks.articulated.execute.record_plan` records while it
simulates, from each recorded state with MuJoCo's kinematics (``mj_kinematics``: positions
only, no dynamics): the robot's signals, the action (the plan's targets at the end of each
frame) and ``env_state``; the success check is the CPU path's
(:func:`~factory.tasks.articulated.execute.check_outcome`), with the hand-to-grasp distance at
the end of the pull read from the configuration kept after that step (the plan's one probe)
and the deepest robot penetration from the device's contacts of every frame.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from factory.demos.record.from_states import PlanRun, StatesRecorder
from factory.demos.record.payload import STATE_SPEC
from factory.robots.panda import RobotIndex
from factory.tasks.articulated.execute import (
    ENV_STATE_DIM,
    Watch,
    allowed_geoms,
    check_outcome,
    env_state,
    grasp_distance,
)
from factory.tasks.articulated.plan import ArticulatedPlan, ArticulatedSetup
from factory.tasks.articulated.record import RecordConfig, Recording
from factory.tasks.articulated.record import robot_signals as _signals

__all__ = ["ArticulatedFromStates", "frames_from_states"]


def frames_from_states(
    model: mujoco.MjModel,
    robot: RobotIndex,
    states: np.ndarray,
    targets: np.ndarray,
    cfg: RecordConfig,
    observe: Callable[[mujoco.MjData], np.ndarray],
    env_dim: int,
    data: mujoco.MjData | None = None,
) -> tuple[Recording, mujoco.MjData]:
    """The recording :func:`~factory.tasks.articulated.execute.record_plan` makes of a plan,
    from its recorded states (no images, outcome unset).

    Args:
        states: (F, nstate) the integration state of each frame (``STATE_SPEC``).
        targets: (T, 8) the plan's arm joint targets and gripper command per physics step.
        observe: ``env_state`` of a frame, (env_dim,), from ``data`` with current kinematics.
        data: scratch data (made when None).

    Returns:
        the recording and ``data`` holding the last frame's state with its kinematics.
    """
    if data is None:
        data = mujoco.MjData(model)
    n = len(states)
    per_frame = max(1, round(1.0 / (cfg.fps * float(model.opt.timestep))))
    steps = len(targets)
    rec = Recording(
        time=np.arange(n) / cfg.fps,
        state=np.asarray(states),
        joint_pos=np.zeros((n, 7)),
        gripper=np.zeros((n, 1)),
        ee_pose=np.zeros((n, 7)),
        action=np.zeros((n, 8)),
        env_state=np.zeros((n, env_dim)),
    )
    for f in range(n):
        mujoco.mj_setState(model, data, states[f], STATE_SPEC)
        mujoco.mj_kinematics(model, data)
        q, width, ee = _signals(model, data, robot)
        rec.joint_pos[f] = q
        rec.gripper[f, 0] = width
        rec.ee_pose[f] = ee
        rec.env_state[f] = observe(data)
        rec.action[f] = targets[min((f + 1) * per_frame, steps) - 1]
    return rec, data


class ArticulatedFromStates(StatesRecorder):
    """``open`` / ``close``: an episode recorded from its GPU-simulated states (module
    docstring).

    Args:
        setup: the scene (the model the device simulated).
    """

    def __init__(self, setup: ArticulatedSetup) -> None:
        self.setup = setup
        m = setup.model
        self.robot_geom = np.zeros(m.ngeom, bool)
        self.robot_geom[setup.robot.geoms] = True
        self.allowed = allowed_geoms(setup)
        self._data = mujoco.MjData(m)

    def probes(self, plan: ArticulatedPlan) -> tuple[int, ...]:
        """The last step of the pull (the step before the release), where
        :func:`~factory.tasks.articulated.execute.execute_episode` reads the slip."""
        return (plan.phases.get("release", len(plan.ctrl)) - 1,)

    def recording(self, plan: ArticulatedPlan, run: PlanRun, rec_cfg: Any) -> Recording:
        """The recording (``env_state`` (F, 11)) and its outcome
        (:func:`~factory.tasks.articulated.execute.check_outcome`)."""
        setup, data = self.setup, self._data
        m = setup.model
        rec, data = frames_from_states(
            m,
            setup.robot,
            run.state,
            plan.targets,
            rec_cfg,
            lambda d: env_state(setup, d),
            ENV_STATE_DIM,
            data,
        )
        q_end = float(data.qpos[setup.qadr])
        released = grasp_distance(setup, data, plan.pose_tool_in_link)
        watch = Watch(worst=run.worst)
        data.qpos[:] = run.probe_qpos[0]
        mujoco.mj_kinematics(m, data)
        watch.slip = grasp_distance(setup, data, plan.pose_tool_in_link)
        rec.outcome = check_outcome(setup, q_end, watch, released, float(rec.gripper[-1, 0]))
        return rec
