"""Closed-loop mobile pick-and-place episodes (``task=mobile_pick_place``): the env behind
``stage=eval`` for the Panda on the Omron base.

:class:`MobileVecEnv` runs ``n`` episodes of one scene with the demos' own pieces
(:mod:`factory.tasks.mobile_pick_place`), so that what a policy sees and does in it is what the
dataset recorded:

* scene: :func:`factory.demos.mobile_items.mobile_scene_planner`, the same set-up as
  ``stage=demos`` (the scene composed with the mobile robot, light floor objects in the base's
  way taken out, the same supports and the object where the scene puts it);
* reset: from a seed, the planner's own spawn (:meth:`MobilePlanner.initial_qpos`: seed ``s``
  starts where the demos' planner starts episode ``s``: base at a random free pose, arm
  stowed, hand closed), or a recorded MuJoCo integration state (replay);
* action (11,) as recorded: arm joint targets (7, rad), gripper command (m; 0.08 open,
  negative squeezes), base target x, y (m, world) and unwrapped yaw (rad), one per frame
  (``1 / fps`` s). The controller is the demos': :func:`~factory.tasks.pick_place.plan.
  targets_to_ctrl` for the arm and fingers, the base's position actuators with the planner's
  velocity lead. With ``interpolate`` (default) arm and base targets move linearly from the
  previous action over the frame with the velocity ``(a - a_prev) * fps`` as lead (the
  recorded action of frame ``f`` is the plan's target at the end of frame ``f``, so this
  first-order hold follows the plan's per-step targets closely); the gripper command is held;
* physics: one ``mujoco.MjData`` per episode stepped one physics step at a time as
  :func:`~factory.tasks.mobile_pick_place.execute.simulate` does, the deepest contact of the base
  and of
  the arm measured after every step (:func:`~factory.tasks.mobile_pick_place.execute.penetrations`);
* observations keyed like the dataset's features: ``observation.state`` (11: arm joints,
  finger opening, base x, y, yaw), ``observation.ee_pose`` (7: tool position + quaternion wxyz,
  world), ``subtask_index`` (1, int64), and per camera ``observation.images.<cam>`` /
  ``observation.depth.<cam>`` drawn by the demos' :class:`~factory.tasks.mobile_pick_place.execute.
  MobileRenderer` from the frame's state set into a fresh ``MjData`` (as ``render_frames``:
  the same images for the same state; fisheye images are ``width`` square);
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
* success: the demos' check (:func:`~factory.tasks.mobile_pick_place.execute.mobile_outcome`: the
object
  on the place support, released, moved < 5 mm over the last 0.5 s, the base and the arm never
  deeper than 2 cm in anything), tested every frame once the object is over the support;
* failures: ``base_collision`` / ``collision`` (a contact deeper than 2 cm ends the episode),
  ``drop`` (the object left the hand while carrying it, for 0.25 s), and at the step limit
  ``nav_timeout`` (still in a navigation sub-task) or the success check's reason (``slip``,
  ``not_on_target``, ``not_released``, ``unstable``).

Frames: world frame (m, rad); a base pose is the footprint centre's (x, y) and the yaw.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from factory.sim.gl import configure_gl

configure_gl("auto")  # before mujoco is imported: the env renders offscreen

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from factory.errors import StoreError, TaskError  # noqa: E402
from factory.nav import BASE_COLLISION  # noqa: E402
from factory.nav.task_poses import ARM_X, PICK_REACH, PLACE_REACH  # noqa: E402
from factory.policy.env_common import Episode, EpisodeEnv  # noqa: E402
from factory.robots.mobile_panda import CAMERAS as PINHOLE  # noqa: E402
from factory.tasks.mobile_pick_place.execute import (  # noqa: E402
    STATE_SPEC,
    MobileRecordConfig,
    MobileRenderer,
    mobile_outcome,
    penetrations,
)
from factory.tasks.mobile_pick_place.scene import (  # noqa: E402
    ALL_CAMERAS,
    CARRY_TOOL,
    FISHEYE_CAMERAS,
    SUBTASKS,
    MobileSetup,
    body_box,
)
from factory.tasks.pick_place.plan import targets_to_ctrl  # noqa: E402

log = logging.getLogger(__name__)

ACTION_DIM = 11
"""The mobile action: arm joints (7, rad), gripper (m), base x, y (m) and yaw (rad)."""
STATE_DIM = 11
"""``observation.state``: arm joints (7), finger opening (m), base x, y (m), yaw (rad)."""
SUBTASK_KEY = "subtask_index"
COLLISION_DEPTH = 0.02
"""A contact of the base or the arm deeper than this (m) ends the episode (the demos' check)."""
LIFT_MIN = 0.03
"""The object must have been lifted this high (m) (the demos' check)."""
NAV_TIMEOUT = "nav_timeout"
DROP = "drop"
FAILURES = (BASE_COLLISION, "collision", DROP, NAV_TIMEOUT, "slip", "not_on_target")
"""Failure reasons of the env (and the success check's ``not_released``, ``unstable``)."""


@dataclass(frozen=True)
class MobileObsSpec:
    """What the mobile env observes and how fast it steps.

    Attributes:
        fps: frames (actions) per second (Hz); the dataset's fps.
        cameras: cameras rendered, from ``left``, ``right``, ``wrist``, ``fisheye_front``,
            ``fisheye_back``; empty for no images.
        width, height: pinhole image size (px); fisheye images are ``width`` square.
        depth: also ``observation.depth.<cam>`` (uint16 mm; fisheye: ray length).
        env_state: unused (mobile datasets record no object poses); kept so that the
            evaluation treats both specs alike.
    """

    fps: float = 20.0
    cameras: tuple[str, ...] = ALL_CAMERAS
    width: int = 128
    height: int = 128
    depth: bool = True
    env_state: bool = False

    def image_shape(self, camera: str) -> tuple[int, int]:
        """(H, W) of a camera's images (px)."""
        if camera in FISHEYE_CAMERAS:
            return (self.width, self.width)
        return (self.height, self.width)

    def keys(self) -> list[str]:
        """Observation keys, as the dataset's feature names."""
        return list(self.shapes())

    def shapes(self) -> dict[str, tuple[tuple[int, ...], str]]:
        """Key -> (shape, dtype) of one env's observation."""
        out: dict[str, tuple[tuple[int, ...], str]] = {
            "observation.state": ((STATE_DIM,), "float32"),
            "observation.ee_pose": ((7,), "float32"),
            SUBTASK_KEY: ((1,), "int64"),
        }
        for c in self.cameras:
            out[f"observation.images.{c}"] = ((*self.image_shape(c), 3), "uint8")
        if self.depth:
            for c in self.cameras:
                out[f"observation.depth.{c}"] = (self.image_shape(c), "uint16")
        return out


def obs_spec_of_mobile_dataset(root: str | Path) -> MobileObsSpec:
    """The observation spec of a mobile LeRobot dataset (fps, cameras, image sizes, depth)."""
    from factory.policy.env import dataset_features

    meta = dataset_features(root)
    feats = meta["features"]
    cams = tuple(c for c in ALL_CAMERAS if f"observation.images.{c}" in feats)
    h = w = 128
    pin = [c for c in cams if c in PINHOLE]
    fish = [c for c in cams if c in FISHEYE_CAMERAS]
    if pin:
        h, w = (int(x) for x in feats[f"observation.images.{pin[0]}"]["shape"][:2])
    elif fish:
        w = h = int(feats[f"observation.images.{fish[0]}"]["shape"][1])
    depth = any(f"observation.depth.{c}" in feats for c in cams)
    return MobileObsSpec(float(meta["fps"]), cams, w, h, depth)


def obs_spec_of_mobile_demos(dc: Any) -> MobileObsSpec:
    """The observation spec of what ``stage=demos task=mobile_pick_place`` records with the
    demos settings ``dc`` (``demos.cameras`` plus both fisheye cameras)."""
    cams = (*dc.cameras, *FISHEYE_CAMERAS) if dc.render else ()
    return MobileObsSpec(dc.fps, tuple(cams), dc.width, dc.height, bool(dc.render))


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
class _Episode(Episode):
    """Book-keeping of one env's running episode: its sub-tasks and deepest contacts too."""

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


class MobileVecEnv(EpisodeEnv[_Episode, MobileRenderer]):
    """``num_envs`` mobile pick-and-place episodes of one scene (see the module docstring).

    Args:
        setup: the scene with the mobile robot (:func:`~factory.demos.mobile_items.
            mobile_scene_planner`).
        planner: its planner (the spawn rule, and the privileged agent).
        num_envs: episodes run at once (stepped one after the other).
        spec: what to observe.
        max_steps: frames before an episode is truncated.
        interpolate: first-order hold of the arm and base targets over a frame.
        rule: when sub-tasks end.
        instruction: the task's language instruction.
    """

    def __init__(
        self,
        setup: MobileSetup,
        planner: Any,
        num_envs: int = 1,
        spec: MobileObsSpec | None = None,
        max_steps: int = 1500,
        interpolate: bool = True,
        rule: SubtaskRule | None = None,
        instruction: str = "",
    ) -> None:
        self.setup = setup
        self.planner = planner
        self.model = m = setup.model
        self.robot = robot = setup.robot
        self.spec = spec or MobileObsSpec()
        self.num_envs = num_envs
        self.max_steps = max_steps
        self.interpolate = interpolate
        self.rule = rule or SubtaskRule()
        self.instruction = instruction
        self.action_dim = ACTION_DIM
        self.dt = float(m.opt.timestep)
        self.per_frame = max(1, round(1.0 / (self.spec.fps * self.dt)))
        fps = self.spec.fps
        self.hold_frames = max(1, round(0.5 * fps))
        self.settle_frames = max(1, round(self.rule.settle * fps))
        self.wait_frames = max(1, round(self.rule.wait * fps))
        self.drop_frames = max(1, round(self.rule.drop_after * fps))
        self._datas = [mujoco.MjData(m) for _ in range(num_envs)]
        self._view = mujoco.MjData(m)
        self._scratch = mujoco.MjData(m)
        self._nstate = mujoco.mj_stateSize(m, STATE_SPEC)
        self._state = np.zeros(self._nstate)
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
        self.renderer: MobileRenderer | None = None
        if self.spec.cameras:
            self.renderer = MobileRenderer(m, self._record_cfg(self.spec.cameras))
        self._video: MobileRenderer | None = None
        self._episodes = [_Episode(done=True) for _ in range(num_envs)]
        self._prev = np.zeros((num_envs, ACTION_DIM))
        self._obs = self._empty_obs(self.spec.shapes())

    # ---- set-up helpers
    def _record_cfg(self, cameras: tuple[str, ...]) -> MobileRecordConfig:
        s = self.spec
        return MobileRecordConfig(s.fps, s.width, s.height, cameras, "uint16_mm", True)

    def sample_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed``: the demos' planner's spawn
        (:meth:`MobilePlanner.initial_qpos`).

        Raises:
            TaskError: no free spawn pose with this seed, or the base cannot work here.
        """
        return np.asarray(self.planner.initial_qpos(int(seed)))

    # ---- episodes
    def reset(
        self,
        seeds: list[int] | None = None,
        states: np.ndarray | None = None,
        qpos: np.ndarray | None = None,
        ids: list[int] | None = None,
        max_steps: list[int] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Starts new episodes in envs ``ids`` (default all).

        Exactly one of ``seeds`` (the planner's spawn), ``states`` (recorded integration
        states (len(ids), nstate): replay) or ``qpos`` ((len(ids), nq): arm, fingers and base
        at rest there) gives the initial configurations; ``max_steps`` (per env) overrides
        the step limit.

        Returns:
            observations of every env (n, ...) and ``{"seed": [...]}``.

        Raises:
            TaskError: a seed without a free spawn pose.
        """
        from factory.robots.mobile_panda import STOW_FINGERS

        ids = self._reset_ids(ids, seeds, states, qpos)
        if seeds is not None:
            qpos = np.stack([self.sample_qpos(int(s)) for s in seeds])
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
                    STOW_FINGERS
                    if seeds is not None
                    else float(np.sum(np.abs(qpos[k][robot.finger_qpos])))
                )
                base = np.asarray(qpos[k][robot.base_qpos], np.float64)
                self._prev[i] = np.concatenate([arm, [grip], base])
                d.ctrl[:] = self._ctrl(self._prev[i][None], np.zeros((1, ACTION_DIM)))[0]
            mujoco.mj_forward(m, d)
            seed, limit = self._episode_start(k, seeds, max_steps, self.max_steps)
            self._episodes[i] = _Episode(seed=seed, limit=limit)
            self._observe(i, first=True)
        return self.observations(), self._reset_info()

    def _load(self, i: int) -> mujoco.MjData:
        """Env ``i``'s current state in a fresh view (``mj_setState`` + ``mj_forward``), as the
        recording draws and measures its frames."""
        m, v = self.model, self._view
        mujoco.mj_getState(m, self._datas[i], self._state, STATE_SPEC)
        mujoco.mj_setState(m, v, self._state, STATE_SPEC)
        mujoco.mj_forward(m, v)
        return v

    def _observe(self, i: int, first: bool = False, action: np.ndarray | None = None) -> None:
        """Observes env ``i`` and updates its episode (sub-task, success, failure)."""
        robot, obs = self.robot, self._obs
        v = self._load(i)
        fingers = v.qpos[robot.finger_qpos]
        base = np.array(v.qpos[robot.base_qpos])
        state = obs["observation.state"]
        state[i, :7] = v.qpos[robot.qpos]
        state[i, 7] = float(fingers[0] - fingers[1])
        state[i, 8:] = base
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, v.site_xmat[robot.site])
        obs["observation.ee_pose"][i] = np.concatenate([v.site_xpos[robot.site], quat])
        if self.renderer is not None:
            for c, (im, dp) in self.renderer.render(v).items():
                obs[f"observation.images.{c}"][i] = im
                if self.spec.depth:
                    obs[f"observation.depth.{c}"][i] = dp
        ep = self._episodes[i]
        z = float(v.qpos[self._obj_adr + 2])
        if first:
            ep.start_z = ep.max_z = z
            ep.sub_start_xy = base[:2].copy()
            ep.history = deque(maxlen=self.hold_frames + 1)
        ep.max_z = max(ep.max_z, z)
        ep.history.append(self._state.copy())
        if not first:
            assert action is not None
            self._advance(i, v, base, action)
            self._judge(i, v)
        obs[SUBTASK_KEY][i, 0] = ep.subtask

    # ---- sub-tasks
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

    def _advance(self, i: int, v: mujoco.MjData, base: np.ndarray, action: np.ndarray) -> None:
        """Ends the running sub-task of env ``i`` when its condition holds (module docstring)."""
        ep, rule, robot = self._episodes[i], self.rule, self.robot
        prev = self._prev[i]
        qd = v.qvel[robot.base_dof]
        still = float(np.abs(action[8:] - prev[8:]).max()) < rule.still_command
        resting = (
            float(np.linalg.norm(qd[:2])) < rule.rest_speed and abs(float(qd[2])) < rule.rest_turn
        )
        ep.rest = ep.rest + 1 if (still and resting) else 0
        ep.rest_long = ep.rest_long + 1 if resting else 0
        slow = (
            float(np.linalg.norm(qd[:2])) < rule.slow_speed and abs(float(qd[2])) < rule.slow_turn
        )
        ep.sub_frames += 1
        held = self._held(v)
        ep.free = 0 if held else ep.free + 1
        moved = float(np.linalg.norm(base[:2] - ep.sub_start_xy)) > rule.moved
        rested = ep.rest >= self.settle_frames or ep.rest_long >= self.wait_frames
        drove = moved or ep.sub_frames >= self.wait_frames
        arrived = rested and drove
        end = False
        if ep.subtask == 0:
            obj = v.xpos[self.pick][:2]
            near = (
                float(np.linalg.norm(obj - self._arm_xy(base))) <= PICK_REACH[1] + rule.reach_margin
            )
            opens = float(action[7]) > rule.open_grip  # the pick begins: the hand opens
            end = near and (arrived or (opens and slow and drove))
        elif ep.subtask == 1:
            lifted = float(v.qpos[self._obj_adr + 2]) - ep.start_z >= LIFT_MIN
            arm_still = float(np.abs(action[:7] - prev[:7]).max()) < rule.still_command
            settled = float(np.abs(v.qvel[robot.arm_dof]).max()) < rule.arm_rest
            end = held and lifted and self._in_carry(v, base) and (arm_still or settled)
            if end:
                ep.carry_z = float(v.qpos[self._obj_adr + 2])
        elif ep.subtask == 2:
            box = self._place_box
            arm = self._arm_xy(base)
            gap = np.maximum(np.maximum(box[:2] - arm, arm - box[3:5]), 0.0)
            near = float(np.linalg.norm(gap)) <= PLACE_REACH[1] + rule.reach_margin
            # the place begins: the arm command moves
            moves = float(np.abs(action[:7] - prev[:7]).max()) * self.spec.fps > rule.arm_move
            end = near and held and (arrived or (moves and slow and drove))
        if end:
            ep.subtask += 1
            ep.completed += 1
            ep.switches.append(ep.steps)
            ep.sub_frames = 0
            ep.rest = ep.rest_long = 0
            ep.sub_start_xy = base[:2].copy()

    def _in_carry(self, v: mujoco.MjData, base: np.ndarray) -> bool:
        """Whether the tool is within ``carry_tol`` of the carry position (base frame)."""
        c, s = np.cos(base[2]), np.sin(base[2])
        tool = v.site_xpos[self.robot.site] - np.array([base[0], base[1], 0.0])
        local = np.array([c * tool[0] + s * tool[1], -s * tool[0] + c * tool[1], tool[2]])
        return float(np.linalg.norm(local - np.asarray(CARRY_TOOL))) <= self.rule.carry_tol

    # ---- success and failure
    def _outcome(self, i: int) -> Any:
        ep = self._episodes[i]
        lift = (ep.carry_z if ep.carry_z is not None else ep.max_z) - ep.start_z
        return mobile_outcome(
            self.setup,
            ep.history[-1],
            ep.history[0],
            lift,
            ep.worst_base,
            ep.worst_arm,
            data=self._scratch,
        )

    def _finish(self, i: int, success: bool, reason: str, details: dict[str, float]) -> None:
        ep = self._episodes[i]
        ep.done, ep.success, ep.reason, ep.details = True, success, reason, details
        if success:
            ep.completed = len(SUBTASKS)

    def _judge(self, i: int, v: mujoco.MjData) -> None:
        """Ends env ``i``'s episode on success, a deep contact, a drop or the step limit."""
        ep = self._episodes[i]
        if ep.worst_base > COLLISION_DEPTH or ep.worst_arm > COLLISION_DEPTH:
            out = self._outcome(i)
            reason = BASE_COLLISION if ep.worst_base > COLLISION_DEPTH else "collision"
            self._finish(i, False, reason, out.details)
            return
        if ep.subtask == 2 and ep.free >= self.drop_frames:
            self._finish(i, False, DROP, self._outcome(i).details)
            return
        box = self._place_box
        xy = v.xpos[self.pick][:2]
        over = bool((xy >= box[:2]).all() and (xy <= box[3:5]).all())
        settled = len(ep.history) > self.hold_frames
        if settled and over and ep.max_z - ep.start_z >= LIFT_MIN:
            out = self._outcome(i)
            if out.success:
                self._finish(i, True, "", out.details)
                return
        if ep.steps >= ep.limit:
            out = self._outcome(i)
            if out.success:
                self._finish(i, True, "", out.details)
            elif ep.subtask in (0, 2):
                self._finish(i, False, NAV_TIMEOUT, out.details)
            else:
                self._finish(i, False, out.reason, out.details)

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

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Applies one action per env (n, 11) for one frame; finished envs do not move.

        Returns:
            observations (n, ...), rewards (n,) (1 on the step of success), terminated (n,)
            (success, a deep contact or a drop), truncated (n,) (step limit), info with
            ``success``, ``reason``, ``steps``, ``subtask`` (n,) each.
        """
        actions = np.asarray(actions, np.float64)
        if actions.shape != (self.num_envs, ACTION_DIM):
            raise ValueError(
                f"actions must be ({self.num_envs}, {ACTION_DIM}), got {actions.shape}"
            )
        m = self.model
        was_done = self.done
        for i, ep in enumerate(self._episodes):
            if ep.done:
                continue
            ctrl = self._controls(actions[i], i)
            d = self._datas[i]
            for s in range(self.per_frame):
                d.ctrl[:] = ctrl[s]
                mujoco.mj_step(m, d)
                if d.ncon:
                    b, a = penetrations(
                        d, self._base_geom, self._arm_geom, self._arm_allowed, self._base_allowed
                    )
                    ep.worst_base, ep.worst_arm = max(ep.worst_base, b), max(ep.worst_arm, a)
            ep.steps += 1
            self._observe(i, action=actions[i])
            self._prev[i] = actions[i]
        reward, terminated, truncated, info = self._step_outcome(
            was_done, terminal=(DROP, BASE_COLLISION, "collision")
        )
        info["subtask"] = np.array([e.subtask for e in self._episodes])
        return self.observations(), reward, terminated, truncated, info

    @property
    def last_actions(self) -> np.ndarray:
        """(n, 11): each env's last action (at a reset: the targets it rests at), a copy."""
        return self._prev.copy()

    def result(self, i: int) -> dict[str, Any]:
        """Env ``i``'s episode so far: success, reason, steps, seed, the check's numbers, the
        sub-task it is in, how many sub-tasks it completed and the frames it switched at."""
        e = self._episodes[i]
        return {
            **self._result(i),
            "record": {
                "subtask": SUBTASKS[min(e.subtask, len(SUBTASKS) - 1)],
                "subtasks_done": int(e.completed),
            },
            "switches": list(e.switches),
        }

    def render(self, i: int, cameras: tuple[str, ...] = ALL_CAMERAS) -> np.ndarray:
        """RGB frame of env ``i``'s current state, ``cameras`` side by side at the spec's size
        (fisheye views are ``width`` square; shorter views are padded with black), for videos."""
        video = self._video_renderer(
            cameras, lambda: MobileRenderer(self.model, self._record_cfg(cameras))
        )
        views = video.render(self._load(i))
        ims = [views[c][0] for c in cameras]
        h = max(im.shape[0] for im in ims)
        ims = [np.pad(im, ((0, h - im.shape[0]), (0, 0), (0, 0))) for im in ims]
        return np.concatenate(ims, axis=1)


def make_mobile_vec_env(
    run_dir: str | Path,
    scene_id: str,
    num_envs: int = 1,
    spec: MobileObsSpec | None = None,
    max_steps: int = 1500,
    interpolate: bool = True,
    dc: Any = None,
) -> tuple[MobileVecEnv, Any]:
    """A batched mobile env of a scene of a run, and the scene's planner (the privileged
    agent), set up exactly as ``stage=demos task=mobile_pick_place`` sets it up.

    Args:
        run_dir: the run directory; scene_id: a scene under ``scenes/``.
        num_envs: episodes run at once; spec: what to observe (default: the demos' cameras).
        max_steps: frames per episode before truncation.
        interpolate: the controller's first-order hold.
        dc: the demos' settings (default: the run's, :func:`factory.policy.env.demos_config_of`).

    Raises:
        StoreError: no such scene; TaskError: the scene cannot host the mobile task.
    """
    from factory.demos.mobile_items import mobile_scene_planner
    from factory.policy.env import demos_config_of

    run_dir = Path(run_dir)
    if not (run_dir / "scenes" / scene_id / "scene.json").is_file():
        raise StoreError(f"no scene {scene_id!r} in {run_dir / 'scenes'}: check the scene id")
    dc = dc or demos_config_of(run_dir)
    setup, planner = mobile_scene_planner(run_dir, scene_id, dc)
    if planner.unusable:
        raise TaskError(f"the robot's base cannot work in {scene_id!r}: {planner.unusable}")
    env = MobileVecEnv(
        setup,
        planner,
        num_envs,
        spec or obs_spec_of_mobile_demos(dc),
        max_steps=max_steps,
        interpolate=interpolate,
        instruction=mobile_instruction(setup),
    )
    return env, planner


def mobile_instruction(setup: MobileSetup) -> str:
    """The task instruction the mobile demos record for a scene (``mobile_stage``'s rule)."""
    scene, objs = setup.scene, setup.objects
    if scene.task is not None and scene.task.instruction:
        return str(scene.task.instruction)
    return f"pick up the {objs.pick.category} and put it on the {objs.place_support.category}"
