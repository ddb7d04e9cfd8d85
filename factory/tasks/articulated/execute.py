"""Executing one planned open or close episode through the position controller, with recording,
and its success check.

The episode runs on one ``MjData`` (``demo_execution = "episode"``): the plan's per-step
controls are applied physics step by physics step (``mj_step``); at every frame the MuJoCo
integration state (exact replay), the robot's signals
(:func:`~factory.tasks.articulated.record.robot_signals`), the action (the plan's targets at
the end of the frame), the part's joint and its handle as seen from the robot (``env_state``)
and, when images are drawn, the recording cameras
(:class:`~factory.tasks.articulated.record.ArticulatedRenderer`) are recorded. Nothing is
teleported: the part moves only because the fingers pull or push its handle.

Success (:func:`check_outcome`): at the end, ``open`` has the joint at
:data:`~factory.tasks.articulated.plan.OPEN_AT` of its span or more (a slide's range, a
hinge's up to 90 deg), ``close`` at :data:`~factory.tasks.articulated.plan.CLOSED_AT` of its
range or less, the hand has let go (open, at least :data:`RELEASED` from the handle) and no
robot contact with the scene other than the articulated object went deeper than
:data:`COLLISION_DEPTH`. Failure reasons: ``collision``, ``not_released``, ``slip`` (the part
fell short and the hand lost the handle during the motion: more than :data:`SLIP` from it at
the motion's end), ``not_open`` / ``not_closed`` (fell short otherwise).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from factory.demos.record.payload import STATE_SPEC
from factory.robots.panda import rot_z
from factory.tasks.articulated.plan import (
    CLOSED_AT,
    OPEN_AT,
    ArticulatedPlan,
    ArticulatedSetup,
)
from factory.tasks.articulated.record import (
    ArticulatedRenderer,
    RecordConfig,
    Recording,
    robot_penetration,
)
from factory.tasks.articulated.record import robot_signals as _signals
from factory.tasks.pick_place.objects import Outcome

__all__ = [
    "COLLISION_DEPTH",
    "ENV_STATE_DIM",
    "RELEASED",
    "SLIP",
    "Watch",
    "check_outcome",
    "env_state",
    "execute_episode",
    "record_plan",
]

ENV_STATE_DIM = 11
"""``env_state``: the part's joint position (rad or m) and its share of the range (0 closed),
the handle's centre and outward normal and the handle's offset from the tool, in the robot's
base frame (:func:`env_state`)."""
COLLISION_DEPTH = 0.02
"""A robot contact with the scene (other than the part) deeper than this (m) fails the episode."""
SLIP = 0.03
"""The tool site farther than this (m) from its grasp on the handle at the end of the motion:
the hand lost the handle."""
RELEASED = 0.04
"""At the end the tool site must be this far (m) from its grasp on the handle, the hand open
(the retreat backs off 5-10 cm)."""
OPEN_HAND = 0.03
"""A gripper opening (m) from which the hand counts as open."""


def env_state(setup: ArticulatedSetup, data: mujoco.MjData) -> np.ndarray:
    """What a policy needs to know of the part, (11,): its joint position (rad or m, 0 closed)
    and share of the range, then, in the robot's base frame, the handle's centre (m), its
    outward normal (unit) and the handle's centre minus the tool site (m). ``data`` with
    current kinematics (the link's ``xpos``/``xmat``, the tool site's ``site_xpos``).

    The joint alone tells a policy how far the part has moved, not where its handle is: in a
    new kitchen the handle stands elsewhere relative to the robot."""
    q = float(data.qpos[setup.qadr])
    center, _, normal = setup.part.handle_in_link()
    rot = data.xmat[setup.body].reshape(3, 3)
    place = setup.placement
    handle = place.to_base(data.xpos[setup.body] + rot @ center)
    facing = (rot @ normal) @ rot_z(place.yaw)
    tool = place.to_base(data.site_xpos[setup.robot.site])
    return np.concatenate([[q, setup.fraction(q)], handle, facing, handle - tool])


def grasp_distance(setup: ArticulatedSetup, data: mujoco.MjData, grasp: np.ndarray) -> float:
    """Distance (m) between the tool site and where the grasp holds the handle (``data`` with
    current kinematics; ``grasp``: the tool pose in the link frame)."""
    b = setup.body
    link = np.eye(4)
    link[:3, :3] = data.xmat[b].reshape(3, 3)
    link[:3, 3] = data.xpos[b]
    want = (link @ grasp)[:3, 3]
    return float(np.linalg.norm(data.site_xpos[setup.robot.site] - want))


@dataclass
class Watch:
    """What the success check needs besides the final state, gathered while the episode runs.

    Attributes:
        worst: deepest robot contact with the scene other than the part (m).
        slip: tool-to-grasp distance at the end of the constrained motion (m).
    """

    worst: float = 0.0
    slip: float = 0.0


def allowed_geoms(setup: ArticulatedSetup) -> np.ndarray:
    """Geoms (ngeom,) a robot contact with is no collision: the articulated object's (its body
    and links: the fingers hold its handle, the hand may brush its front)."""
    m = setup.model
    root = m.body(setup.part.obj.id).id
    bodies = [b for b in range(m.nbody) if b == root or _below(m, b, root)]
    return np.isin(m.geom_bodyid, bodies)


def _below(m: mujoco.MjModel, b: int, root: int) -> bool:
    while b > 0:
        b = int(m.body_parentid[b])
        if b == root:
            return True
    return False


def check_outcome(
    setup: ArticulatedSetup, q_end: float, watch: Watch, released: float, opening: float
) -> Outcome:
    """The success check of an episode.

    Args:
        setup: the scene.
        q_end: the part's joint position at the end (rad or m).
        watch: what was seen during the episode.
        released: tool-to-grasp distance at the end (m).
        opening: the gripper's opening at the end (m).
    """
    frac = setup.fraction(q_end)
    details = {
        "joint": float(q_end),
        "fraction": float(frac),
        "opened": setup.opened(q_end),
        "range": float(setup.hi),
        "span": float(setup.span),
        "worst_penetration": float(watch.worst),
        "slip": float(watch.slip),
        "released": float(released),
    }
    if watch.worst > COLLISION_DEPTH:
        return Outcome(False, "collision", details)
    done = setup.opened(q_end) >= OPEN_AT if setup.direction == "open" else frac <= CLOSED_AT
    if not done:
        if watch.slip > SLIP:
            return Outcome(False, "slip", details)
        return Outcome(False, "not_open" if setup.direction == "open" else "not_closed", details)
    if released < RELEASED or opening < OPEN_HAND:
        return Outcome(False, "not_released", details)
    return Outcome(True, "", details)


def record_plan(
    m: mujoco.MjModel,
    robot: Any,
    qpos0: np.ndarray,
    ctrl: np.ndarray,
    targets: np.ndarray,
    cfg: RecordConfig,
    renderer: ArticulatedRenderer | None,
    observe: Callable[[mujoco.MjData], np.ndarray],
    env_dim: int,
    allowed: np.ndarray,
    on_step: Callable[[int, mujoco.MjData], None],
) -> tuple[Recording, mujoco.MjData, float]:
    """Runs a plan's open-loop controls on one ``MjData`` physics step by physics step and
    records every frame (the articulated tasks' and ``task=place_inside``'s episodes).

    Args:
        qpos0: the start (nq,); ctrl: controls per physics step (T, nu); targets: the arm's
            joint targets and gripper command per physics step (T, 8), recorded as the action.
        renderer: draws the cameras (None: one is made when ``cfg.render``).
        observe: ``env_state`` of the frame, (env_dim,).
        allowed: geoms (ngeom,) the robot may touch without it counting as penetration.
        on_step: called after each physics step ``k`` (phase checks).

    Returns:
        the recording (its outcome unset; simulation and rendering seconds set), the final
        ``MjData`` and the deepest robot penetration (m) over the frames.
    """
    data = mujoco.MjData(m)
    data.qpos[:] = qpos0
    data.ctrl[:] = ctrl[0]
    mujoco.mj_forward(m, data)
    dt = float(m.opt.timestep)
    per_frame = max(1, round(1.0 / (cfg.fps * dt)))
    steps = len(ctrl)
    n_frames = int(np.ceil(steps / per_frame)) + 1
    nstate = mujoco.mj_stateSize(m, STATE_SPEC)
    depth_type = np.uint16 if cfg.depth == "uint16_mm" else np.float32
    own = renderer
    if own is None and cfg.render:
        own = ArticulatedRenderer(m, cfg)
    rec = Recording(
        time=np.arange(n_frames) / cfg.fps,
        state=np.zeros((n_frames, nstate)),
        joint_pos=np.zeros((n_frames, 7)),
        gripper=np.zeros((n_frames, 1)),
        ee_pose=np.zeros((n_frames, 7)),
        action=np.zeros((n_frames, 8)),
        env_state=np.zeros((n_frames, env_dim)),
        rgb={c: np.zeros((n_frames, cfg.height, cfg.width, 3), np.uint8) for c in cfg.cameras}
        if own is not None
        else {},
        depth={c: np.zeros((n_frames, cfg.height, cfg.width), depth_type) for c in cfg.cameras}
        if own is not None
        else {},
    )
    robot_geom = np.zeros(m.ngeom, bool)
    robot_geom[robot.geoms] = True
    worst = 0.0
    sim_s = render_s = 0.0
    state = np.zeros(nstate)

    def record(frame: int) -> float:
        nonlocal worst
        t0 = time.perf_counter()
        mujoco.mj_getState(m, data, state, STATE_SPEC)
        rec.state[frame] = state
        q, width, ee = _signals(m, data, robot)
        rec.joint_pos[frame] = q
        rec.gripper[frame, 0] = width
        rec.ee_pose[frame] = ee
        rec.env_state[frame] = observe(data)
        step = min((frame + 1) * per_frame, steps) - 1
        rec.action[frame] = targets[step]
        worst = max(worst, robot_penetration(m, data, robot_geom, allowed))
        if own is not None:
            rgbs, depths = own.render(data)
            for c, im, dp in zip(cfg.cameras, rgbs, depths, strict=True):
                rec.rgb[c][frame] = im
                rec.depth[c][frame] = dp
        return time.perf_counter() - t0

    try:
        render_s += record(0)
        for f in range(n_frames - 1):
            t0 = time.perf_counter()
            for k in range(f * per_frame, (f + 1) * per_frame):
                data.ctrl[:] = ctrl[min(k, steps - 1)]
                mujoco.mj_step(m, data)
                on_step(k, data)
            mujoco.mj_forward(m, data)
            sim_s += time.perf_counter() - t0
            render_s += record(f + 1)
    finally:
        if renderer is None and own is not None:
            own.close()
    rec.sim_seconds = sim_s
    rec.render_seconds = render_s
    return rec, data, worst


def execute_episode(
    setup: ArticulatedSetup,
    plan: ArticulatedPlan,
    cfg: RecordConfig,
    renderer: ArticulatedRenderer | None = None,
) -> Recording:
    """Runs one planned episode and records it (images when ``cfg.render`` and a renderer is
    given, or one is made; :func:`record_plan`).

    Returns:
        the recording (``env_state`` (F, 11): :func:`env_state` per frame), with its
        outcome (:func:`check_outcome`), simulation and rendering seconds.
    """
    watch = Watch()
    pull_end = plan.phases.get("release", len(plan.ctrl))

    def on_step(k: int, data: mujoco.MjData) -> None:
        if k == pull_end - 1:
            mujoco.mj_kinematics(setup.model, data)
            watch.slip = grasp_distance(setup, data, plan.pose_tool_in_link)

    rec, data, watch.worst = record_plan(
        setup.model,
        setup.robot,
        plan.qpos0,
        plan.ctrl,
        plan.targets,
        cfg,
        renderer,
        lambda d: env_state(setup, d),
        ENV_STATE_DIM,
        allowed_geoms(setup),
        on_step,
    )
    released = grasp_distance(setup, data, plan.pose_tool_in_link)
    rec.outcome = check_outcome(
        setup, float(data.qpos[setup.qadr]), watch, released, float(rec.gripper[-1, 0])
    )
    return rec
