"""Executing a planned mobile episode: simulate, record, check success, render, replay.

:func:`execute_mobile` simulates an episode's per-step controls in one ``mujoco.MjData``,
records a frame every ``1 / fps`` s (integration state, base pose, arm, gripper, tool pose,
action, sub-task labels), checks success (:func:`check_mobile_success`) and only then draws the
images of the five cameras (``left``, ``right``, ``wrist`` and the fisheye cameras
``fisheye_front``/``fisheye_back``) from the recorded states (:func:`render_frames`): a failed
episode costs its physics alone. :func:`replay` re-simulates a recording from its first state.
Nothing is teleported.

Frames: world frame for poses (m, rad); the base pose is the footprint centre's (x, y) and the
unwrapped yaw (the base joints' values).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from factory.demos.record.frame_render import CameraStrip, encode_depth, size_offscreen
from factory.demos.record.payload import STATE_SPEC
from factory.nav import BASE_COLLISION
from factory.robots.mobile_panda import CAMERAS
from factory.tasks.mobile_pick_place.scene import (
    ALL_CAMERAS,
    COLLISION,
    FISHEYE_CAMERAS,
    MobileSetup,
    MobileTaskError,
    body_box,
    support_top,
)
from factory.tasks.pick_place.objects import Outcome, object_poses

if TYPE_CHECKING:
    from factory.demos.record.rig import CameraRig
    from factory.tasks.mobile_pick_place.plan import MobileEpisodePlan

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MobileRecordConfig:
    """What a mobile episode records.

    Attributes:
        fps: frames per second (Hz).
        width, height: pinhole image size (px); the fisheye images are ``width`` square.
        cameras: recording cameras, from :data:`ALL_CAMERAS`.
        depth: ``uint16_mm`` (millimetres) or ``float32`` (metres); pinhole depth is along the
            optical axis, fisheye depth is the ray length.
        render: render images (off: states and signals only).
        fisheye_fov_deg: full field of view of the fisheye cameras (deg).
    """

    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: tuple[str, ...] = ALL_CAMERAS
    depth: str = "uint16_mm"
    render: bool = True
    fisheye_fov_deg: float = 180.0

    def __post_init__(self) -> None:
        unknown = [c for c in self.cameras if c not in ALL_CAMERAS]
        if unknown:
            raise MobileTaskError(f"unknown camera(s) {unknown}: choose from {ALL_CAMERAS}")
        if self.depth not in ("uint16_mm", "float32"):
            raise MobileTaskError(f"depth must be uint16_mm or float32, got {self.depth!r}")


@dataclass
class MobileRecording:
    """One executed mobile episode (F frames) and its outcome.

    Attributes:
        time: (F,) s. state: (F, nstate) MuJoCo integration state (``mj_setState`` with
            ``mjSTATE_INTEGRATION`` reproduces the frame).
        base_pose: (F, 3) base x, y (m) and unwrapped yaw (rad), world frame.
        joint_pos: (F, 7) arm joints (rad). gripper: (F, 1) finger opening (m).
        ee_pose: (F, 7) tool site position (m) + quaternion wxyz, world frame.
        action: (F, 11) targets at the end of the frame: arm (7, rad), gripper (m), base x, y
            (m), yaw (rad).
        subtask: (F,) int8 label id (index into :data:`SUBTASKS`) of the frame's period.
        subtask_done: (F,) bool: true on the last frame of each sub-task.
        env_state: (F, 14) the pick object's and the place support's position (m) and
            quaternion wxyz, world frame (:func:`~factory.tasks.pick_place.objects.object_poses`:
            the fixed task's ``env_state``).
        rgb: camera -> (F, H, W, 3) uint8; depth: camera -> (F, H, W) uint16 mm or float32 m.
        ctrl: (S, nu) the controls of every physics step simulated (S = (F - 1) x steps per
            frame): replaying them from ``state[0]`` reproduces the episode.
        outcome: the success check.
        max_base_penetration, max_arm_penetration: deepest contact of the base / the arm and
            hand with the scene over every physics step (m).
        sim_seconds, render_seconds: wall time (s).
    """

    time: np.ndarray
    state: np.ndarray
    base_pose: np.ndarray
    joint_pos: np.ndarray
    gripper: np.ndarray
    ee_pose: np.ndarray
    action: np.ndarray
    subtask: np.ndarray
    subtask_done: np.ndarray
    env_state: np.ndarray = field(default_factory=lambda: np.zeros((0, 14)))
    rgb: dict[str, np.ndarray] = field(default_factory=dict)
    depth: dict[str, np.ndarray] = field(default_factory=dict)
    ctrl: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    outcome: Outcome | None = None
    max_base_penetration: float = 0.0
    max_arm_penetration: float = 0.0
    sim_seconds: float = 0.0
    render_seconds: float = 0.0


class MobileRenderer:
    """Renders the mobile robot's recording cameras: the pinhole ones (``left``, ``right``,
    ``wrist``) side by side in one GL pass, RGB and depth read together (a
    :class:`~factory.demos.record.frame_render.CameraStrip`, as
    :class:`factory.demos.execute.cpu.FrameRenderer`), and the fisheye ones through
    :class:`factory.sim.fisheye.FisheyeRenderer` (its own GL context).

    On a CPU renderer the cost of a frame is its 13 draws (3 pinhole views, 2 x 5 fisheye cube
    faces), each sending the geometry through the vertex stage, so each draw gets only what
    it can see: the model is drawn from :func:`factory.sim.render_model.render_model` (the
    infinite ground plane as 16 quads instead of 40,000) and each view skips the geoms
    outside its frustum (:class:`factory.sim.frustum.FrustumCuller`, ``cull``; the same
    images bit for bit).

    Args:
        model: the compiled scene (physics model; not changed).
        cfg: cameras, image size and depth format.
        cull: frustum culling per view.
    """

    def __init__(self, model: mujoco.MjModel, cfg: MobileRecordConfig, cull: bool = True) -> None:
        from factory.sim.fisheye import FisheyeRenderer, FisheyeSpec
        from factory.sim.gl import configure_gl
        from factory.sim.render_model import render_model

        configure_gl("auto")
        model = render_model(model)  # the ground plane as 16 quads, not 40,000
        self.cfg = cfg
        self.pinhole = [c for c in cfg.cameras if c in CAMERAS]
        self.fisheye = [c for c in cfg.cameras if c in FISHEYE_CAMERAS]
        self.strip: CameraStrip | None = None
        self.fish: FisheyeRenderer | None = None
        n, w, h = len(self.pinhole), cfg.width, cfg.height
        if n:
            size_offscreen(model, n * w, h)
            cams = [model.camera(CAMERAS[c]).id for c in self.pinhole]
            self.strip = CameraStrip(model, cams, w, h, cfg.depth, cull=cull)
        if self.fisheye:
            spec = FisheyeSpec(resolution=cfg.width, fov_deg=cfg.fisheye_fov_deg)
            self.fish = FisheyeRenderer(model, spec, cull=cull)
            self.fish_ids = {c: model.camera(FISHEYE_CAMERAS[c]).id for c in self.fisheye}

    def render(self, data: mujoco.MjData) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB (H, W, 3) uint8, depth (H, W)) of the state in ``data`` (current
        kinematics needed)."""
        out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if self.strip is not None:
            rgbs, depths = self.strip.render(data)
            for c, im, dp in zip(self.pinhole, rgbs, depths, strict=True):
                out[c] = (im, dp)
        if self.fish is not None:
            for c in self.fisheye:
                im, dp = self.fish.render(data, self.fish_ids[c])
                out[c] = (im, encode_depth(dp, self.cfg.depth))
        return out

    def close(self) -> None:
        """Frees the GL contexts."""
        if self.strip is not None:
            self.strip.close()
        if self.fish is not None:
            self.fish.close()


def camera_rig(cfg: MobileRecordConfig) -> CameraRig:
    """The cameras :class:`MobileRenderer` draws with ``cfg``, for a renderer of recorded
    states (the GPU pipeline's): the pinhole cameras on the robot
    (:data:`factory.robots.mobile_panda.CAMERAS`, ``width`` x ``height`` px) and the fisheye
    cameras (:data:`~factory.tasks.mobile_pick_place.scene.FISHEYE_CAMERAS`, ``width`` px
    square, an equidistant lens of ``fisheye_fov_deg``), in ``cfg.cameras``' order."""
    from factory.demos.record.rig import CameraRig, RigCamera
    from factory.sim.fisheye import FisheyeSpec

    cams = []
    for c in cfg.cameras:
        if c in FISHEYE_CAMERAS:
            lens = FisheyeSpec(resolution=cfg.width, fov_deg=cfg.fisheye_fov_deg)
            cams.append(RigCamera(c, FISHEYE_CAMERAS[c], cfg.width, cfg.width, lens))
        else:
            cams.append(RigCamera(c, CAMERAS[c], cfg.width, cfg.height))
    return CameraRig(tuple(cams), cfg.depth)


def penetrations(
    data: mujoco.MjData,
    base_geom: np.ndarray,
    arm_geom: np.ndarray,
    arm_allowed: np.ndarray,
    base_allowed: np.ndarray,
) -> tuple[float, float]:
    """Deepest contact (m) of a base geom and of an arm/hand geom with a scene geom, over the
    current contacts (vectorized over ``data.contact``)."""
    n = data.ncon
    if not n:
        return 0.0, 0.0
    geom = data.contact.geom[:n]
    depth = -data.contact.dist[:n]
    robot = base_geom | arm_geom
    r1, r2 = robot[geom[:, 0]], robot[geom[:, 1]]
    mixed = r1 != r2
    if not mixed.any():
        return 0.0, 0.0
    rg = np.where(r1, geom[:, 0], geom[:, 1])[mixed]
    other = np.where(r1, geom[:, 1], geom[:, 0])[mixed]
    d = depth[mixed]
    on_base = base_geom[rg] & ~base_allowed[other]
    on_arm = arm_geom[rg] & ~base_geom[rg] & ~arm_allowed[other]
    worst_base = float(d[on_base].max()) if on_base.any() else 0.0
    worst_arm = float(d[on_arm].max()) if on_arm.any() else 0.0
    return max(worst_base, 0.0), max(worst_arm, 0.0)


def simulate(
    setup: MobileSetup,
    state0: np.ndarray,
    ctrl: np.ndarray,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
    targets: np.ndarray | None = None,
    subtask: np.ndarray | None = None,
    images: bool = True,
) -> MobileRecording:
    """Runs per-step controls from an integration state and records frames at ``cfg.fps``.

    Frame ``f`` is the state after ``f * k`` physics steps (``k`` steps per frame). The
    physics and the per-frame signals come first; the images are drawn afterwards from the
    recorded states (:func:`render_frames`), each from a separate ``MjData`` (``mj_setState`` +
    ``mj_forward``), so the simulation is the same whether or not it is rendered, and a replay
    from ``state0`` with the same ``ctrl`` reproduces the states and images exactly.

    Args:
        setup: the composed scene.
        state0: initial integration state (nstate,).
        ctrl: controls per physics step (S, nu); S should be a multiple of the steps per frame.
        cfg: what to record.
        renderer: a renderer to reuse (made if None and images are drawn).
        targets, subtask: per-step action (S, 11) and sub-task labels (S,); when given,
            recorded per frame: the action at the frame period's last step, the label at its
            first, and the done flag on the last frame of each sub-task.
        images: draw the images now (when ``cfg.render``); False leaves ``rgb``/``depth``
            empty for a later :func:`render_frames`.

    Returns:
        the recording, without outcome.
    """
    model, robot = setup.model, setup.robot
    dt = float(model.opt.timestep)
    k = max(1, round(1.0 / (cfg.fps * dt)))
    n_steps = len(ctrl)
    n_frames = math.ceil(n_steps / k) + 1
    total = (n_frames - 1) * k
    if total > n_steps:
        ctrl = np.concatenate([ctrl, np.repeat(ctrl[-1:], total - n_steps, axis=0)])
    nstate = mujoco.mj_stateSize(model, STATE_SPEC)
    rec = MobileRecording(
        time=np.arange(n_frames) / cfg.fps,
        state=np.zeros((n_frames, nstate)),
        base_pose=np.zeros((n_frames, 3)),
        joint_pos=np.zeros((n_frames, 7)),
        gripper=np.zeros((n_frames, 1)),
        ee_pose=np.zeros((n_frames, 7)),
        action=np.zeros((n_frames, 11)),
        subtask=np.zeros(n_frames, np.int8),
        subtask_done=np.zeros(n_frames, bool),
        env_state=np.zeros((n_frames, 14)),
        ctrl=np.array(ctrl),
    )
    data = mujoco.MjData(model)
    view = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state0, STATE_SPEC)
    base_geom = np.zeros(model.ngeom, bool)
    base_geom[robot.base_geoms] = True
    arm_geom = np.zeros(model.ngeom, bool)
    arm_geom[robot.geoms] = True
    arm_geom &= ~base_geom
    objs = setup.objects
    pick = model.body(objs.pick.id).id
    supports = [model.body(objs.pick_support.id).id, model.body(objs.place_support.id).id]
    base_allowed = np.isin(model.geom_bodyid, [pick])
    arm_allowed = np.isin(model.geom_bodyid, [pick, *supports])
    env_bodies = (pick, supports[1])
    worst_b = worst_a = 0.0
    quat = np.zeros(4)

    def record(f: int) -> None:
        mujoco.mj_getState(model, data, rec.state[f], STATE_SPEC)
        mujoco.mj_setState(model, view, rec.state[f], STATE_SPEC)
        mujoco.mj_kinematics(model, view)
        rec.base_pose[f] = view.qpos[robot.base_qpos]
        rec.joint_pos[f] = view.qpos[robot.qpos]
        fingers = view.qpos[robot.finger_qpos]
        rec.gripper[f, 0] = float(fingers[0] - fingers[1])
        mujoco.mju_mat2Quat(quat, view.site_xmat[robot.site])
        rec.ee_pose[f] = np.concatenate([view.site_xpos[robot.site], quat])
        rec.env_state[f] = object_poses(view, env_bodies)
        last = min((f + 1) * k, n_steps) - 1
        if targets is not None:
            rec.action[f] = targets[last]
        if subtask is not None:
            first = min(f * k, n_steps - 1)
            rec.subtask[f] = subtask[first]

    t0 = time.perf_counter()
    record(0)
    for f in range(1, n_frames):
        for s in range((f - 1) * k, f * k):
            data.ctrl[:] = ctrl[s]
            mujoco.mj_step(model, data)
            if data.ncon:
                b, a = penetrations(data, base_geom, arm_geom, arm_allowed, base_allowed)
                worst_b, worst_a = max(worst_b, b), max(worst_a, a)
        record(f)
    if subtask is not None:
        rec.subtask_done[:-1] = rec.subtask[1:] != rec.subtask[:-1]
        rec.subtask_done[-1] = True
    rec.max_base_penetration = worst_b
    rec.max_arm_penetration = worst_a
    rec.sim_seconds = time.perf_counter() - t0
    if images and cfg.render:
        render_frames(setup, rec, cfg, renderer)
    return rec


def render_frames(
    setup: MobileSetup,
    rec: MobileRecording,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
) -> None:
    """Draws every camera of ``cfg`` for every recorded state into ``rec.rgb``/``rec.depth``.

    Each frame is the state ``rec.state[f]`` set into a fresh ``MjData`` and ``mj_forward``ed,
    so the images depend on the recorded state alone (the same before or after the success
    check, and in a replay). Adds the wall time to ``rec.render_seconds``.

    Args:
        setup: the composed scene.
        rec: a recording with its states.
        cfg: cameras, image size and depth format.
        renderer: a renderer to reuse (made and closed here if None).
    """
    model = setup.model
    t0 = time.perf_counter()
    n_frames = len(rec.state)
    depth_type = np.uint16 if cfg.depth == "uint16_mm" else np.float32
    for c in cfg.cameras:
        side = (cfg.width, cfg.width) if c in FISHEYE_CAMERAS else (cfg.height, cfg.width)
        rec.rgb[c] = np.zeros((n_frames, *side, 3), np.uint8)
        rec.depth[c] = np.zeros((n_frames, *side), depth_type)
    own = renderer or MobileRenderer(model, cfg)
    view = mujoco.MjData(model)
    try:
        for f in range(n_frames):
            mujoco.mj_setState(model, view, rec.state[f], STATE_SPEC)
            mujoco.mj_forward(model, view)
            for c, (im, dp) in own.render(view).items():
                rec.rgb[c][f] = im
                rec.depth[c][f] = dp
    finally:
        if renderer is None:
            own.close()
    rec.render_seconds += time.perf_counter() - t0


def check_mobile_success(
    setup: MobileSetup,
    rec: MobileRecording,
    plan: MobileEpisodePlan,
    fps: float,
    settle_tol: float = 0.005,
    speed_tol: float = 0.02,
    above_tol: float = 0.03,
    penetration_tol: float = 0.02,
) -> Outcome:
    """Whether an executed mobile episode succeeded (:func:`mobile_outcome` of its last frame).

    The lift is the object's height at the first frame of ``navigate_to_place`` above its
    height at the start; the settling motion is measured over the last 0.5 s.
    """
    model = setup.model
    qs = slice(1, 1 + model.nq)
    adr = int(model.jnt_qposadr[model.body_jntadr[model.body(setup.objects.pick.id).id]])
    hold = max(1, round(0.5 * fps))
    k = max(1, round(1.0 / (fps * float(model.opt.timestep))))
    start_z = float(rec.state[0, qs][adr + 2])
    lift_frame = min(len(rec.state) - 1, plan.phases["navigate_to_place"] // k)
    lifted = float(rec.state[lift_frame, qs][adr + 2]) - start_z
    return mobile_outcome(
        setup,
        rec.state[-1],
        rec.state[max(0, len(rec.state) - 1 - hold)],
        lifted,
        rec.max_base_penetration,
        rec.max_arm_penetration,
        settle_tol,
        speed_tol,
        above_tol,
        penetration_tol,
    )


def mobile_outcome(
    setup: MobileSetup,
    state_end: np.ndarray,
    state_before: np.ndarray,
    lifted: float,
    base_penetration: float,
    arm_penetration: float,
    settle_tol: float = 0.005,
    speed_tol: float = 0.02,
    above_tol: float = 0.03,
    penetration_tol: float = 0.02,
    data: mujoco.MjData | None = None,
) -> Outcome:
    """The mobile task's success check on an episode's last state (shared by the demos and the
    closed-loop env, :mod:`factory.tasks.mobile_pick_place.env`).

    The object rose with the hand (``lifted`` >= 3 cm, else ``slip``), its bottom ends within
    ``above_tol`` (m) above the place support's top and its centre inside the support's
    footprint (else ``not_on_target``), no finger touches it (``not_released``), it moved less
    than ``settle_tol`` (m) since ``state_before`` (0.5 s earlier) and its speed is below
    ``speed_tol`` (m/s) (``unstable``); the base never pressed more than ``penetration_tol`` (m)
    into the scene (``base_collision``) nor the arm or hand into anything but the task objects
    (``collision``).

    Args:
        setup: the composed scene.
        state_end, state_before: integration states (nstate,) at the end and 0.5 s before.
        lifted: how high the object was lifted (m).
        base_penetration, arm_penetration: deepest contacts over the episode (m).
        settle_tol, speed_tol, above_tol, penetration_tol: the tolerances above.
        data: scratch data to use (else a new one).
    """
    model, robot = setup.model, setup.robot
    objs = setup.objects
    qs = slice(1, 1 + model.nq)
    vs = slice(1 + model.nq, 1 + model.nq + model.nv)
    data = data if data is not None else mujoco.MjData(model)
    mujoco.mj_setState(model, data, state_end, STATE_SPEC)
    mujoco.mj_forward(model, data)
    pick = model.body(objs.pick.id).id
    support = model.body(objs.place_support.id).id
    adr = int(model.jnt_qposadr[model.body_jntadr[pick]])
    dof = int(model.jnt_dofadr[model.body_jntadr[pick]])
    obj_box = body_box(model, data, pick)
    sup_box = body_box(model, data, support)
    top = support_top(model, data, support)
    centre = data.xipos[pick]
    # the support's footprint: its top's rectangle in its own frame (scene dimensions)
    sup = objs.place_support
    local = data.xmat[support].reshape(3, 3).T @ (centre - data.xpos[support])
    inside = bool(
        abs(local[0]) <= sup.dimensions.width / 2 and abs(local[1]) <= sup.dimensions.length / 2
    ) and bool((centre[:2] >= sup_box[:2]).all() and (centre[:2] <= sup_box[3:5]).all())
    q_end = state_end[qs]
    q_before = state_before[qs]
    moved = float(np.linalg.norm(q_end[adr : adr + 3] - q_before[adr : adr + 3]))
    speed = float(np.linalg.norm(state_end[vs][dof : dof + 3]))
    touching = False
    for c in data.contact[: data.ncon]:
        bodies = [int(model.geom_bodyid[c.geom[0]]), int(model.geom_bodyid[c.geom[1]])]
        if pick in bodies and np.isin(bodies, robot.bodies).any():
            touching = True
    bottom = float(obj_box[2])
    details = {
        "lift_m": lifted,
        "bottom_above_top_m": bottom - top,
        "support_top_m": top,
        "inside_footprint": float(inside),
        "settle_motion_m": moved,
        "final_speed_m_s": speed,
        "base_penetration_m": base_penetration,
        "robot_penetration_m": arm_penetration,
    }
    if base_penetration > penetration_tol:
        return Outcome(False, BASE_COLLISION, details)
    if arm_penetration > penetration_tol:
        return Outcome(False, COLLISION, details)
    if lifted < 0.03:
        return Outcome(False, "slip", details)
    if not inside or not (-0.01 <= bottom - top <= above_tol):
        return Outcome(False, "not_on_target", details)
    if touching:
        return Outcome(False, "not_released", details)
    if moved > settle_tol or speed > speed_tol:
        return Outcome(False, "unstable", details)
    return Outcome(True, "", details)


def execute_mobile(
    setup: MobileSetup,
    plan: MobileEpisodePlan,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
    render_failures: bool = False,
) -> MobileRecording:
    """Simulates a planned episode on the CPU, checks success, and renders it.

    The images are drawn after the success check, from the recorded states, and only for a
    successful episode unless ``render_failures``: a failed episode costs its physics only
    (rendering five cameras is most of an episode's time on a CPU).

    Args:
        setup: the composed scene.
        plan: the planned episode.
        cfg: what to record.
        renderer: a renderer to reuse.
        render_failures: draw the images of a failed episode too.

    Returns:
        the recording with its ``outcome``; ``rgb``/``depth`` are empty for a failed episode
        (unless ``render_failures``) or when ``cfg.render`` is off.
    """
    model = setup.model
    data = mujoco.MjData(model)
    data.qpos[:] = plan.qpos0
    data.ctrl[:] = plan.ctrl[0]
    mujoco.mj_forward(model, data)
    state0 = np.zeros(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, state0, STATE_SPEC)
    rec = simulate(
        setup,
        state0,
        plan.ctrl,
        cfg,
        renderer,
        targets=plan.targets,
        subtask=plan.subtask,
        images=False,
    )
    rec.outcome = check_mobile_success(setup, rec, plan, cfg.fps)
    if cfg.render and (rec.outcome.success or render_failures):
        render_frames(setup, rec, cfg, renderer)
    return rec


def replay(
    setup: MobileSetup,
    rec: MobileRecording,
    cfg: MobileRecordConfig,
    renderer: MobileRenderer | None = None,
) -> MobileRecording:
    """Re-simulates a recording from its first state with its recorded controls (same frames,
    same images on the same machine)."""
    return simulate(setup, rec.state[0], rec.ctrl, cfg, renderer)
