"""The Franka Panda with the Panda gripper, composed from robosuite's MJCF robot models.

robosuite 1.5.1's model classes (:class:`robosuite.models.robots.Panda`,
:class:`robosuite.models.grippers.PandaGripper`) give the arm and hand MJCF; its environment
runtime is not used. Here the arm's torque motors become position actuators with the Panda's
torque limits, robot bodies get gravity compensation (as the real controller does), a pedestal
holds the base at table height, and a ``wrist`` camera rides on the hand.

Frames: the robot base frame has +x pointing forward (towards the table), +z up; its origin is
the centre of link0's bottom. The tool frame is the site ``gripper0_grip_site`` between the
finger pads: +z is the approach direction (out of the palm), +x the closing axis.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from factory.robots.robosuite_models import CACHE_KEY as CACHE_KEY  # re-exported
from factory.robots.robosuite_models import ROBOSUITE_VERSION as ROBOSUITE_VERSION  # re-exported
from factory.robots.robosuite_models import robosuite_cache_dir, robosuite_panda_xml
from factory.robots.visual_mesh import VISUAL_FACES, simplify_visual_mesh

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

log = logging.getLogger(__name__)

PREFIX = "panda/"
"""Every name of the robot in a composed model starts with this."""
ARM_JOINTS: tuple[str, ...] = tuple(f"{PREFIX}robot0_joint{i}" for i in range(1, 8))
FINGER_JOINTS: tuple[str, str] = (
    f"{PREFIX}gripper0_finger_joint1",
    f"{PREFIX}gripper0_finger_joint2",
)
TOOL_SITE = f"{PREFIX}gripper0_grip_site"
HAND_BODY = f"{PREFIX}robot0_right_hand"


@dataclass(frozen=True)
class PandaLimits:
    """The Franka Emika Panda's joint limits (datasheet), per arm joint.

    Attributes:
        q_min, q_max: position limits (rad).
        v_max: velocity limits (rad/s).
        a_max: acceleration limits (rad/s^2).
        j_max: jerk limits (rad/s^3).
        tau_max: torque limits (N m).
        finger_max: opening per finger (m); the hand opens to twice this.
    """

    q_min: tuple[float, ...] = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
    q_max: tuple[float, ...] = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
    v_max: tuple[float, ...] = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
    a_max: tuple[float, ...] = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
    j_max: tuple[float, ...] = (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
    tau_max: tuple[float, ...] = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
    finger_max: float = 0.04


PANDA = PandaLimits()

HOME_QPOS = np.array([0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785])
"""A ready pose above the table (rad): tool about 0.45 m in front of the base, pointing down."""

SQUEEZE = 0.01
"""How far past closed a finger target goes when grasping (m): ~2000 N/m x (this + contact)."""
GRIP_CLOSED = -2 * SQUEEZE
GRIP_OPEN = 2 * PANDA.finger_max

_KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
_KV = (450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0)


def rot_z(yaw: float) -> np.ndarray:
    """Rotation (3, 3) by ``yaw`` rad about +z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def yaw_quat(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation by ``yaw`` rad about +z."""
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def pose_matrix(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """4x4 transform from a position (3,) and a rotation (3, 3) or MuJoCo xmat (9,)."""
    out = np.eye(4)
    out[:3, :3] = np.asarray(rot).reshape(3, 3)
    out[:3, 3] = pos
    return out


@dataclass(frozen=True)
class RobotPlacement:
    """Where the robot stands: base position (m, world) and heading (rad about +z)."""

    x: float
    y: float
    z: float
    yaw: float
    pedestal: bool = True

    def pos(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def quat(self) -> np.ndarray:
        return yaw_quat(self.yaw)

    def matrix(self) -> np.ndarray:
        """The base pose (4, 4) in the world frame."""
        return pose_matrix(self.pos(), rot_z(self.yaw))

    def to_world(self, p_base: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` in the base frame -> world frame."""
        return np.asarray(p_base) @ rot_z(self.yaw).T + self.pos()

    def to_base(self, p_world: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` in the world frame -> base frame."""
        return (np.asarray(p_world) - self.pos()) @ rot_z(self.yaw)


CAMERAS: dict[str, str] = {
    "left": "camera_left",
    "right": "camera_right",
    "wrist": f"{PREFIX}wrist_camera",
}
"""Recording camera name -> camera name in the composed model."""
SCENE_CAMERAS = ("left", "right")
"""The recording cameras fixed in the world (:func:`add_robot` places them per scene), whose pose
in the robot's base frame an episode records as their calibration
(:attr:`factory.schema.episode.EpisodeInfo.camera_poses`); the wrist camera rides on the hand
(its pose is forward kinematics of the joints)."""


@dataclass(frozen=True)
class CameraRig:
    """The recording cameras.

    Third-person cameras look at the workspace centre (``workspace`` m ahead of the base, at
    base height) from ``offset`` (m, base frame, relative to that centre); ``left`` is on the
    robot's left (+y). ``wrist`` rides on the hand.
    """

    workspace: float = 0.5
    left_offset: tuple[float, ...] = (-0.05, 0.75, 0.6)
    right_offset: tuple[float, ...] = (-0.05, -0.75, 0.6)
    fovy: float = 50.0
    wrist_fovy: float = 75.0


def robot_cache_dir() -> Path:
    """Where the composed robot MJCF and its meshes are kept (``FACTORY_ROBOT_CACHE``)."""
    return robosuite_cache_dir("panda")


def _robosuite_xml() -> str:
    """The arm + hand MJCF from robosuite's model classes (absolute mesh paths)."""
    return robosuite_panda_xml()


def is_visual_mesh(el: ET.Element) -> bool:
    """Whether an MJCF element is one of robosuite's visual meshes (``<mesh>``, an OBJ or STL
    file, ``_vis`` in its name: ``robot0_link0_vis_3``, ``gripper0_hand_vis``,
    ``mobilebase0_omron_5_vis``); collision meshes are named without it."""
    name, src = el.get("name") or "", el.get("file") or ""
    return el.tag == "mesh" and "_vis" in name and src.lower().endswith((".obj", ".stl"))


def export_mjcf(xml: str, cache: Path, max_faces: int = VISUAL_FACES) -> None:
    """Writes a robosuite MJCF ``xml`` (absolute file paths) with the files it references under
    ``cache`` (``robot.xml`` with relative paths, files under ``files/``), atomically; visual
    meshes (:func:`is_visual_mesh`) are simplified to ``max_faces`` faces each, more for a
    mesh larger than 0.4 m (:func:`factory.robots.visual_mesh.simplify_visual_mesh`; the fixed
    Panda's 135k visual faces become 27k, the mobile robot's 257k 38k), the others copied."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    tmp = cache.with_name(cache.name + f".tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    faces = [0, 0]
    for k, el in enumerate(root.iter()):
        src = el.get("file")
        if not src:
            continue
        rel = f"files/{k:04d}_{Path(src).name}"
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        if is_visual_mesh(el):
            done = simplify_visual_mesh(src, tmp / rel, max_faces)
            faces[0] += done.faces_in
            faces[1] += done.faces_out
        else:
            shutil.copyfile(src, tmp / rel)
        el.set("file", rel)
    log.info("robot cache %s: visual meshes simplified from %d to %d faces", cache.name, *faces)
    (tmp / "robot.xml").write_text(ET.tostring(root, encoding="unicode"))
    cache.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.rename(tmp, cache)
    except OSError:  # another process wrote it first
        shutil.rmtree(tmp, ignore_errors=True)


def cached_mjcf(cache: Path, make_xml: Callable[[], str]) -> str:
    """The MJCF kept in ``cache`` with absolute file paths, exported from ``make_xml()`` (a
    robosuite composition) the first time; ``make_xml()`` itself where the cache is not
    writable."""
    import xml.etree.ElementTree as ET

    if not (cache / "robot.xml").is_file():
        try:
            export_mjcf(make_xml(), cache)
        except OSError as e:  # unwritable cache: use robosuite's paths directly
            log.info("robot cache %s not writable (%s); using robosuite's files", cache, e)
            return make_xml()
    root = ET.fromstring((cache / "robot.xml").read_text())
    for el in root.iter():
        if el.get("file"):
            el.set("file", str(cache / el.get("file", "")))
    return ET.tostring(root, encoding="unicode")


def export_robot(cache: Path) -> None:
    """Writes robosuite's composed Panda MJCF and its files under ``cache``."""
    export_mjcf(_robosuite_xml(), cache)


@functools.lru_cache(maxsize=1)
def _robot_xml() -> str:
    """The Panda MJCF with absolute file paths: from the cache, made from robosuite once."""
    return cached_mjcf(robot_cache_dir(), _robosuite_xml)


def add_panda_actuators(spec: mujoco.MjSpec) -> None:
    """Appends the Panda's position actuators to a robosuite Panda spec (in place):
    ``robot0_act1..7`` (arm joint targets, rad, with the Panda's torque limits), then the two
    finger actuators ``gripper0_act1..2`` (m)."""
    for i in range(7):
        act = spec.add_actuator(name=f"robot0_act{i + 1}", target=f"robot0_joint{i + 1}")
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=_KP[i], kv=_KV[i])
        act.ctrllimited = True
        act.ctrlrange = [PANDA.q_min[i], PANDA.q_max[i]]
        act.forcelimited = True
        act.forcerange = [-PANDA.tau_max[i], PANDA.tau_max[i]]
    for k in range(2):
        act = spec.add_actuator(name=f"gripper0_act{k + 1}", target=f"gripper0_finger_joint{k + 1}")
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=2000.0, kv=20.0)
        act.ctrllimited = True
        # Targets reach past the closed stop so that a closed hand keeps squeezing.
        act.ctrlrange = [-SQUEEZE, PANDA.finger_max] if k == 0 else [-PANDA.finger_max, SQUEEZE]
        act.forcelimited = True
        act.forcerange = [-40.0, 40.0]


def finish_panda_spec(
    spec: mujoco.MjSpec, wrist_fovy: float, no_gravcomp: tuple[str, ...] = ()
) -> None:
    """Finishes a robosuite Panda spec (in place): gravity compensation for the arm and hand
    bodies, grippy finger pads, collision geoms hidden from cameras, and the ``wrist`` camera.

    Args:
        spec: the robot's spec (names without a prefix).
        wrist_fovy: vertical field of view of the ``wrist`` camera (deg).
        no_gravcomp: ``robot0_``/``gripper0_`` bodies left without gravity compensation.
    """
    for body in spec.bodies:
        if body.name.startswith(("robot0_", "gripper0_")) and body.name not in no_gravcomp:
            body.gravcomp = 1.0
    # Finger pads grip with high friction, as robosuite sets them. Collision geoms go to
    # group 3, which cameras do not draw (the visual meshes are in groups 1-2).
    for geom in spec.geoms:
        if "pad_collision" in geom.name:
            geom.friction = [2.0, 0.05, 0.0001]
            geom.condim = 4
        if geom.contype or geom.conaffinity:
            geom.group = 3
    spec.body("robot0_right_hand").add_camera(
        name="wrist_camera",
        pos=[0.05, 0.0, 0.0],
        quat=[0.0, 0.707108, 0.707108, 0.0],
        fovy=wrist_fovy,
    )


def panda_spec(pedestal_height: float = 0.0, wrist_fovy: float = 75.0) -> mujoco.MjSpec:
    """The Panda arm + gripper as an MjSpec, with position-controlled joints.

    Args:
        pedestal_height: height of a column under the base (m); 0 for none.
        wrist_fovy: vertical field of view of the ``wrist`` camera (deg).

    Returns:
        a spec whose actuators are ``robot0_act1..7`` (joint position targets, rad) and the two
        finger position actuators (m), in that order.
    """
    spec = mujoco.MjSpec.from_string(_robot_xml())
    spec.compiler.degree = False
    for act in list(spec.actuators):
        if act.name.startswith("robot0_torq"):
            spec.delete(act)
    fingers = list(spec.actuators)
    for act in fingers:  # re-added after the arm so that the order is arm, fingers
        spec.delete(act)
    add_panda_actuators(spec)
    finish_panda_spec(spec, wrist_fovy)
    base = spec.body("robot0_base")
    if pedestal_height > 0:
        base.add_geom(
            name="robot0_pedestal",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[0.11, pedestal_height / 2, 0],
            pos=[-0.02, 0.0, -pedestal_height / 2],
            rgba=[0.55, 0.56, 0.58, 1.0],
        )
    return spec


def _look_quat(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Quaternion of a MuJoCo camera at ``eye`` looking at ``target`` (world z up)."""
    fwd = target - eye
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right = right / np.linalg.norm(right)
    up = np.cross(right, fwd)
    mat = np.stack([right, up, -fwd], axis=1)  # camera x, y, z axes as columns
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, mat.reshape(-1))
    return q


def add_robot(
    spec: mujoco.MjSpec,
    placement: RobotPlacement,
    rig: CameraRig | None = None,
) -> None:
    """Attaches the Panda and the recording cameras to a scene spec (in place).

    Args:
        spec: the scene's spec (see :func:`factory.sim.compile.build_spec`).
        placement: where the base stands; with ``pedestal`` a column reaches the floor.
        rig: the third-person cameras; default :class:`CameraRig`.
    """
    rig = rig or CameraRig()
    robot = panda_spec(placement.z if placement.pedestal else 0.0, rig.wrist_fovy)
    frame = spec.worldbody.add_frame(pos=placement.pos().tolist(), quat=placement.quat().tolist())
    spec.attach(robot, frame=frame, prefix=PREFIX)
    center = placement.to_world(np.array([rig.workspace, 0.0, 0.0]))
    for name, offset in (("left", rig.left_offset), ("right", rig.right_offset)):
        eye = placement.to_world(np.array([rig.workspace, 0.0, 0.0]) + np.asarray(offset))
        spec.worldbody.add_camera(
            name=CAMERAS[name],
            pos=eye.tolist(),
            quat=_look_quat(eye, center).tolist(),
            fovy=rig.fovy,
        )


def robot_model() -> mujoco.MjModel:
    """The robot alone (base at the origin, no pedestal), for IK; names as in a scene."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.attach(panda_spec(), frame=spec.worldbody.add_frame(), prefix=PREFIX)
    return spec.compile()


class FingerTargets:
    """The Panda hand's finger values for a total opening, shared by the robot indexes."""

    def gripper_ctrl(self, opening: float) -> np.ndarray:
        """Finger targets (2,) for a total opening (m): 0.08 open, negative squeezes."""
        half = float(np.clip(opening / 2, -SQUEEZE, PANDA.finger_max))
        return np.array([half, -half])

    def gripper_ctrls(self, openings: np.ndarray) -> np.ndarray:
        """:meth:`gripper_ctrl` of many openings at once: (T,) m -> (T, 2)."""
        half = np.clip(np.asarray(openings, float) / 2, -SQUEEZE, PANDA.finger_max)
        return np.stack([half, -half], axis=-1)

    def finger_pos(self, opening: float) -> np.ndarray:
        """Finger joint positions (2,) for a total opening (m), within the joint range."""
        half = float(np.clip(opening / 2, 0.0, PANDA.finger_max))
        return np.array([half, -half])


@dataclass
class RobotIndex(FingerTargets):
    """Addresses of the robot in a compiled model (ids into qpos, qvel, ctrl, bodies, geoms).

    Attributes:
        qpos: arm joint qpos addresses (7,).
        finger_qpos: finger joint qpos addresses (2,).
        ctrl_arm: arm actuator indices (7,); ctrl_fingers: finger actuator indices (2,).
        site: the tool site id; hand: the hand body id.
        geoms: every robot geom that collides (contype or conaffinity set).
        finger_geoms: geoms of the finger bodies (allowed to touch the grasped object).
        bodies: robot body ids.
    """

    qpos: np.ndarray
    finger_qpos: np.ndarray
    ctrl_arm: np.ndarray
    ctrl_fingers: np.ndarray
    site: int
    hand: int
    geoms: np.ndarray
    finger_geoms: np.ndarray
    bodies: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> RobotIndex:
        def jq(name: str) -> int:
            return int(model.jnt_qposadr[model.joint(name).id])

        bodies = np.array([b for b in range(model.nbody) if model.body(b).name.startswith(PREFIX)])
        in_robot = np.isin(model.geom_bodyid, bodies)
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        finger_bodies = [
            b
            for b in bodies
            if "finger" in model.body(b).name
            or model.body(b).name == f"{PREFIX}gripper0_right_gripper"
        ]
        return cls(
            qpos=np.array([jq(j) for j in ARM_JOINTS]),
            finger_qpos=np.array([jq(j) for j in FINGER_JOINTS]),
            ctrl_arm=np.array([model.actuator(f"{PREFIX}robot0_act{i + 1}").id for i in range(7)]),
            ctrl_fingers=np.array(
                [model.actuator(f"{PREFIX}gripper0_act{k + 1}").id for k in range(2)]
            ),
            site=int(model.site(TOOL_SITE).id),
            hand=int(model.body(HAND_BODY).id),
            geoms=np.flatnonzero(in_robot & collides),
            finger_geoms=np.flatnonzero(np.isin(model.geom_bodyid, finger_bodies) & collides),
            bodies=bodies,
        )
