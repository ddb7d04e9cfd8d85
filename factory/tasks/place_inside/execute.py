"""Executing one planned ``place_inside`` episode through the position controller, with
recording, and its success check.

As the articulated tasks' (:mod:`factory.tasks.articulated.execute`): the plan's controls are
applied physics step by physics step on one ``MjData``; every frame records the integration
state, the robot's signals, the action and ``env_state`` (:data:`ENV_STATE_DIM`: the part's
joint position and share of range, the object's position and quaternion), and the cameras when
images are drawn. Nothing is teleported: the drawer moves because the fingers pull and push
its handle, the object because the fingers hold it or the drawer carries it.

Success (:func:`check_outcome`): at the end the object lies in the interior volume behind the
part (its origin, which is its bottom's centre, inside the volume's rectangle in the frame of
the body holding it, the drawer's link or, behind a door, the container's case, and within
:data:`FLOOR_TOL` of its floor or shelf), the part is closed (at most
:data:`~factory.tasks.articulated.plan.CLOSED_AT` of its range), the hand is open and away from
the handle, and no robot contact with the scene other than the container and the object went
deeper than :data:`~factory.tasks.articulated.execute.COLLISION_DEPTH`. Failure reasons, the
first that applies: ``collision``; the object not inside: ``slip`` (it was not lifted off the
top: less than :data:`LIFTED` above its start at the end of the lift), ``dropped`` (it was
farther than :data:`DROPPED` from its planned place pose when the hand opened), else
``not_inside``; ``not_closed``; ``not_released``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from factory.tasks.articulated.execute import (
    COLLISION_DEPTH,
    OPEN_HAND,
    RELEASED,
    allowed_geoms,
    record_plan,
)
from factory.tasks.articulated.execute import grasp_distance as handle_distance
from factory.tasks.articulated.plan import CLOSED_AT
from factory.tasks.articulated.record import (
    ArticulatedRenderer,
    RecordConfig,
    Recording,
)
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
    "tilt",
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
    volume's rectangle and within :data:`FLOOR_TOL` of its support, in the frame of
    :attr:`~factory.tasks.place_inside.plan.PlaceInsideSetup.interior_body`: the drawer's link,
    or the case behind a door), and the origin in that frame (3,) (m); ``data`` with current
    kinematics."""
    b = setup.interior_body
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


def tilt(setup: PlaceInsideSetup, data: mujoco.MjData) -> float:
    """The object's tilt (deg): the angle between its up axis and the world's (0 upright, 90
    lying on its side; reported, not judged: an object on its side inside still counts)."""
    up = float(data.xmat[setup.pick_body].reshape(3, 3)[2, 2])
    return float(np.degrees(np.arccos(np.clip(up, -1.0, 1.0))))


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
        "tilt": tilt(setup, data),
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
    given, or one is made; :func:`factory.tasks.articulated.execute.record_plan`).

    Returns:
        the recording (``env_state`` (F, 9)), with its outcome (:func:`check_outcome`),
        simulation and rendering seconds.
    """
    watch = Watch()
    a = setup.pick_adr
    z0 = float(plan.qpos0[a + 2])
    steps = len(plan.ctrl)
    lift_end = plan.phases.get("transport", steps)
    release = plan.phases.get("place_release", steps)

    def on_step(k: int, data: mujoco.MjData) -> None:
        if k == lift_end - 1:
            watch.lifted = float(data.qpos[a + 2]) - z0
        if k == release - 1:
            want = plan.pose_obj_place[:3, 3]
            watch.off_place = float(np.linalg.norm(data.qpos[a : a + 3] - want))

    rec, data, watch.worst = record_plan(
        setup.model,
        setup.art.robot,
        plan.qpos0,
        plan.ctrl,
        plan.targets,
        cfg,
        renderer,
        lambda d: env_state(setup, d),
        ENV_STATE_DIM,
        allowed(setup),
        on_step,
    )
    rec.outcome = check_outcome(setup, data, watch, plan.pose_tool_in_link_close)
    return rec
