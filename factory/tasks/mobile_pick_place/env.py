"""The mobile pick-and-place task in the evaluation env (``task=mobile_pick_place``): the
Panda on the Omron base, simulated one episode at a time as ``stage=demos`` simulates the task.

:class:`MobileSim` is the simulation behind :class:`~factory.policy.vector_env.PickPlaceVecEnv` for
this task; it runs ``n`` episodes of one scene with the demos' own pieces, so that what a policy
sees and does in it is what the dataset recorded:

* scene: :func:`factory.tasks.mobile_pick_place.demos.mobile_scene_planner`, the same set-up as
  ``stage=demos`` (the scene composed with the mobile robot, light floor objects in the base's
  way taken out, the same supports and the object where the scene puts it);
* reset: from a seed, the planner's own spawn (:meth:`MobilePlanner.initial_qpos`: seed ``s``
  starts where the demos' planner starts episode ``s``: base at a random free pose, arm
  stowed, hand closed), or a recorded MuJoCo integration state (replay);
* action (11,) as recorded: arm joint targets (7, rad), gripper command (m; 0.08 open,
  negative squeezes), base target x, y (m, world) and unwrapped yaw (rad), one per frame (``1 /
  fps`` s). The controller is the demos': :func:`~factory.tasks.pick_place.plan.targets_to_ctrl` for
  the arm and fingers, the base's position actuators with the planner's velocity lead. With
  ``interpolate`` (default) arm and base targets move linearly from the previous action over the
  frame with the velocity ``(a - a_prev) * fps`` as lead (the recorded action of frame ``f`` is the
  plan's target at the end of frame ``f``, so this first-order hold follows the plan's per-step
  targets closely); the gripper command is held;
* physics: one ``mujoco.MjData`` per episode stepped one physics step at a time as
  :func:`~factory.tasks.mobile_pick_place.execute.simulate` does, the deepest contact of the
  base and of the arm measured after every step
  (:func:`~factory.tasks.mobile_pick_place.execute.penetrations`);
* observations keyed like the dataset's features: ``observation.state`` (11: arm joints, finger
  opening, base x, y, yaw), ``observation.ee_pose`` (7: tool position + quaternion wxyz, world),
  ``subtask_index`` (1, int64), with ``env_state`` ``observation.environment_state`` (14: the
  pick object's and the place support's position + quaternion wxyz, world; the dataset's
  layout, :func:`~factory.tasks.pick_place.objects.object_poses`; asked for by state policies that
  read it, never by a perception policy, which predicts it), and per camera
  ``observation.images.<cam>`` /
  ``observation.depth.<cam>`` drawn by the demos'
  :class:`~factory.tasks.mobile_pick_place.execute.MobileRenderer` from the frame's state set into a
  fresh ``MjData`` (as ``render_frames``: the same images for the same state; fisheye images are
  ``width`` square);
* sub-tasks (``navigate_to_pick``, ``pick``, ``navigate_to_place``, ``place``): the env's own
  check of each sub-task's end condition, read from the simulation (:class:`SubtaskRule`), not
  the policy's prediction (the policies predict no done flag). The demos end a drive when the
  base has arrived and rested ``settle`` s, the pick when the arm holds the lifted object in
  its carry posture; the env ends ``navigate_to_pick`` when the base has rested ``settle`` s
  (measured speed and commanded target still) with the object within the arm's reach,
  ``pick`` when the object is held, lifted >= 3 cm and the tool is near the carry position
  (still arm command), ``navigate_to_place`` when the base has rested with the place
  support's top within reach; ``place`` ends with success. A policy's commands never stand
  as still as a plan's, and it starts the next sub-task as soon as it thinks the last one is
  done (its action chunk spans the switch), so a sub-task also ends when the policy begins
  the next one the way every demo begins it, with the same conditions on where the robot is:
  ``navigate_to_pick`` when the hand opens (the demos drive with it closed and open it first
  thing in the pick) with the base slow and the object within reach; ``pick`` when the arm
  has settled (measured joint speeds) with the lifted object held in the carry posture;
  ``navigate_to_place`` when the arm command starts to move (the place begins) with the base
  slow and the support within reach;
* success: the demos' check (:func:`~factory.tasks.mobile_pick_place.execute.mobile_outcome`:
  the object on the place support, released, moved < 5 mm over the last 0.5 s, the base and
  the arm never deeper than 2 cm in anything), tested every frame once the object is over the
  support;
* failures: ``base_collision`` / ``collision`` (a contact deeper than 2 cm ends the episode),
  ``drop`` (the object left the hand while carrying it, for 0.25 s), and at the step limit
  ``nav_timeout`` (still in a navigation sub-task) or the success check's reason (``slip``,
  ``not_on_target``, ``not_released``, ``unstable``).

Frames: world frame (m, rad); a base pose is the footprint centre's (x, y) and the yaw.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from factory.demos.record.payload import STATE_SPEC
from factory.nav import BASE_COLLISION
from factory.nav.task_poses import ARM_X, PICK_REACH, PLACE_REACH
from factory.robots.mobile_panda import STOW_FINGERS
from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN, PANDA
from factory.tasks.mobile_pick_place.dataset import SUBTASK_KEY
from factory.tasks.mobile_pick_place.execute import (
    MobileRecordConfig,
    MobileRenderer,
    mobile_outcome,
    penetrations,
)
from factory.tasks.mobile_pick_place.scene import (
    ALL_CAMERAS,
    CARRY_TOOL,
    SUBTASKS,
    MobileSetup,
    body_box,
)
from factory.tasks.pick_place.dataset import ENV_STATE_KEY
from factory.tasks.pick_place.objects import Outcome, object_poses
from factory.tasks.pick_place.plan import targets_to_ctrl

__all__ = [
    "ACTION_DIM",
    "COLLISION_DEPTH",
    "DROP",
    "FAILURES",
    "LIFT_MIN",
    "NAV_TIMEOUT",
    "OBSERVATIONS",
    "STATE_DIM",
    "SUBTASK_KEY",
    "SUBTASK_RULE",
    "MobileSim",
    "SubtaskRule",
    "action_bounds",
    "instruction",
]

ACTION_DIM = 11
"""The mobile action: arm joints (7, rad), gripper (m), base x, y (m) and yaw (rad)."""
STATE_DIM = 11
"""``observation.state``: arm joints (7), finger opening (m), base x, y (m), yaw (rad)."""
OBSERVATIONS: dict[str, tuple[tuple[int, ...], str]] = {
    "observation.state": ((STATE_DIM,), "float32"),
    "observation.ee_pose": ((7,), "float32"),
    SUBTASK_KEY: ((1,), "int64"),
}
"""The env's observations besides the cameras': the state, the tool pose (position m +
quaternion wxyz, world frame) and the sub-task the env is in."""
COLLISION_DEPTH = 0.02
"""A contact of the base or the arm deeper than this (m) ends the episode (the demos' check)."""
LIFT_MIN = 0.03
"""The object must have been lifted this high (m) (the demos' check)."""
NAV_TIMEOUT = "nav_timeout"
DROP = "drop"
FAILURES = (BASE_COLLISION, "collision", DROP, NAV_TIMEOUT, "slip", "not_on_target")
"""Failure reasons of the env (and the success check's ``not_released``, ``unstable``)."""
TERMINAL: tuple[str, ...] = (DROP, BASE_COLLISION, "collision")
"""Failures that end an episode as terminated, even on its last frame."""
SUBTASK_RULE = (
    "the env's own check (factory.tasks.mobile_pick_place.env.SubtaskRule): a drive ends when "
    "the base has rested 0.2 s within reach of the object / of the place support's top, or "
    "when the next sub-task begins there with the base slow (the hand opens / the arm moves); "
    "the pick when the object is held, lifted >= 3 cm and the tool is in the carry posture with "
    "the arm's command still or the arm settled"
)
"""How the env ends sub-tasks, in words (an evaluation's ``results.json``)."""


def action_bounds() -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest action (11,) float32: arm joint targets within the Panda's limits
    (rad), the gripper command from squeezing shut to open (m), the base target (x, y m,
    unwrapped yaw rad) unbounded."""
    low = np.array([*PANDA.q_min, GRIP_CLOSED, -np.inf, -np.inf, -np.inf], np.float32)
    high = np.array([*PANDA.q_max, GRIP_OPEN, np.inf, np.inf, np.inf], np.float32)
    return low, high


def instruction(setup: MobileSetup) -> str:
    """The task instruction the mobile demos record for a scene."""
    scene, objs = setup.scene, setup.objects
    if scene.task is not None and scene.task.instruction:
        return str(scene.task.instruction)
    return f"pick up the {objs.pick.category} and put it on the {objs.place_support.category}"


@dataclass(frozen=True)
class SubtaskRule:
    """When the env ends a sub-task (see the module docstring).

    Attributes:
        settle: the base must rest this long (s) to end a drive (the demos' pause after it).
        rest_speed: base speed (m/s) below which it rests; rest_turn: yaw rate (rad/s).
        still_command: a target change (m or rad per frame) below which the command is still
            (the drives of the demos stop for a frame or two between the straight pieces of
            their paths; these stops are shorter than ``settle``).
        moved: the base counts as having driven after this distance (m) from where the
            sub-task began; a drive also ends without it after ``wait`` s in the sub-task.
        wait: see ``moved`` (s); a base resting this long ends a drive whatever its command
            does (a policy's target may jitter by more than ``still_command``).
        reach_margin: added to the reach of the arm (m) when judging "within reach".
        carry_tol: distance (m) of the tool from the carry position (in the base frame) that
            counts as the carry posture.
        drop_after: the object out of the hand this long (s) while carrying it is a ``drop``.
        open_grip: a gripper command above this (m) opens the hand: a policy has begun the pick.
        slow_speed: base speed (m/s) below which a policy's base counts as arrived when it
            begins the next sub-task; slow_turn: its yaw rate (rad/s).
        arm_rest: measured arm joint speeds (rad/s) below which the arm has settled.
        arm_move: commanded arm joint speed (rad/s) above which the arm moves.
    """

    settle: float = 0.2
    rest_speed: float = 0.02
    rest_turn: float = 0.05
    still_command: float = 1e-4
    moved: float = 0.05
    wait: float = 1.0
    reach_margin: float = 0.1
    carry_tol: float = 0.12
    drop_after: float = 0.25
    open_grip: float = 0.04
    slow_speed: float = 0.1
    slow_turn: float = 0.3
    arm_rest: float = 0.1
    arm_move: float = 0.2


@dataclass
class _Progress:
    """What one running episode has done so far: the object's heights, the states of the last
    0.5 s, its sub-tasks and the deepest contacts of the base and the arm."""

    start_z: float = 0.0
    max_z: float = 0.0
    history: deque[np.ndarray] = field(default_factory=deque)
    subtask: int = 0
    completed: int = 0
    switches: list[int] = field(default_factory=list)
    sub_start_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sub_frames: int = 0
    rest: int = 0
    rest_long: int = 0
    free: int = 0
    carry_z: float | None = None
    worst_base: float = 0.0
    worst_arm: float = 0.0


class MobileSim:
    """``num_envs`` mobile pick-and-place episodes of one scene (see the module docstring).

    Args:
        setup: the scene with the mobile robot (
            :func:`~factory.tasks.mobile_pick_place.demos.mobile_scene_planner`).
        planner: its planner (the spawn rule, and the privileged agent).
        num_envs: episodes run at once (stepped one after the other).
        spec: what to observe (:class:`~factory.policy.obs_spec.ObsSpec`).
        interpolate: first-order hold of the arm and base targets over a frame.
        rule: when sub-tasks end.
    """

    action_dim: int = ACTION_DIM
    terminal: tuple[str, ...] = TERMINAL
    video_cameras: tuple[str, ...] = ALL_CAMERAS

    def __init__(
        self,
        setup: MobileSetup,
        planner: Any,
        num_envs: int,
        spec: Any,
        interpolate: bool = True,
        rule: SubtaskRule | None = None,
    ) -> None:
        self.setup = setup
        self.planner = planner
        self.model = m = setup.model
        self.robot = robot = setup.robot
        self.spec = spec
        self.num_envs = num_envs
        self.interpolate = interpolate
        self.rule = rule or SubtaskRule()
        fps = spec.fps
        self.per_frame = max(1, round(1.0 / (fps * float(m.opt.timestep))))
        self.hold_frames = max(1, round(0.5 * fps))
        self.settle_frames = max(1, round(self.rule.settle * fps))
        self.wait_frames = max(1, round(self.rule.wait * fps))
        self.drop_frames = max(1, round(self.rule.drop_after * fps))
        self._datas = [mujoco.MjData(m) for _ in range(num_envs)]
        self._view = mujoco.MjData(m)
        self._scratch = mujoco.MjData(m)
        self._state = np.zeros(mujoco.mj_stateSize(m, STATE_SPEC))
        base_geom = np.zeros(m.ngeom, bool)
        base_geom[robot.base_geoms] = True
        arm_geom = np.zeros(m.ngeom, bool)
        arm_geom[robot.geoms] = True
        arm_geom &= ~base_geom
        self._base_geom, self._arm_geom = base_geom, arm_geom
        objs = setup.objects
        self.pick = m.body(objs.pick.id).id
        self.place_support = m.body(objs.place_support.id).id
        supports = [m.body(objs.pick_support.id).id, self.place_support]
        self._base_allowed = np.isin(m.geom_bodyid, [self.pick])
        self._arm_allowed = np.isin(m.geom_bodyid, [self.pick, *supports])
        self._robot_body = np.zeros(m.nbody, bool)
        self._robot_body[robot.bodies] = True
        jnt = int(m.body_jntadr[self.pick])
        self._obj_adr = int(m.jnt_qposadr[jnt])
        cb = robot.ctrl_base
        self._base_lead = -m.actuator_biasprm[cb, 2] / m.actuator_gainprm[cb, 0]
        kin = mujoco.MjData(m)
        mujoco.mj_kinematics(m, kin)
        self._place_box = body_box(m, kin, self.place_support)
        self._progress = [_Progress() for _ in range(num_envs)]
        self._prev = np.zeros((num_envs, ACTION_DIM))

    # ---- reset
    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' planner's spawn
        (:meth:`MobilePlanner.initial_qpos`).

        Raises:
            TaskError: no free spawn pose with this seed, or the base cannot work here.
        """
        return np.asarray(self.planner.initial_qpos(int(seed)))

    def reset(
        self, ids: list[int], states: np.ndarray | None, qpos: np.ndarray | None, spawned: bool
    ) -> None:
        """Sets envs ``ids`` to recorded integration states, or to ``qpos`` (arm, fingers and
        base at rest there; ``spawned``: the planner's spawns, hand closed)."""
        m, robot = self.model, self.robot
        for k, i in enumerate(ids):
            d = self._datas[i]
            mujoco.mj_resetData(m, d)
            if states is not None:
                mujoco.mj_setState(m, d, np.asarray(states[k], np.float64), STATE_SPEC)
                self._prev[i, :7] = d.ctrl[robot.ctrl_arm]
                fingers = d.qpos[robot.finger_qpos]
                self._prev[i, 7] = float(fingers[0] - fingers[1])
                self._prev[i, 8:] = d.ctrl[robot.ctrl_base]
            else:
                assert qpos is not None
                d.qpos[:] = qpos[k]
                arm = np.asarray(qpos[k][robot.qpos], np.float64)
                grip = (
                    STOW_FINGERS if spawned else float(np.sum(np.abs(qpos[k][robot.finger_qpos])))
                )
                base = np.asarray(qpos[k][robot.base_qpos], np.float64)
                self._prev[i] = np.concatenate([arm, [grip], base])
                d.ctrl[:] = self._ctrl(self._prev[i][None], np.zeros((1, ACTION_DIM)))[0]
            mujoco.mj_forward(m, d)

    def load(self, i: int) -> mujoco.MjData:
        """Env ``i``'s current state in a fresh view (``mj_setState`` + ``mj_forward``), as the
        recording draws and measures its frames."""
        m, v = self.model, self._view
        mujoco.mj_getState(m, self._datas[i], self._state, STATE_SPEC)
        mujoco.mj_setState(m, v, self._state, STATE_SPEC)
        mujoco.mj_forward(m, v)
        return v

    # ---- stepping
    def _ctrl(self, targets: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """Controls (T, nu) of targets (T, 11) and their velocities (T, 11): the demos'
        controller (arm and fingers by ``targets_to_ctrl``, the base with its velocity lead)."""
        ridx: Any = self.robot
        ctrl = targets_to_ctrl(self.model, ridx, targets[:, :7], vel[:, :7], targets[:, 7])
        ctrl[:, self.robot.ctrl_base] = targets[:, 8:] + self._base_lead * vel[:, 8:]
        return ctrl

    def _controls(self, a: np.ndarray, i: int) -> np.ndarray:
        """Per-physics-step controls (per_frame, nu) of one frame's action for env ``i``."""
        pf = self.per_frame
        prev = self._prev[i]
        if self.interpolate:
            alpha = (np.arange(1, pf + 1) / pf)[:, None]
            targets = prev + (a - prev) * alpha
            vel = np.broadcast_to((a - prev) * self.spec.fps, targets.shape).copy()
        else:
            targets = np.broadcast_to(a, (pf, ACTION_DIM)).copy()
            vel = np.zeros_like(targets)
        targets[:, 7] = a[7]
        vel[:, 7] = 0.0
        return self._ctrl(targets, vel)

    def advance(self, ids: list[int], actions: np.ndarray) -> None:
        """Simulates one frame of envs ``ids`` under their actions (len(ids), 11), one physics
        step at a time, measuring the base's and the arm's deepest contacts after each."""
        m = self.model
        for i, a in zip(ids, actions, strict=True):
            p = self._progress[i]
            ctrl = self._controls(a, i)
            d = self._datas[i]
            for s in range(self.per_frame):
                d.ctrl[:] = ctrl[s]
                mujoco.mj_step(m, d)
                if d.ncon:
                    b, arm = penetrations(
                        d, self._base_geom, self._arm_geom, self._arm_allowed, self._base_allowed
                    )
                    p.worst_base, p.worst_arm = max(p.worst_base, b), max(p.worst_arm, arm)

    def end_frame(self, ids: list[int], actions: np.ndarray) -> None:
        """The frame's actions (len(ids), 11) become the targets the next frame starts from."""
        self._prev[ids] = actions

    # ---- observing
    def observe(
        self,
        i: int,
        v: mujoco.MjData,
        obs: dict[str, np.ndarray],
        ep: Any,
        action: np.ndarray | None,
    ) -> Outcome | None:
        """Writes env ``i``'s observations but the images and, after a frame's ``action``
        (None: the episode's first observation), advances its sub-task; its episode's outcome
        once it ends (success, failure; ``ep``: its steps and step limit)."""
        robot = self.robot
        fingers = v.qpos[robot.finger_qpos]
        base = np.array(v.qpos[robot.base_qpos])
        state = obs["observation.state"]
        state[i, :7] = v.qpos[robot.qpos]
        state[i, 7] = float(fingers[0] - fingers[1])
        state[i, 8:] = base
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, v.site_xmat[robot.site])
        obs["observation.ee_pose"][i] = np.concatenate([v.site_xpos[robot.site], quat])
        if self.spec.env_state:
            obs[ENV_STATE_KEY][i] = object_poses(v, (self.pick, self.place_support))
        z = float(v.qpos[self._obj_adr + 2])
        if action is None:
            self._progress[i] = _Progress(
                start_z=z,
                max_z=z,
                history=deque(maxlen=self.hold_frames + 1),
                sub_start_xy=base[:2].copy(),
            )
        p = self._progress[i]
        p.max_z = max(p.max_z, z)
        p.history.append(self._state.copy())
        out = None
        if action is not None:
            self._advance(i, v, base, action, ep.steps)
            out = self._judge(i, v, ep)
        obs[SUBTASK_KEY][i, 0] = p.subtask
        return out

    def _held(self, v: mujoco.MjData) -> bool:
        """Whether a robot body touches the pick object."""
        n = v.ncon
        if not n:
            return False
        bodies = self.model.geom_bodyid[v.contact.geom[:n]]
        with_obj = (bodies == self.pick).any(axis=1)
        with_robot = self._robot_body[bodies].any(axis=1)
        return bool((with_obj & with_robot).any())

    def _arm_xy(self, base: np.ndarray) -> np.ndarray:
        """The arm mount's (x, y) in the world (m) for a base pose (x, y, yaw)."""
        c, s = np.cos(base[2]), np.sin(base[2])
        return np.array([base[0] + ARM_X * c, base[1] + ARM_X * s])

    def _advance(
        self, i: int, v: mujoco.MjData, base: np.ndarray, action: np.ndarray, steps: int
    ) -> None:
        """Ends the running sub-task of env ``i`` (at frame ``steps``) when its condition holds
        (module docstring)."""
        p, rule, robot = self._progress[i], self.rule, self.robot
        prev = self._prev[i]
        qd = v.qvel[robot.base_dof]
        still = float(np.abs(action[8:] - prev[8:]).max()) < rule.still_command
        resting = (
            float(np.linalg.norm(qd[:2])) < rule.rest_speed and abs(float(qd[2])) < rule.rest_turn
        )
        p.rest = p.rest + 1 if (still and resting) else 0
        p.rest_long = p.rest_long + 1 if resting else 0
        slow = (
            float(np.linalg.norm(qd[:2])) < rule.slow_speed and abs(float(qd[2])) < rule.slow_turn
        )
        p.sub_frames += 1
        held = self._held(v)
        p.free = 0 if held else p.free + 1
        moved = float(np.linalg.norm(base[:2] - p.sub_start_xy)) > rule.moved
        rested = p.rest >= self.settle_frames or p.rest_long >= self.wait_frames
        drove = moved or p.sub_frames >= self.wait_frames
        arrived = rested and drove
        end = False
        if p.subtask == 0:
            obj = v.xpos[self.pick][:2]
            near = (
                float(np.linalg.norm(obj - self._arm_xy(base))) <= PICK_REACH[1] + rule.reach_margin
            )
            opens = float(action[7]) > rule.open_grip  # the pick begins: the hand opens
            end = near and (arrived or (opens and slow and drove))
        elif p.subtask == 1:
            lifted = float(v.qpos[self._obj_adr + 2]) - p.start_z >= LIFT_MIN
            arm_still = float(np.abs(action[:7] - prev[:7]).max()) < rule.still_command
            settled = float(np.abs(v.qvel[robot.arm_dof]).max()) < rule.arm_rest
            end = held and lifted and self._in_carry(v, base) and (arm_still or settled)
            if end:
                p.carry_z = float(v.qpos[self._obj_adr + 2])
        elif p.subtask == 2:
            box = self._place_box
            arm = self._arm_xy(base)
            gap = np.maximum(np.maximum(box[:2] - arm, arm - box[3:5]), 0.0)
            near = float(np.linalg.norm(gap)) <= PLACE_REACH[1] + rule.reach_margin
            # the place begins: the arm command moves
            moves = float(np.abs(action[:7] - prev[:7]).max()) * self.spec.fps > rule.arm_move
            end = near and held and (arrived or (moves and slow and drove))
        if end:
            p.subtask += 1
            p.completed += 1
            p.switches.append(steps)
            p.sub_frames = 0
            p.rest = p.rest_long = 0
            p.sub_start_xy = base[:2].copy()

    def _in_carry(self, v: mujoco.MjData, base: np.ndarray) -> bool:
        """Whether the tool is within ``carry_tol`` of the carry position (base frame)."""
        c, s = np.cos(base[2]), np.sin(base[2])
        tool = v.site_xpos[self.robot.site] - np.array([base[0], base[1], 0.0])
        local = np.array([c * tool[0] + s * tool[1], -s * tool[0] + c * tool[1], tool[2]])
        return float(np.linalg.norm(local - np.asarray(CARRY_TOOL))) <= self.rule.carry_tol

    # ---- success and failure
    def _outcome(self, i: int) -> Outcome:
        p = self._progress[i]
        lift = (p.carry_z if p.carry_z is not None else p.max_z) - p.start_z
        return mobile_outcome(
            self.setup,
            p.history[-1],
            p.history[0],
            lift,
            p.worst_base,
            p.worst_arm,
            data=self._scratch,
        )

    def _finish(self, i: int, success: bool, reason: str, details: dict[str, float]) -> Outcome:
        if success:
            self._progress[i].completed = len(SUBTASKS)
        return Outcome(success, reason, details)

    def _judge(self, i: int, v: mujoco.MjData, ep: Any) -> Outcome | None:
        """Env ``i``'s outcome on success, a deep contact, a drop or the step limit."""
        p = self._progress[i]
        if p.worst_base > COLLISION_DEPTH or p.worst_arm > COLLISION_DEPTH:
            out = self._outcome(i)
            reason = BASE_COLLISION if p.worst_base > COLLISION_DEPTH else "collision"
            return self._finish(i, False, reason, out.details)
        if p.subtask == 2 and p.free >= self.drop_frames:
            return self._finish(i, False, DROP, self._outcome(i).details)
        box = self._place_box
        xy = v.xpos[self.pick][:2]
        over = bool((xy >= box[:2]).all() and (xy <= box[3:5]).all())
        settled = len(p.history) > self.hold_frames
        if settled and over and p.max_z - p.start_z >= LIFT_MIN:
            out = self._outcome(i)
            if out.success:
                return self._finish(i, True, "", out.details)
        if ep.steps >= ep.limit:
            out = self._outcome(i)
            if out.success:
                return self._finish(i, True, "", out.details)
            if p.subtask in (0, 2):
                return self._finish(i, False, NAV_TIMEOUT, out.details)
            return self._finish(i, False, out.reason, out.details)
        return None

    # ---- images and results
    def renderer(self, cameras: tuple[str, ...]) -> MobileRenderer:
        """A renderer of ``cameras`` at the spec's size (depth in millimetres; fisheye views
        ``width`` square)."""
        s = self.spec
        return MobileRenderer(
            self.model, MobileRecordConfig(s.fps, s.width, s.height, cameras, "uint16_mm", True)
        )

    def draw(
        self, renderer: MobileRenderer, data: mujoco.MjData, i: int = -1
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB, depth) of the state in ``data`` (env ``i``'s, loaded)."""
        return renderer.render(data)

    def step_info(self) -> dict[str, np.ndarray]:
        """``subtask`` (n,): the sub-task each env is in."""
        return {"subtask": np.array([p.subtask for p in self._progress])}

    def result(self, i: int) -> dict[str, Any]:
        """The sub-task env ``i`` is in, how many sub-tasks it completed and the frames it
        switched at."""
        p = self._progress[i]
        return {
            "record": {
                "subtask": SUBTASKS[min(p.subtask, len(SUBTASKS) - 1)],
                "subtasks_done": int(p.completed),
            },
            "switches": list(p.switches),
        }

    @property
    def last_actions(self) -> np.ndarray:
        """(n, 11): each env's last action (at a reset: the targets it rests at), a copy."""
        return self._prev.copy()
