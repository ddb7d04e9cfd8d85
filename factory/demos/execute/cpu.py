"""Batched execution of planned episodes through the position controller, with recording.

All episodes of one scene run together in one ``mujoco.batch.Batch`` (one simulation per
episode, a thread per core): each recording period, ``Batch.rollout`` applies the per-step
control targets; at every frame the MuJoCo integration state is copied out (exact replay), the
robot's state and the action are recorded, and the named cameras are rendered (RGB + depth).
Nothing is teleported: the arm follows the targets through the actuators and the object moves
only by contact.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from factory.demos.record.contacts import robot_penetration
from factory.demos.record.frame_render import CameraStrip, size_offscreen
from factory.demos.record.payload import STATE_SPEC
from factory.robots.panda import CAMERAS, RobotIndex
from factory.tasks.pick_place.objects import Outcome, check_success, object_poses
from factory.tasks.pick_place.plan import EpisodePlan, SceneSetup, camera_calibration

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecordConfig:
    """What is recorded.

    Attributes:
        fps: frames per second (Hz).
        width, height: image size (px).
        cameras: recording cameras (``left``, ``right``, ``wrist``).
        depth: ``uint16_mm`` (millimetres) or ``float32`` (metres).
        render: render images (off: states and robot signals only).
        shadows: draw the lights' shadows (MuJoCo's shadow maps, :data:`SHADOW_SIZE` px;
            about 2.5x the rendering time).
    """

    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: tuple[str, ...] = ("left", "right", "wrist")
    depth: str = "uint16_mm"
    render: bool = True
    shadows: bool = False


SHADOW_SIZE = 1024
"""Shadow map size (px) of the recording renderer (scene renders use the model's 4096)."""


@dataclass
class Recording:
    """One executed episode's frames (F of them) and its outcome.

    Attributes:
        time: (F,) s; state: (F, nstate) MuJoCo integration state; joint_pos: (F, 7) rad;
        gripper: (F, 1) opening between the fingers (m); ee_pose: (F, 7) tool site position (m)
        and quaternion (w, x, y, z) in the world frame; action: (F, 8) next arm joint targets
        (rad) and gripper command (m; negative squeezes); rgb: camera -> (F, H, W, 3) uint8;
        depth: camera -> (F, H, W) uint16 mm or float32 m; env_state: (F, 14) pick object
        and target poses, see
        :func:`~factory.tasks.pick_place.objects.object_poses`; appearance: the episode's appearance
        randomisation as recorded (an :class:`~factory.schema.episode.EpisodeAppearance`),
        ``None`` when none was applied; camera_poses, camera_fovy: the calibration of the
        recorded cameras fixed in the scene as their images were drawn (camera -> pose (12,)
        in the robot's base frame; camera -> vertical field of view, deg), see
        :func:`calibrate_recordings`; empty without images.
    """

    time: np.ndarray
    state: np.ndarray
    joint_pos: np.ndarray
    gripper: np.ndarray
    ee_pose: np.ndarray
    action: np.ndarray
    rgb: dict[str, np.ndarray] = field(default_factory=dict)
    depth: dict[str, np.ndarray] = field(default_factory=dict)
    env_state: np.ndarray = field(default_factory=lambda: np.zeros((0, 14)))
    outcome: Outcome | None = None
    appearance: Any = None
    camera_poses: dict[str, list[float]] = field(default_factory=dict)
    camera_fovy: dict[str, float] = field(default_factory=dict)
    sim_seconds: float = 0.0
    render_seconds: float = 0.0


class FrameRenderer(CameraStrip):
    """Renders the recording cameras of a composed model: RGB and depth from one GL pass
    (a :class:`~factory.demos.record.frame_render.CameraStrip` of ``cfg.cameras``).

    Reflections, the skybox and multisampling are off (they cost more than the image itself
    at this size), and shadows unless ``cfg.shadows`` (shadow maps of :data:`SHADOW_SIZE`);
    collision geoms (group 3) and sites are hidden. Depth is the depth buffer of the RGB pass,
    so it matches the image: transparent geoms (window glass) do not occlude.

    With ``cull`` (default), as the mobile task's renderer does, the vertex stage (most of a
    frame's time on a CPU renderer, each light adding per-vertex lighting) draws only what a
    view can see: infinite ground planes are drawn as a few large quads instead of MuJoCo's
    200 x 200 grid (the GL context is made from :func:`factory.sim.render_model.render_model`'s
    copy and the scene's plane resized to match; the scene is made from ``model`` itself, so
    appearance patches written into it still show) and each view
    skips the geoms outside its frustum (:class:`factory.sim.frustum.FrustumCuller`, the same
    pixels; nothing is culled while shadows are on). 1.7x (flat look) to 2x (textures and
    room lights) the frames per second on one core (``scripts/bench_recording.py``).
    """

    def __init__(self, model: mujoco.MjModel, cfg: RecordConfig, cull: bool = True) -> None:
        from factory.sim.gl import configure_gl

        configure_gl("auto")
        self.cfg = cfg
        if cfg.shadows:
            model.vis.quality.shadowsize = min(int(model.vis.quality.shadowsize), SHADOW_SIZE)
        size_offscreen(model, len(cfg.cameras) * cfg.width, cfg.height)
        cams = [model.camera(CAMERAS[c]).id for c in cfg.cameras]
        super().__init__(model, cams, cfg.width, cfg.height, cfg.depth, cfg.shadows, cull)


def robot_signals(
    model: mujoco.MjModel, data: mujoco.MjData, robot: RobotIndex
) -> tuple[np.ndarray, float, np.ndarray]:
    """Arm joints (7,) rad, gripper opening (m) and tool pose (7,): position (m) + quaternion
    wxyz, world frame; ``data`` needs current kinematics."""
    q = np.array(data.qpos[robot.qpos])
    fingers = data.qpos[robot.finger_qpos]
    width = float(fingers[0] - fingers[1])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[robot.site])
    ee = np.concatenate([data.site_xpos[robot.site], quat])
    return q, width, ee


def new_recordings(n_frames: list[int], cfg: RecordConfig, nstate: int) -> list[Recording]:
    """Empty recordings of ``n_frames[i]`` frames each (images only when ``cfg.render``)."""
    depth_type = np.uint16 if cfg.depth == "uint16_mm" else np.float32
    return [
        Recording(
            time=np.arange(f) / cfg.fps,
            state=np.zeros((f, nstate)),
            joint_pos=np.zeros((f, 7)),
            gripper=np.zeros((f, 1)),
            ee_pose=np.zeros((f, 7)),
            action=np.zeros((f, 8)),
            env_state=np.zeros((f, 14)),
            rgb={c: np.zeros((f, cfg.height, cfg.width, 3), np.uint8) for c in cfg.cameras}
            if cfg.render
            else {},
            depth={c: np.zeros((f, cfg.height, cfg.width), depth_type) for c in cfg.cameras}
            if cfg.render
            else {},
        )
        for f in n_frames
    ]


def finish_recordings(
    setup: SceneSetup,
    plans: list[EpisodePlan],
    recs: list[Recording],
    n_frames: list[int],
    per_frame: int,
    worst: np.ndarray,
    fps: float,
) -> None:
    """Sets each recording's outcome: the task's success check on its recorded states.

    Args:
        n_frames: frames of each recording; per_frame: physics steps per frame;
        worst: (n,) deepest robot penetration into the scene seen at a recorded frame (m).
    """
    model = setup.model
    pick = model.body(setup.objects.pick.id).id
    qadr = int(model.jnt_qposadr[model.body_jntadr[pick]])
    qpos_slice = slice(1, 1 + model.nq)  # time, then qpos in the integration state
    hold_frames = max(1, round(0.5 * fps))
    for i, p in enumerate(plans):
        rec = recs[i]
        last = n_frames[i] - 1
        lift_frame = min(last, int(np.ceil(p.phases["transport"] / per_frame)))
        q_end = rec.state[last, qpos_slice]
        q_before = rec.state[max(0, last - hold_frames), qpos_slice]
        rec.outcome = check_success(
            model,
            q_end,
            q_before,
            float(rec.state[lift_frame, qpos_slice][qadr + 2]),
            float(rec.state[0, qpos_slice][qadr + 2]),
            setup.objects,
            setup.robot,
            float(worst[i]),
        )


def calibrate_recordings(
    setup: SceneSetup,
    recs: list[Recording],
    cfg: RecordConfig,
    looks: list[tuple[Any, Any]] | None,
) -> None:
    """Sets each recording's ``camera_poses`` and ``camera_fovy``: the calibration of the
    recorded cameras fixed in the scene with the episode's appearance patch (``looks[i][1]``;
    None: the model's own), computed on the host from the model
    (:func:`~factory.tasks.pick_place.plan.camera_calibration`), the same for both executors;
    nothing without images (``cfg.render`` off)."""
    if not cfg.render:
        return
    for i, rec in enumerate(recs):
        patch = looks[i][1] if looks is not None else None
        rec.camera_poses, rec.camera_fovy = camera_calibration(setup, cfg.cameras, patch)


def execute(
    setup: SceneSetup,
    plans: list[EpisodePlan],
    cfg: RecordConfig,
    nthread: int = 0,
    renderer: FrameRenderer | None = None,
    looks: list[tuple[Any, Any]] | None = None,
) -> list[Recording]:
    """Runs the planned episodes of one scene together and records them.

    Args:
        setup: the scene with the robot.
        plans: planned episodes (their ``qpos0`` and ``ctrl``).
        cfg: what to record.
        nthread: simulation threads (0: one per core).
        renderer: a renderer to reuse (made if None and ``cfg.render``).
        looks: per plan, its appearance (an
            :class:`~factory.schema.episode.EpisodeAppearance`) and the model fields it sets
            (a :class:`~factory.demos.record.appearance.ModelPatch`), written into the model before
            each of its frames is drawn; the model is restored at the end. ``None``: the
            model as it is.

    Returns:
        one recording per plan, with its success check and its cameras' calibration
        (:func:`calibrate_recordings`).
    """
    from mujoco.batch import Batch

    model, robot = setup.model, setup.robot
    n = len(plans)
    if n == 0:
        return []
    dt = float(model.opt.timestep)
    per_frame = max(1, round(1.0 / (cfg.fps * dt)))
    lengths = [len(p.ctrl) for p in plans]
    n_frames = [int(np.ceil(t / per_frame)) + 1 for t in lengths]
    total = max(n_frames) - 1
    ctrl = np.zeros((n, total * per_frame, model.nu))
    for i, p in enumerate(plans):
        ctrl[i, : len(p.ctrl)] = p.ctrl
        ctrl[i, len(p.ctrl) :] = p.ctrl[-1]
    batch = Batch(model, n, nthread, persistent=True)
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    qpos = batch.bind("qpos")
    for i, p in enumerate(plans):
        qpos[i] = p.qpos0
    batch.bind("ctrl")[:] = ctrl[:, 0]
    batch.forward()
    own = renderer
    if own is None and cfg.render:
        own = FrameRenderer(model, cfg)
    data = mujoco.MjData(model)
    robot_geom = np.zeros(model.ngeom, bool)
    robot_geom[robot.geoms] = True
    pick = model.body(setup.objects.pick.id).id
    target = model.body(setup.objects.target.id).id
    support = model.body(setup.objects.support.id).id
    allowed = np.isin(model.geom_bodyid, [pick, target, support])
    nstate = mujoco.mj_stateSize(model, STATE_SPEC)
    worst = np.zeros(n)
    recs = new_recordings(n_frames, cfg, nstate)
    sim_s = render_s = 0.0
    if looks is not None:
        from factory.demos.record.appearance import apply_patch, place_cameras_and_lights

    def record(frame: int, states: np.ndarray) -> float:
        """Records frame ``frame`` of every episode from the batch's states (n, nstate)."""
        t0 = time.perf_counter()
        for i in range(n):
            if frame >= n_frames[i]:
                continue
            rec = recs[i]
            if looks is not None:
                apply_patch(model, looks[i][1])
            mujoco.mj_setState(model, data, states[i], STATE_SPEC)
            mujoco.mj_forward(model, data)
            if looks is not None:  # the look's cameras and lights, where forward left them
                place_cameras_and_lights(model, data)
            worst[i] = max(worst[i], robot_penetration(model, data, robot_geom, allowed))
            q, width, ee = robot_signals(model, data, robot)
            rec.state[frame] = states[i]
            rec.joint_pos[frame] = q
            rec.gripper[frame, 0] = width
            rec.ee_pose[frame] = ee
            rec.env_state[frame] = object_poses(data, (pick, target))
            step = min((frame + 1) * per_frame, lengths[i]) - 1
            rec.action[frame] = plans[i].targets[step]
            if own is not None:
                rgbs, depths = own.render(data)
                for c, im, dp in zip(cfg.cameras, rgbs, depths, strict=True):
                    rec.rgb[c][frame] = im
                    rec.depth[c][frame] = dp
        return time.perf_counter() - t0

    own_look = None
    if looks is not None:
        from factory.demos.record.appearance import PATCH_FIELDS

        own_look = {f: np.array(getattr(model, f)) for f in PATCH_FIELDS}
    try:
        render_s += record(0, batch.state)
        for f in range(total):
            t0 = time.perf_counter()
            ctl = ctrl[:, f * per_frame : (f + 1) * per_frame]
            batch.rollout(per_frame, control=ctl, record=())
            sim_s += time.perf_counter() - t0
            render_s += record(f + 1, batch.state)
    finally:
        if own_look is not None:
            for name, value in own_look.items():
                np.copyto(getattr(model, name), value)
    if renderer is None and own is not None:
        own.close()
    finish_recordings(setup, plans, recs, n_frames, per_frame, worst, cfg.fps)
    calibrate_recordings(setup, recs, cfg, looks)
    for i, rec in enumerate(recs):
        rec.appearance = looks[i][0] if looks is not None else None
        rec.sim_seconds = sim_s / n
        rec.render_seconds = render_s / n
    return recs
