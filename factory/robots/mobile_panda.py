"""The Franka Panda with the Panda gripper on robosuite's Omron mobile base.

robosuite 1.5.1's model classes compose the MJCF (:class:`robosuite.models.robots.Panda`,
``add_base(OmronMobileBase())``, ``add_gripper(PandaGripper())``): the arm stands on the
base's torso column, the column on the Omron LD-60's wheeled body. It is exported once with its
meshes to the robot cache (``FACTORY_ROBOT_CACHE``, as :mod:`factory.robots.panda` does), so a
machine with the cache needs no robosuite. Here, as for the fixed arm, the arm's torque motors
become position actuators with the Panda's torque limits and robot bodies get gravity
compensation; in addition robosuite's base joints (velocity-driven, with odd axes) and the
torso lift are replaced by a holonomic base: ``base_x``, ``base_y`` (slides along world x and
y) and ``base_yaw`` (a hinge about +z through the footprint centre), each driven by a position
actuator. The torso stays at its lowest: the arm's base (link0) is 0.70 m above the floor.

Frames: the base frame has its origin on the floor at the centre of the wheeled body's
footprint (a 0.70 x 0.50 m box), +x forward, +z up; the base joints' values are the world
pose of this frame, x, y (m) and unwrapped yaw (rad), and so are the base actuators' targets.
``qpos0`` is the pose given to :func:`add_mobile_robot` (joint ``ref``), so ``mj_resetData``
puts the robot there. link0 sits at ``ARM_MOUNT`` in the base frame. The tool frame is the
site ``mobile/gripper0_grip_site`` as for the fixed robot.

Cameras ride on the robot: ``left`` and ``right`` on a head above the torso look at the
workspace in front of the robot (:class:`MobileCameraRig`), ``wrist`` on the hand. Fisheye
cameras are not added yet; their hook is two empty bodies on top of the wheeled body,
``mobile/fisheye_front_mount`` (looking forward) and ``mobile/fisheye_back_mount`` (looking
back). A mount body's +x is its view direction and +z is up; a camera added to it with
``quat=FISHEYE_CAMERA_QUAT`` looks along that +x (MuJoCo cameras look along their -z).
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from factory.nav.base_trajectory import BaseLimits
from factory.nav.footprint import Footprint
from factory.robots.panda import (
    FingerTargets,
    _look_quat,
    add_panda_actuators,
    cached_mjcf,
    export_mjcf,
    finish_panda_spec,
    yaw_quat,
)
from factory.robots.robosuite_models import robosuite_cache_dir, robosuite_panda_xml

log = logging.getLogger(__name__)

PREFIX = "mobile/"
"""Every name of the mobile robot in a composed model starts with this."""
BASE_BODY = f"{PREFIX}robot0_base"
"""The body that carries the base frame (and, below it, everything else of the robot)."""
BASE_JOINTS: tuple[str, str, str] = (f"{PREFIX}base_x", f"{PREFIX}base_y", f"{PREFIX}base_yaw")
BASE_ACTUATORS: tuple[str, str, str] = (
    f"{PREFIX}base_act_x",
    f"{PREFIX}base_act_y",
    f"{PREFIX}base_act_yaw",
)
ARM_JOINTS: tuple[str, ...] = tuple(f"{PREFIX}robot0_joint{i}" for i in range(1, 8))
FINGER_JOINTS: tuple[str, str] = (
    f"{PREFIX}gripper0_finger_joint1",
    f"{PREFIX}gripper0_finger_joint2",
)
TOOL_SITE = f"{PREFIX}gripper0_grip_site"
HAND_BODY = f"{PREFIX}robot0_right_hand"
HAND_GEOM = f"{PREFIX}gripper0_hand_collision"
"""The collision geom of the hand's palm (the fingers have their own)."""

ARM_MOUNT: tuple[float, float, float] = (0.20, 0.0, 0.70)
"""Position of the arm's base (link0) in the base frame (m)."""
BASE_HALF_EXTENTS: tuple[float, float, float] = (0.35, 0.25, 0.19)
"""Half sizes of the wheeled body's collision box (m), centred at (0, 0, 0.192)."""
FOOTPRINT_RADIUS = 0.45
"""Radius (m) of a disc about the base origin that holds the robot's footprint in the stowed
pose: the box's circumscribed radius is 0.430 m, plus 2 cm. Inflate the occupancy grid by it."""

BASE_FOOTPRINT = Footprint(rear=0.35, front=0.40, half_width=0.25, margin=0.04)
"""The robot's outline from above with the arm stowed (base frame, m): the wheeled body's box
(0.70 x 0.50 m) and, ahead of it, the stowed hand (to x = 0.397 m), with 4 cm all round;
navigation checks poses and motions with it (:class:`factory.nav.Footprint`). Carrying, the
planner lengthens its front by the object."""

BASE_LIMITS = BaseLimits()
"""Conservative driving limits of the Omron LD-60 (0.5 m/s, 0.5 m/s^2, 1 rad/s, 1 rad/s^2; the
datasheet allows 1.35 m/s): see :class:`factory.nav.BaseLimits`."""

STOW_QPOS = np.array([0.0, -1.7628, 0.0, -3.0, 0.0, 1.75, 0.785])
"""The arm folded over the base for driving (rad): upper arm back against its joint limit,
forearm folded down, hand above the torso inside the footprint."""
STOW_FINGERS = 0.0
"""Total finger opening (m) while driving: closed."""

CAMERAS: dict[str, str] = {
    "left": f"{PREFIX}camera_left",
    "right": f"{PREFIX}camera_right",
    "wrist": f"{PREFIX}wrist_camera",
}
"""Recording camera name -> camera name in the composed model (all ride on the robot)."""
FISHEYE_MOUNTS: dict[str, str] = {
    "fisheye_front": f"{PREFIX}fisheye_front_mount",
    "fisheye_back": f"{PREFIX}fisheye_back_mount",
}
"""Hook for fisheye cameras: camera name -> the body to add it to (see the module docstring)."""
FISHEYE_CAMERA_QUAT: tuple[float, float, float, float] = (0.5, 0.5, -0.5, -0.5)
"""Quaternion (w, x, y, z) of a camera in a fisheye mount body that looks along the body's +x
with the image's up along +z."""

_BASE_KP = (50000.0, 50000.0, 10000.0)
"""Base position gains: N/m for x and y, N m/rad for yaw; critically damped (``dampratio``)."""
_BASE_FORCE = (600.0, 600.0, 600.0)
"""Base force limits (N, N, N m), robosuite's for the Omron base's actuators."""
_BASE_MASS = 60.0
"""Mass of the wheeled body (kg); the LD-60 weighs about 60 kg (robosuite's box has ~1 kg, and its
visual meshes, which would add 70 kg at the default density, are made massless here)."""


@dataclass(frozen=True)
class MobileCameraRig:
    """The robot-mounted recording cameras, in the base frame (m, deg).

    ``left`` and ``right`` sit on a head above the torso, ``eye_y`` to each side (``left`` on
    +y), and look at ``workspace``, a point in front of the robot at table height. ``wrist``
    rides on the hand as on the fixed robot.
    """

    workspace: tuple[float, float, float] = (0.95, 0.0, 0.75)
    eye_x: float = 0.0
    eye_y: float = 0.3
    eye_z: float = 1.35
    fovy: float = 60.0
    wrist_fovy: float = 75.0


def mobile_cache_dir() -> Path:
    """Where the composed mobile robot MJCF and its meshes are kept (``FACTORY_ROBOT_CACHE``)."""
    return robosuite_cache_dir("panda-omron")


def _robosuite_xml() -> str:
    """Panda + gripper on the Omron base from robosuite's model classes (absolute paths)."""
    return robosuite_panda_xml("OmronMobileBase", "mobile robot model", mobile_cache_dir())


def export_mobile_robot(cache: Path) -> None:
    """Writes robosuite's composed mobile Panda MJCF and its files under ``cache``
    (:func:`~factory.robots.panda.export_mjcf`: visual meshes simplified as for the fixed
    robot)."""
    export_mjcf(_robosuite_xml(), cache)


@functools.lru_cache(maxsize=1)
def _mobile_xml() -> str:
    """The mobile robot MJCF with absolute file paths: from the cache, made once."""
    return cached_mjcf(mobile_cache_dir(), _robosuite_xml)


def _pose3(pose: tuple[float, float, float] | np.ndarray) -> tuple[float, float, float]:
    x, y, yaw = (float(v) for v in np.asarray(pose, float).reshape(3))
    return x, y, yaw


def mobile_spec(
    pose: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
    rig: MobileCameraRig | None = None,
) -> mujoco.MjSpec:
    """The mobile robot as an MjSpec (names without the prefix), standing at ``pose``.

    Args:
        pose: the base's initial world pose (x, y in m, yaw in rad); it becomes ``qpos0`` of
            the base joints, whose values are world coordinates (attach at the world origin).
        rig: the robot-mounted cameras; default :class:`MobileCameraRig`.

    Returns:
        a spec whose actuators are, in order, ``base_act_x``, ``base_act_y``, ``base_act_yaw``
        (world pose targets, m and rad), ``robot0_act1..7`` (arm joint targets, rad) and the
        two finger position actuators (m).
    """
    rig = rig or MobileCameraRig()
    x0, y0, yaw0 = _pose3(pose)
    spec = mujoco.MjSpec.from_string(_mobile_xml())
    spec.compiler.degree = False
    for act in list(spec.actuators):
        spec.delete(act)
    for name in (
        "mobilebase0_joint_mobile_forward",
        "mobilebase0_joint_mobile_side",
        "mobilebase0_joint_mobile_yaw",
        "mobilebase0_joint_torso_height",
    ):
        spec.delete(spec.joint(name))

    # The base frame: robot0_base (the root) at the footprint centre; robosuite's base body
    # (and the arm on it) shifted forward so that its wheeled body is centred there.
    base = spec.body("robot0_base")
    base.pos = [x0, y0, 0.0]
    base.quat = yaw_quat(yaw0).tolist()
    spec.body("mobilebase0_base").pos = [ARM_MOUNT[0], 0.0, 0.0]
    c, s = math.cos(yaw0), math.sin(yaw0)
    # Slide axes in the body frame that point along world x and y (the body starts at yaw0).
    for name, axis, ref in (("base_x", [c, -s, 0.0], x0), ("base_y", [s, c, 0.0], y0)):
        base.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, ref=ref)
    base.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1], ref=yaw0)
    for i, joint in enumerate(("base_x", "base_y", "base_yaw")):
        act = spec.add_actuator(name=f"base_act_{joint[5:]}", target=joint)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=_BASE_KP[i], dampratio=1.0)
        act.ctrllimited = False
        act.forcelimited = True
        act.forcerange = [-_BASE_FORCE[i], _BASE_FORCE[i]]

    add_panda_actuators(spec)
    for geom in spec.geoms:
        if geom.name in ("mobilebase0_fixed_support", "mobilebase0_support"):
            geom.contype = geom.conaffinity = 0  # robosuite's visual copies of the columns
        if geom.name == "mobilebase0_pedestal_feet_col":
            geom.mass = _BASE_MASS
        elif geom.parent.name.startswith("mobilebase0_") and not (geom.contype or geom.conaffinity):
            geom.density = 0.0
    # As on the fixed robot (after the columns above lost their collisions), but the base
    # body, which carries the wheeled body, gets no gravity compensation.
    finish_panda_spec(spec, rig.wrist_fovy, no_gravcomp=("robot0_base",))

    target = np.asarray(rig.workspace, float)
    for name, side in (("camera_left", 1.0), ("camera_right", -1.0)):
        eye = np.array([rig.eye_x, side * rig.eye_y, rig.eye_z])
        base.add_camera(
            name=name, pos=eye.tolist(), quat=_look_quat(eye, target).tolist(), fovy=rig.fovy
        )
    top = 2 * BASE_HALF_EXTENTS[2] + 0.01
    for name, x, yaw in (
        ("fisheye_front_mount", BASE_HALF_EXTENTS[0] - 0.02, 0.0),
        ("fisheye_back_mount", -BASE_HALF_EXTENTS[0] + 0.02, math.pi),
    ):
        base.add_body(name=name, pos=[x, 0.0, top], quat=yaw_quat(yaw).tolist())
    return spec


def add_mobile_robot(
    spec: mujoco.MjSpec,
    pose: tuple[float, float, float] | np.ndarray,
    rig: MobileCameraRig | None = None,
) -> None:
    """Attaches the mobile robot with its cameras to a scene spec (in place), names prefixed
    with ``mobile/``.

    Args:
        spec: the scene's spec (see :func:`factory.sim.compile.build_spec`).
        pose: the base's initial world pose (x, y in m, yaw in rad); ``qpos0`` of the base.
        rig: the robot-mounted cameras; default :class:`MobileCameraRig`.
    """
    robot = mobile_spec(pose, rig)
    spec.attach(robot, frame=spec.worldbody.add_frame(), prefix=PREFIX)


def mobile_robot_model(
    pose: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
) -> mujoco.MjModel:
    """The mobile robot alone (no floor), names as in a scene."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    add_mobile_robot(spec, pose)
    return spec.compile()


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class MobileRobotIndex(FingerTargets):
    """Addresses of the mobile robot in a compiled model.

    Attributes:
        base_qpos: base joint qpos addresses (3,): x, y, yaw.
        base_dof: base joint dof (qvel) addresses (3,).
        ctrl_base: base actuator indices (3,): x, y, yaw targets.
        qpos: arm joint qpos addresses (7,); arm_dof: their dof addresses (7,).
        finger_qpos: finger joint qpos addresses (2,).
        ctrl_arm: arm actuator indices (7,); ctrl_fingers: finger actuator indices (2,).
        base_body: the body of the base frame; site: the tool site; hand: the hand body.
        geoms: every robot geom that collides; base_geoms: those of the base and torso
            (not of the arm or hand); finger_geoms: those of the fingers.
        bodies: robot body ids.
    """

    base_qpos: np.ndarray
    base_dof: np.ndarray
    ctrl_base: np.ndarray
    qpos: np.ndarray
    arm_dof: np.ndarray
    finger_qpos: np.ndarray
    ctrl_arm: np.ndarray
    ctrl_fingers: np.ndarray
    base_body: int
    site: int
    hand: int
    geoms: np.ndarray
    base_geoms: np.ndarray
    finger_geoms: np.ndarray
    bodies: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> MobileRobotIndex:
        def jq(name: str) -> int:
            return int(model.jnt_qposadr[model.joint(name).id])

        def jd(name: str) -> int:
            return int(model.jnt_dofadr[model.joint(name).id])

        bodies = np.array([b for b in range(model.nbody) if model.body(b).name.startswith(PREFIX)])
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        names = [model.body(b).name for b in range(model.nbody)]
        base_bodies = [
            b
            for b in bodies
            if names[b] == BASE_BODY or names[b].startswith(f"{PREFIX}mobilebase0_")
        ]
        finger_bodies = [
            b
            for b in bodies
            if "finger" in names[b] or names[b] == f"{PREFIX}gripper0_right_gripper"
        ]
        return cls(
            base_qpos=np.array([jq(j) for j in BASE_JOINTS]),
            base_dof=np.array([jd(j) for j in BASE_JOINTS]),
            ctrl_base=np.array([model.actuator(a).id for a in BASE_ACTUATORS]),
            qpos=np.array([jq(j) for j in ARM_JOINTS]),
            arm_dof=np.array([jd(j) for j in ARM_JOINTS]),
            finger_qpos=np.array([jq(j) for j in FINGER_JOINTS]),
            ctrl_arm=np.array([model.actuator(f"{PREFIX}robot0_act{i + 1}").id for i in range(7)]),
            ctrl_fingers=np.array(
                [model.actuator(f"{PREFIX}gripper0_act{k + 1}").id for k in range(2)]
            ),
            base_body=int(model.body(BASE_BODY).id),
            site=int(model.site(TOOL_SITE).id),
            hand=int(model.body(HAND_BODY).id),
            geoms=np.flatnonzero(np.isin(model.geom_bodyid, bodies) & collides),
            base_geoms=np.flatnonzero(np.isin(model.geom_bodyid, base_bodies) & collides),
            finger_geoms=np.flatnonzero(np.isin(model.geom_bodyid, finger_bodies) & collides),
            bodies=bodies,
        )

    def base_pose(self, data: mujoco.MjData) -> np.ndarray:
        """The base's world pose (3,): x, y (m), unwrapped yaw (rad)."""
        return np.array(data.qpos[self.base_qpos])

    def stow(self, data: mujoco.MjData) -> None:
        """Puts the arm in ``STOW_QPOS`` with closed fingers, and the arm and finger targets
        there (positions and controls; call ``mj_forward`` after)."""
        data.qpos[self.qpos] = STOW_QPOS
        data.qvel[self.arm_dof] = 0.0
        data.qpos[self.finger_qpos] = self.finger_pos(STOW_FINGERS)
        data.ctrl[self.ctrl_arm] = STOW_QPOS
        data.ctrl[self.ctrl_fingers] = self.gripper_ctrl(STOW_FINGERS)

    def drive_to(self, data: mujoco.MjData, pose: np.ndarray) -> None:
        """Sets the base targets (controls) to a world pose (3,): x, y (m), unwrapped yaw."""
        data.ctrl[self.ctrl_base] = np.asarray(pose, float)
