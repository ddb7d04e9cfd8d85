"""Executing one planned ``place_inside`` episode through the position controller, with
recording, and its success check.

As the articulated tasks' (:mod:`factory.tasks.articulated.execute`): the plan's controls are
applied physics step by physics step on one ``MjData``; every frame records the integration
state, the robot's signals, the action and ``env_state`` (:data:`ENV_STATE_DIM`: the part's
joint position and share of range, the object's position and quaternion), and the cameras when
images are drawn. Nothing is teleported: the drawer moves because the fingers pull and push
its handle, the object because the fingers hold it or the drawer carries it.

Success (:func:`check_outcome`): at the end the object lies in the interior volume behind the
part (its origin, which is its bottom's centre, inside the volume's rectangle in the link's
frame and within :data:`FLOOR_TOL` of its floor), the part is closed (at most
:data:`~factory.tasks.articulated.plan.CLOSED_AT` of its range), the hand is open and away from
the handle, and no robot contact with the scene other than the container and the object went
deeper than :data:`~factory.tasks.articulated.execute.COLLISION_DEPTH`. Failure reasons, the
first that applies: ``collision``; the object not inside: ``slip`` (it was not lifted off the
top: less than :data:`LIFTED` above its start at the end of the lift), ``dropped`` (it was
farther than :data:`DROPPED` from its planned place pose when the hand opened), else
``not_inside``; ``not_closed``; ``not_released``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np

from factory.demos.record.payload import STATE_SPEC
from factory.tasks.articulated.execute import COLLISION_DEPTH, OPEN_HAND, RELEASED, allowed_geoms
from factory.tasks.articulated.execute import grasp_distance as handle_distance
from factory.tasks.articulated.plan import CLOSED_AT
from factory.tasks.articulated.record import (
    ArticulatedRenderer,
    RecordConfig,
    Recording,
    robot_penetration,
)
from factory.tasks.articulated.record import robot_signals as _signals
from factory.tasks.pick_place.objects import Outcome
from factory.tasks.place_inside.plan import PlaceInsidePlan, PlaceInsideSetup

__all__ = [
    "DROPPED",
    "ENV_STATE_DIM",
    "FLOOR_TOL",
    "LIFTED",
    "Watch",
    "check_outcome",
    "env_state",
    "execute_episode",
    "inside",
]

ENV_STATE_DIM = 9
"""``env_state``: the part's joint position (rad or m), its share of the range, the object's
position (3, m) and quaternion (4, wxyz), world frame."""
LIFTED = 0.03
"""The object at least this far (m) above its start at the end of the lift, else ``slip``."""
DROPPED = 0.05
"""The object farther than this (m) from its planned place pose when the hand opens:
``dropped``."""
FLOOR_TOL = 0.03
"""The object's origin (its bottom) within this (m) of the interior's floor counts as lying on
it (below: fell through; above: resting on something else)."""


def env_state(setup: PlaceInsideSetup, data: mujoco.MjData) -> np.ndarray:
    """The part's joint position and share of range, the object's position and quaternion
    (9,), from ``data``'s qpos."""
    art = setup.art
    q = float(data.qpos[art.qadr])
    a = setup.pick_adr
    return np.concatenate([[q, art.fraction(q)], data.qpos[a : a + 7]])


def allowed(setup: PlaceInsideSetup) -> np.ndarray:
    """Geoms (ngeom,) a robot contact with is no collision: the container's and the object's."""
    out = allowed_geoms(setup.art)
    m = setup.model
    out |= m.geom_bodyid == setup.pick_body
    return out


def inside(setup: PlaceInsideSetup, data: mujoco.MjData) -> tuple[bool, np.ndarray]:
    """Whether the object lies in the interior volume behind the part (its origin inside the
    volume's rectangle, the link's frame, and within :data:`FLOOR_TOL` of its floor), and the
    origin in the link's frame (3,) (m); ``data`` with current kinematics."""
    art = setup.art
    b = art.body
    link = np.eye(4)
    link[:3, :3] = data.xmat[b].reshape(3, 3)
    link[:3, 3] = data.xpos[b]
    p = (np.linalg.inv(link) @ np.append(data.xpos[setup.pick_body], 1.0))[:3]
    lo, hi = setup.interior.lo, setup.interior.hi
    ok = bool(
        lo[0] <= p[0] <= hi[0]
        and lo[1] <= p[1] <= hi[1]
        and abs(p[2] - setup.interior.floor_z) <= FLOOR_TOL
    )
    return ok, p


@dataclass
class Watch:
    """What the success check needs besides the final state, gathered while the episode runs.

    Attributes:
        worst: deepest robot contact with the scene other than the container and object (m).
        lifted: the object's height above its start at the end of the lift (m).
        off_place: the object's distance from its planned place pose when the hand opens (m).
    """

    worst: float = 0.0
    lifted: float = 1.0
    off_place: float = 0.0


def check_outcome(
    setup: PlaceInsideSetup, data: mujoco.MjData, watch: Watch, grasp: np.ndarray
) -> Outcome:
    """The success check at the state in ``data`` (current kinematics).

    Args:
        setup: the scene.
        data: the final state.
        watch: what was seen during the episode.
        grasp: the closing handle grasp (4, 4), the link's frame.
    """
    art = setup.art
    q = float(data.qpos[art.qadr])
    ok, p = inside(setup, data)
    fingers = data.qpos[art.robot.finger_qpos]
    released = handle_distance(art, data, grasp)
    details = {
        "joint": q,
        "fraction": float(art.fraction(q)),
        "range": float(art.hi),
        "object_x": float(p[0]),
        "object_y": float(p[1]),
        "object_z": float(p[2]),
        "worst_penetration": float(watch.worst),
        "lifted": float(watch.lifted),
        "off_place": float(watch.off_place),
        "released": float(released),
    }
    if watch.worst > COLLISION_DEPTH:
        return Outcome(False, "collision", details)
    closed = art.fraction(q) <= CLOSED_AT
    let_go = released >= RELEASED and float(fingers[0] - fingers[1]) >= OPEN_HAND
    if ok and closed and let_go:
        return Outcome(True, "", details)
    if not ok:
        if watch.lifted < LIFTED:
            return Outcome(False, "slip", details)
        if watch.off_place > DROPPED:
            return Outcome(False, "dropped", details)
        return Outcome(False, "not_inside", details)
    if not closed:
        return Outcome(False, "not_closed", details)
    return Outcome(False, "not_released", details)


def execute_episode(
    setup: PlaceInsideSetup,
    plan: PlaceInsidePlan,
    cfg: RecordConfig,
    renderer: ArticulatedRenderer | None = None,
) -> Recording:
    """Runs one planned episode and records it (images when ``cfg.render`` and a renderer is
    given, or one is made).

    Returns:
        the recording (``env_state`` (F, 9)), with its outcome (:func:`check_outcome`),
        simulation and rendering seconds.
    """
    m, robot = setup.model, setup.art.robot
    data = mujoco.MjData(m)
    data.qpos[:] = plan.qpos0
    data.ctrl[:] = plan.ctrl[0]
    mujoco.mj_forward(m, data)
    dt = float(m.opt.timestep)
    per_frame = max(1, round(1.0 / (cfg.fps * dt)))
    steps = len(plan.ctrl)
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
        env_state=np.zeros((n_frames, ENV_STATE_DIM)),
        rgb={c: np.zeros((n_frames, cfg.height, cfg.width, 3), np.uint8) for c in cfg.cameras}
        if own is not None
        else {},
        depth={c: np.zeros((n_frames, cfg.height, cfg.width), depth_type) for c in cfg.cameras}
        if own is not None
        else {},
    )
    robot_geom = np.zeros(m.ngeom, bool)
    robot_geom[robot.geoms] = True
    ok_geoms = allowed(setup)
    watch = Watch()
    z0 = float(plan.qpos0[setup.pick_adr + 2])
    lift_end = plan.phases.get("transport", steps)
    release = plan.phases.get("place_release", steps)
    sim_s = render_s = 0.0
    state = np.zeros(nstate)

    def record(frame: int) -> float:
        t0 = time.perf_counter()
        mujoco.mj_getState(m, data, state, STATE_SPEC)
        rec.state[frame] = state
        q, width, ee = _signals(m, data, robot)
        rec.joint_pos[frame] = q
        rec.gripper[frame, 0] = width
        rec.ee_pose[frame] = ee
        rec.env_state[frame] = env_state(setup, data)
        step = min((frame + 1) * per_frame, steps) - 1
        rec.action[frame] = plan.targets[step]
        watch.worst = max(watch.worst, robot_penetration(m, data, robot_geom, ok_geoms))
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
                data.ctrl[:] = plan.ctrl[min(k, steps - 1)]
                mujoco.mj_step(m, data)
                if k == lift_end - 1:
                    watch.lifted = float(data.qpos[setup.pick_adr + 2]) - z0
                if k == release - 1:
                    want = plan.pose_obj_place[:3, 3]
                    a = setup.pick_adr
                    watch.off_place = float(np.linalg.norm(data.qpos[a : a + 3] - want))
            mujoco.mj_forward(m, data)
            sim_s += time.perf_counter() - t0
            render_s += record(f + 1)
    finally:
        if renderer is None and own is not None:
            own.close()
    rec.outcome = check_outcome(setup, data, watch, plan.pose_tool_in_link_close)
    rec.sim_seconds = sim_s
    rec.render_seconds = render_s
    return rec
