"""The recording pieces of the articulated tasks' episodes, on the tasks' floor: what is
recorded (:class:`RecordConfig`, :class:`Recording`), the cameras' renderer
(:class:`ArticulatedRenderer`) and the same cameras as a renderer of recorded states needs them
(:func:`camera_rig`: the GPU pipeline draws them on MuJoCo Warp), and the robot's signals and
contacts per frame.

They match the fixed task's (:mod:`factory.demos.execute.cpu`, a floor above the tasks, which
a task package does not import): the same settings, arrays, renderer set-up (one
:class:`~factory.demos.record.frame_render.CameraStrip` of the recording cameras, collision
geoms hidden, frustum culling) and signal definitions, so that the stored episodes, the dataset
export and the evaluation env read them the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from factory.demos.record.contacts import robot_penetration
from factory.demos.record.frame_render import CameraStrip, size_offscreen
from factory.robots.panda import CAMERAS, RobotIndex

if TYPE_CHECKING:
    from factory.demos.record.rig import CameraRig

__all__ = [
    "SHADOW_SIZE",
    "ArticulatedRenderer",
    "RecordConfig",
    "Recording",
    "camera_rig",
    "robot_penetration",
    "robot_signals",
]

SHADOW_SIZE = 1024
"""Shadow map size (px) of the recording renderer when shadows are on."""


@dataclass(frozen=True)
class RecordConfig:
    """What is recorded (as the fixed task's ``RecordConfig``).

    Attributes:
        fps: frames per second (Hz).
        width, height: image size (px).
        cameras: recording cameras (``left``, ``right``, ``wrist``).
        depth: ``uint16_mm`` (millimetres) or ``float32`` (metres).
        render: render images (off: states and robot signals only).
        shadows: draw the lights' shadows.
    """

    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: tuple[str, ...] = ("left", "right", "wrist")
    depth: str = "uint16_mm"
    render: bool = True
    shadows: bool = False


@dataclass
class Recording:
    """One executed episode's frames (F of them) and its outcome.

    Attributes:
        time: (F,) s; state: (F, nstate) MuJoCo integration state; joint_pos: (F, 7) rad;
        gripper: (F, 1) opening between the fingers (m); ee_pose: (F, 7) tool site position
        (m) and quaternion wxyz, world frame; action: (F, 8) arm joint targets (rad) and
        gripper command (m) at the end of each frame; env_state: (F, 11) the part's joint
        and its handle seen from the robot (:func:`~factory.tasks.articulated.execute.
        env_state`); rgb: camera -> (F, H, W, 3) uint8; depth:
        camera -> (F, H, W) uint16 mm or float32 m; outcome: the success check.
    """

    time: np.ndarray
    state: np.ndarray
    joint_pos: np.ndarray
    gripper: np.ndarray
    ee_pose: np.ndarray
    action: np.ndarray
    env_state: np.ndarray
    rgb: dict[str, np.ndarray] = field(default_factory=dict)
    depth: dict[str, np.ndarray] = field(default_factory=dict)
    outcome: Any = None
    sim_seconds: float = 0.0
    render_seconds: float = 0.0


class ArticulatedRenderer(CameraStrip):
    """RGB and depth of the recording cameras from one GL pass (reflections, skybox and
    multisampling off; shadows only with ``cfg.shadows``; frustum culling with ``cull``)."""

    def __init__(self, model: mujoco.MjModel, cfg: RecordConfig, cull: bool = True) -> None:
        from factory.sim.gl import configure_gl

        configure_gl("auto")
        self.cfg = cfg
        if cfg.shadows:
            model.vis.quality.shadowsize = min(int(model.vis.quality.shadowsize), SHADOW_SIZE)
        size_offscreen(model, len(cfg.cameras) * cfg.width, cfg.height)
        cams = [model.camera(CAMERAS[c]).id for c in cfg.cameras]
        super().__init__(model, cams, cfg.width, cfg.height, cfg.depth, cfg.shadows, cull)


def camera_rig(cfg: RecordConfig) -> CameraRig:
    """The cameras :class:`ArticulatedRenderer` draws with ``cfg``, for a renderer of recorded
    states (the GPU pipeline's): the fixed-base Panda's pinhole cameras
    (:data:`factory.robots.panda.CAMERAS`: ``left`` and ``right`` fixed in the scene, ``wrist``
    on the hand), ``width`` x ``height`` px each, in ``cfg.cameras``' order, and the depth
    format."""
    from factory.demos.record.rig import CameraRig, RigCamera

    return CameraRig(
        tuple(RigCamera(c, CAMERAS[c], cfg.width, cfg.height) for c in cfg.cameras), cfg.depth
    )


def robot_signals(
    model: mujoco.MjModel, data: mujoco.MjData, robot: RobotIndex
) -> tuple[np.ndarray, float, np.ndarray]:
    """Arm joints (7,) rad, gripper opening (m) and tool pose (7,): position (m) + quaternion
    wxyz, world frame; ``data`` needs current kinematics."""
    q = np.array(data.qpos[robot.qpos])
    fingers = data.qpos[robot.finger_qpos]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[robot.site])
    return q, float(fingers[0] - fingers[1]), np.concatenate([data.site_xpos[robot.site], quat])
