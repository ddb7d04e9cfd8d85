"""Planning one "put the mug in the drawer" or "put the mug in the microwave" demonstration:
open the part, pick the object, place it on the interior support behind the part, release,
retreat, close the part.

Per scene, :func:`setup_scene` chooses the container part (a drawer whose link carries an
interior support and volume, or a door with a level of the fixed case behind it, big enough
for the object; empty ones first, then one with something stored there, which is taken out),
the pick object (:mod:`~factory.tasks.place_inside.containers`) and, through the articulated
tasks' set-up (:func:`factory.tasks.articulated.plan.setup_scene` for that part, direction
``open``; a door opened to :data:`DOOR_OPEN` only, and the spot must let the arm push it
back: ``round_trip``), the robot's base spot in front of the part. The pick object stands on
the container's top (the counter above the drawer, a nightstand's, a microwave's or a fridge's
top): it is moved there, and what else stands on that top is taken out of the scene
(``cleared``).

Per episode (:meth:`PlaceInsidePlanner.plan_episode`):

1. the object's pose on the top is drawn (:meth:`PlaceInsidePlanner.object_pose`) and written
   into the model's ``qpos0`` (so that the articulated planner sees it);
2. ``open``: the articulated planner's episode (reach, handle grasp, constrained pull, release,
   retreat: :meth:`~factory.tasks.articulated.plan.ArticulatedPlanner.plan_episode`);
3. pick and place with the pick-and-place machinery: antipodal grasps
   (:class:`~factory.demos.plan.grasps.GraspPool`), IK (mink), RRTConnect (OMPL) for the
   reach and the transport (the object attached), the object set upright on the drawer's
   floor in the part of the drawer that stands out of the cabinet, lowered from above,
   released, the hand raised; behind a door, set on the level's support
   :data:`DOOR_DEPTH` behind its front, slid in level from in front of the opening
   (:data:`DOOR_OUT`), released, the hand backed off along its approach
   (:data:`DOOR_RETREAT`); the grasps that approach it level are tried first;
4. ``close``: the handle grasp and the constrained push back to 0
   (:func:`~factory.tasks.articulated.plan.grasp_and_follow`, the object carried by a drawer
   ignored by the checker like the drawer itself; behind a door it stands still and counts as
   an obstacle), reached by RRTConnect, then release and retreat.

Every free motion is timed with ruckig segment by segment; the constrained motions as one
ruckig profile of the path parameter (:func:`~factory.tasks.articulated.plan.time_along`).
"""

from __future__ import annotations

import itertools
import logging
import math
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from factory.demos.plan.grasps import (
    Grasp,
    GraspConfig,
    GraspPool,
    GripperShape,
    collision_pieces,
    facing_order,
    gripper_clear,
)
from factory.demos.plan.planner import Attachment, CollisionChecker, PlannerConfig, plan
from factory.demos.plan.timing import Limits, time_path
from factory.errors import TaskError
from factory.robots.panda import (
    GRIP_CLOSED,
    GRIP_OPEN,
    RobotIndex,
    RobotPlacement,
    pose_matrix,
    rot_z,
    yaw_quat,
)
from factory.schema import Scene, SceneObject
from factory.tasks.articulated.plan import (
    GRASP_SEEDS,
    OPEN_GOAL,
    READY_QPOS,
    ArticulatedMotion,
    ArticulatedPlan,
    ArticulatedPlanner,
    ArticulatedSetup,
    HandleMotion,
    PlanFailure,
    SetupHint,
    grasp_and_follow,
    grasps_in_link,
    initial_state,
    time_along,
)
from factory.tasks.pick_place.plan import targets_to_ctrl
from factory.tasks.place_inside.containers import (
    MARGIN,
    Container,
    Interior,
    container_parts,
    container_top,
    on_top,
    pick_object,
    without,
)

__all__ = ["PlaceInsidePlan", "PlaceInsidePlanner", "PlaceInsideSetup", "setup_scene"]

log = logging.getLogger(__name__)

MAX_CONTAINERS = 4
"""Container parts :func:`setup_scene` tries before it gives up on a scene."""
TOP_FRONT = 0.10
"""The object stands at least this far (m) behind the container top's front edge (the hand
holding the drawer's handle below works there)."""
REACH = (0.30, 0.72)
"""Horizontal distances (m) from the base at which the object may stand on the top."""
LIFT = 0.12
"""Lift after the grasp and height of the pre-place pose above the place pose (m)."""
PLACE_DROP = 0.01
"""The object is released this far above the drawer's floor (m)."""
MAX_GRASPS = 8
"""Object grasps tried per episode."""
DOOR_OPEN = (0.78, 0.82)
"""Shares of the span (of 90 deg: 70-74 deg) a door is opened to: the arm pushes a door back
shut from its handle up to about 72 deg (wider, the handle faces sideways: docs/
ARTICULATED_TASKS.md), and the opening is clear for the hand at that angle."""
DOOR_DEPTH = 0.03
"""Behind a door, the object is set this far (m) plus its radius and :data:`MARGIN` behind
the level's front edge (near the opening: the arm reaches in less)."""
DOOR_OUT = 0.08
"""The object is slid in level from this far (m) in front of the level's front edge (its
near side), 1 cm above its place pose."""
DOOR_RETREAT = 0.08
"""Behind a door, the open hand backs off this far (m) along its approach after the release."""
DOOR_PLACE_RESTARTS = 12
"""Behind a door, random IK starts tried for the place pose after the seeds (the default
solve's 6: :class:`~factory.robots.ik.IKConfig`)."""
DOOR_PLACE_BRANCHES = 3
"""Behind a door, collision-free arm configurations at the place pose from which the straight
slide out of the opening is tried (the first alone: its elbow often meets the open door on the
way out)."""
DOOR_GRASPS = GraspConfig(approaches=12, max_tilt_deg=91.0)
"""Object grasps behind a door: approaches every 30 deg about the closing axis, up to level,
the most level first: the forearm must pass under the top of the opening (a microwave's cavity
is 0.28 m high), which the pick-and-place default's tilts (up to 45 deg from straight down
here) run into."""
DOOR_TOP_FRONT = (0.01, 0.06)
"""Behind a door, the object starts this far (m) plus its radius behind the door's hinge line
(the door's top edge is part of the top's front: an object standing on it fell when the door
swung), near the front so that the forearm of a hand held level or tilted 30 deg stays clear
of the top."""
LINE_STEP = 0.03
"""Waypoint spacing (m) of the straight tool motion that slides the object in behind a door."""
GRASP_CHECK_SEEDS = 3
"""Starts of the object (seeds 0, 1, ...) at which :meth:`PlaceInsidePlanner.check_graspable`
looks for a grasp before the scene's episodes are planned."""


@dataclass
class PlaceInsideSetup:
    """A scene ready for planning.

    Attributes:
        art: the articulated set-up of the part (direction ``open``): the composed model, the
            robot's base spot, the part's joint.
        pick: the object put away (standing on the container's top in ``art.scene``).
        interior: the interior behind the part.
        top_z: the container top's height (m, world frame); top_rect: its rectangle
            ``[x0, y0, x1, y1]`` (m, the container's frame).
        pick_body, pick_adr: the object's body id and free-joint qpos address in the model.
        cleared: objects taken out of the scene (from the top, out of the part's way).
    """

    art: ArticulatedSetup
    pick: SceneObject
    interior: Interior
    top_z: float
    top_rect: np.ndarray
    pick_body: int
    pick_adr: int
    cleared: tuple[str, ...] = ()

    @property
    def behind_door(self) -> bool:
        """The interior is the fixed case behind a door (not carried by the part)."""
        return not self.interior.carried

    @property
    def interior_body(self) -> int:
        """The body whose frame holds :attr:`interior` (id in :attr:`model`): the drawer's link,
        or the container's root body behind a door."""
        if self.interior.carried:
            return self.art.body
        return int(self.model.body(self.container.id).id)

    @property
    def model(self) -> mujoco.MjModel:
        """The composed scene + robot."""
        return self.art.model

    @property
    def robot(self) -> RobotIndex:
        """The robot's index in :attr:`model`."""
        return self.art.robot

    @property
    def placement(self) -> RobotPlacement:
        """The robot's base pose (world frame)."""
        return self.art.placement

    @property
    def scene(self) -> Scene:
        """The scene as composed (the object on the top, ``cleared`` taken out)."""
        return self.art.scene

    @property
    def container(self) -> SceneObject:
        """The articulated object holding the part."""
        return self.art.part.obj

    def pose_container(self) -> np.ndarray:
        """The container's pose (4, 4), world frame."""
        c = self.container
        return pose_matrix(
            np.array([c.position.x, c.position.y, c.position.z]),
            rot_z(math.radians(c.rotation.z)),
        )

    def instruction(self) -> str:
        """The episode's instruction: the scene's when the scene was made for the task, else
        "put the <object> in <the part's label>" ("put the mug in the drawer of the base
        cabinet"), behind a door "put the <object> in the <container>" ("put the mug in the
        microwave oven"; "... behind the left door" where it has two)."""
        task = self.scene.task
        if task is not None and task.kind == "place_inside" and task.instruction:
            return str(task.instruction)
        what = self.pick.category.replace("_", " ")
        if not self.behind_door:
            return f"put the {what} in {self.art.part.label}"
        label = self.art.part.label
        where = self.container.category.replace("_", " ")
        side = label.split(" of the ")[0].removeprefix("the ")
        return f"put the {what} in the {where}" + (f" behind the {side}" if side != "door" else "")


class _CarriedSetup(ArticulatedSetup):
    """The articulated set-up whose moving link carries the placed object too: the collision
    checker ignores the object with the link while the part closes (it moves with it)."""

    carried: int = -1

    def link_bodies(self) -> np.ndarray:
        own = super().link_bodies()
        return np.append(own, self.carried) if self.carried >= 0 else own


def setup_scene(
    scene: Scene,
    assets_root: str | Path,
    freeze_beyond: float = 1.0,
    hint: dict[str, Any] | None = None,
) -> PlaceInsideSetup:
    """Chooses the container part, the pick object and the robot's base spot (module
    docstring), and composes the scene with the robot there.

    Args:
        hint: the choices of an earlier search with the same arguments (:func:`hint_of`):
            the same set-up, composed without searching.

    Raises:
        TaskError: no pick object, no container part (none with an interior, too small) or
            none the robot can open (and, behind a door, push back) from a free base spot;
            with the counts and, for the parts the instruction names, a reason each; a
            ``hint`` whose container the scene lacks.
    """
    pick = pick_object(scene)
    why: Counter[str] = Counter()
    refusals: list[str] = []
    parts = container_parts(scene, assets_root, pick, why, refusals)
    if hint is not None:
        match = [
            b
            for b in parts
            if b.part.key == hint["container"] and b.interior.support == hint["support"]
        ]
        art_hint = SetupHint.from_json(hint["articulated"])
        out = (
            _setup_container(scene, assets_root, pick, match[0], freeze_beyond, why, [], art_hint)
            if match
            else None
        )
        if out is None:
            raise TaskError(
                f"scene {scene.id!r}: its set-up record names container {hint['container']} "
                f"({hint['support']}), which the scene does not offer as recorded; delete the "
                "run's cache/setups folder and re-run"
            )
        return out
    for box in parts[:MAX_CONTAINERS]:
        out = _setup_container(scene, assets_root, pick, box, freeze_beyond, why, refusals)
        if out is not None:
            return out
    reasons = "; ".join(refusals)
    fix = ""
    if why["too_small"]:
        fix = "; ask for a smaller object or a larger container"
    elif why["unreachable"]:
        fix = "; ask for another container, or generate the scene again (another seed)"
    raise TaskError(
        f"scene {scene.id!r}: no container part for {pick.id!r} "
        f"({len(parts)} candidate(s); {dict(why) or 'no articulated part with an interior'})"
        + (f": {reasons}" if reasons else "")
        + fix
    )


def _setup_container(
    scene: Scene,
    assets_root: str | Path,
    pick: SceneObject,
    box: Container,
    freeze_beyond: float,
    why: Counter[str],
    refusals: list[str],
    hint: SetupHint | None = None,
) -> PlaceInsideSetup | None:
    """:func:`setup_scene` for one container: the set-up, or None (counted into ``why``, the
    reason added to ``refusals``); with ``hint``, the articulated set-up composed from it."""
    from factory.tasks.articulated.plan import setup_scene as setup_part

    part, inner = box.part, box.interior
    top = container_top(part.obj, assets_root)
    assert top is not None
    sc = on_top(without(scene, box.stored), part.obj, top[0], pick)
    cleared = sorted({o.id for o in scene.objects} - {o.id for o in sc.objects})
    sc = replace(
        sc,
        objects=[
            replace(o, task_joint=part.joint.name if o.id == part.obj.id else None)
            for o in sc.objects
        ],
    )
    door = box.behind_door
    try:
        art = setup_part(
            sc,
            assets_root,
            "open",
            freeze_beyond=freeze_beyond,
            open_to=DOOR_OPEN[1] if door else OPEN_GOAL[1],
            round_trip=door,
            spot_check=_InteriorReach(box, pick, top[1]) if door else None,
            hint=hint,
        )
    except TaskError as e:
        log.info("scene %s: %s: %s", scene.id, part.key, e)
        why["unreachable"] += 1
        counts = str(e).rpartition(" (")[2].rstrip(")")
        refusals.append(
            f"{part.key} ({part.label}): unreachable: no free base spot from which the "
            f"arm opens it{' and pushes it back' if door else ''} ({counts})"
        )
        return None
    if pick.id in art.frozen:
        why["object_out_of_reach"] += 1
        refusals.append(f"{part.key} ({part.label}): {pick.id!r} out of the arm's reach")
        return None
    m = art.model
    body = m.body(pick.id).id
    adr = int(m.jnt_qposadr[m.body_jntadr[body]])
    out = PlaceInsideSetup(
        art,
        pick,
        inner,
        part.obj.position.z + top[0],
        top[1],
        body,
        adr,
        tuple(sorted(set(cleared) | set(art.cleared))),
    )
    log.info(
        "scene %s: put %s in %s (%s, %s); cleared %s",
        scene.id,
        pick.id,
        part.key,
        part.label,
        inner.support,
        list(out.cleared),
    )
    return out


def hint_of(setup: PlaceInsideSetup) -> dict[str, Any]:
    """A set-up's choices (JSON values), for :func:`setup_scene`'s ``hint``: the container
    (part and interior support) and the articulated set-up's
    (:class:`~factory.tasks.articulated.plan.SetupHint`)."""
    return {
        "container": setup.art.part.key,
        "support": setup.interior.support,
        "articulated": SetupHint.of(setup.art).to_json(),
    }


REACH_TILTS = (60.0, 30.0)
"""Tilts (deg from straight down) of the hand :class:`_InteriorReach` tries at the place
point behind a door."""


class _InteriorReach:
    """The articulated set-up's ``spot_check`` behind a door: from the spot, the hand reaches
    the place point (:meth:`PlaceInsidePlanner.place_xy`, at 0.6 of the object's height above
    the level) collision-free with the door open to :data:`DOOR_OPEN`'s upper end, approaching
    into the case (+y of the container), along the reach from the base or between the two,
    tilted :data:`REACH_TILTS` from straight down, the closing axis level; and the middle of
    the band of the container's top where the object starts (:data:`DOOR_TOP_FRONT` behind the
    hinge line) lies within :data:`REACH` of the base (``top_out_of_reach``: a fridge's top,
    1.45 m high, from a spot that works its door). Refuses the spot with
    ``interior_out_of_reach`` (or ``top_out_of_reach``): the handle's path alone picks spots
    from which the case's inside is out of the hand's reach or behind the open door."""

    def __init__(self, box: Container, pick: SceneObject, top_rect: np.ndarray) -> None:
        from factory.robots.ik import IKSolver

        self.box = box
        self.pick = pick
        self.top_rect = top_rect
        self.ik = IKSolver()

    def __call__(self, art: ArticulatedSetup, checker: CollisionChecker) -> str:
        c = self.box.part.obj
        world = pose_matrix(
            np.array([c.position.x, c.position.y, c.position.z]),
            rot_z(math.radians(c.rotation.z)),
        )
        inner, d = self.box.interior, self.pick.dimensions
        r = 0.5 * math.hypot(d.width, d.length)
        joint = self.box.part.joint
        hinge = float(joint.anchor[1]) * self.box.part.scale[1]
        band = np.array(
            [
                0.5 * (self.top_rect[0] + self.top_rect[2]),
                hinge + r + 0.5 * sum(DOOR_TOP_FRONT),
                0.0,
                1.0,
            ]
        )
        start = (world @ band)[:2]
        if not REACH[0] <= float(np.linalg.norm(start - art.placement.pos()[:2])) <= REACH[1]:
            return "top_out_of_reach"
        u = 0.5 * (inner.lo[0] + inner.hi[0])
        v = min(inner.lo[1] + r + MARGIN + DOOR_DEPTH, 0.5 * (inner.lo[1] + inner.hi[1]))
        point = (world @ np.array([u, v, inner.floor_z + 0.6 * d.height, 1.0]))[:3]
        into = world[:3, 1]
        reach = point - art.placement.pos()
        reach[2] = 0.0
        reach /= max(float(np.linalg.norm(reach)), 1e-9)
        mid = into + reach
        aims = [into, reach, mid / max(float(np.linalg.norm(mid)), 1e-9)]
        checker.set_scene(initial_state(art, DOOR_OPEN[1] * art.span))
        checker.attach(None)
        checker.ignore_bodies([])
        base_inv = np.linalg.inv(art.placement.matrix())
        for aim, tilt in itertools.product(aims, REACH_TILTS):
            t = math.radians(tilt)
            z = math.sin(t) * aim - math.cos(t) * np.array([0.0, 0.0, 1.0])
            side = np.cross([0.0, 0.0, 1.0], aim)
            rot = np.stack([side, np.cross(z, side), z], axis=1)
            tool = pose_matrix(point, rot)
            seeds = [READY_QPOS, *GRASP_SEEDS]
            if self.ik.solve(base_inv @ tool, seeds, accept=checker.valid) is not None:
                return ""
        return "interior_out_of_reach"


@dataclass
class PlaceInsidePlan:
    """What execution needs for one episode (as
    :class:`~factory.tasks.articulated.plan.ArticulatedPlan`).

    Attributes:
        qpos0: initial state (nq,): the part closed, the object on the top, the arm at
            :data:`~factory.tasks.articulated.plan.READY_QPOS`.
        ctrl: actuator controls per physics step (T, nu).
        targets: desired arm joints (rad) and gripper command (m) per physics step (T, 8).
        phases: phase name -> first physics step (``open_*``, ``pick_*``, ``close_*``).
        grasp_width: the object grasp's span (m).
        plan_seconds: planning time per planned free motion (s).
        seconds: total planning time (s).
        attempts: object grasps tried.
        q_open: the part's joint after opening (rad or m, as planned).
        pose_obj_place: the object's planned pose on the drawer's floor (4, 4), world frame.
        pose_tool_in_link_open, pose_tool_in_link_close: the handle grasps (4, 4), link frame.
    """

    qpos0: np.ndarray
    ctrl: np.ndarray
    targets: np.ndarray
    phases: dict[str, int]
    grasp_width: float
    plan_seconds: dict[str, float]
    seconds: float
    attempts: int
    q_open: float = 0.0
    pose_obj_place: np.ndarray = field(default_factory=lambda: np.eye(4))
    pose_tool_in_link_open: np.ndarray = field(default_factory=lambda: np.eye(4))
    pose_tool_in_link_close: np.ndarray = field(default_factory=lambda: np.eye(4))


class _Timeline:
    """Arm targets, velocities and gripper commands per physics step, phase by phase."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.arm: list[np.ndarray] = []
        self.vel: list[np.ndarray] = []
        self.grip: list[float] = []
        self.phases: dict[str, int] = {}

    def hold(self, name: str, q: np.ndarray, secs: float, opening: float) -> None:
        self.phases[name] = len(self.arm)
        n = max(1, round(secs / self.dt))
        self.arm.extend([q] * n)
        self.vel.extend([np.zeros(7)] * n)
        self.grip.extend([opening] * n)

    def move(self, name: str, path: np.ndarray, limits: Limits, opening: float) -> None:
        self.phases[name] = len(self.arm)
        timed = time_path(path, limits, self.dt)
        self.arm.extend(list(timed.q[1:]))
        self.vel.extend(list(timed.qd[1:]))
        self.grip.extend([opening] * (len(timed.q) - 1))

    def along(self, name: str, path: np.ndarray, limits: Limits, opening: float) -> None:
        self.phases[name] = len(self.arm)
        q, qd = time_along(path, limits, self.dt)
        self.arm.extend(list(q[1:]))
        self.vel.extend(list(qd[1:]))
        self.grip.extend([opening] * (len(q) - 1))


class PlaceInsidePlanner:
    """Plans the episodes of one scene (deterministic per seed).

    Args:
        setup: the scene with the robot placed.
        motion: timing and geometry of the handle motions (the free motions use its speeds).
        planner_cfg: RRTConnect settings.
    """

    def __init__(
        self,
        setup: PlaceInsideSetup,
        motion: ArticulatedMotion | None = None,
        planner_cfg: PlannerConfig | None = None,
    ) -> None:
        self.setup = setup
        self.motion = motion or ArticulatedMotion()
        self.planner_cfg = planner_cfg or PlannerConfig()
        goal = DOOR_OPEN if setup.behind_door else OPEN_GOAL
        self.opener = ArticulatedPlanner(setup.art, self.motion, self.planner_cfg, goal)
        art = setup.art
        fields = {f: getattr(art, f) for f in art.__dataclass_fields__}
        self.closer = _CarriedSetup(**{**fields, "direction": "close"})
        if setup.interior.carried:  # a drawer carries the object; a door's case does not
            self.closer.carried = setup.pick_body
        m = setup.model
        self.model = m
        self.robot = art.robot
        self.ik = self.opener.ik
        self.checker = self.opener.checker
        self.kin = self.opener.kin
        self.dt = float(m.opt.timestep)
        self.grasp_cfg = DOOR_GRASPS if setup.behind_door else GraspConfig()
        self.shape = GripperShape.of(m, self.robot, GRIP_OPEN)
        self.pieces = collision_pieces(m, setup.pick_body)
        key = f"{setup.scene.id}/{setup.pick.id}".encode()
        self.pool = GraspPool(
            self.pieces, self.grasp_cfg, zlib.crc32(key), m.body_ipos[setup.pick_body]
        )
        self.home_pose = np.array(m.qpos0[setup.pick_adr : setup.pick_adr + 7])
        mo = self.motion
        self.fast = Limits.panda(mo.speed, mo.accel, mo.jerk)
        self.slow = Limits.panda(mo.speed * mo.slow, mo.accel * mo.slow, mo.jerk * mo.slow)
        self.pull = Limits.panda(mo.pull, mo.pull, mo.pull)

    # -- the object's start ------------------------------------------------------------------

    def object_pose(self, rng: np.random.Generator, tries: int = 200) -> np.ndarray:
        """The object's start pose on the container's top (7: position m, quaternion wxyz;
        world frame): a spot of the top :data:`MARGIN` inside its sides, :data:`TOP_FRONT`
        behind its front edge, :data:`REACH` from the base, turned at random.

        Raises:
            TaskError: no such spot on the top.
        """
        s = self.setup
        d = s.pick.dimensions
        r = 0.5 * math.hypot(d.width, d.length)
        x0, y0, x1, y1 = s.top_rect
        world = s.pose_container()
        base = s.art.placement.pos()[:2]
        front = (TOP_FRONT, y1 - y0 - 2 * r - MARGIN)
        if s.behind_door:  # behind the door's hinge line (the door's top edge moves)
            hinge = float(s.art.part.joint.anchor[1]) * float(s.art.part.scale[1]) - y0
            front = (hinge + DOOR_TOP_FRONT[0], hinge + DOOR_TOP_FRONT[1])
        for _ in range(tries):
            u = rng.uniform(x0 + r + MARGIN, x1 - r - MARGIN)
            v = rng.uniform(y0 + r + front[0], y0 + r + front[1])
            xy = (world @ np.array([u, v, 0.0, 1.0]))[:2]
            if REACH[0] <= float(np.linalg.norm(xy - base)) <= REACH[1]:
                break
        else:
            raise TaskError(
                f"no spot on the top of {s.container.id!r} within {REACH} m of the robot's base"
            )
        quat = np.zeros(4)
        mujoco.mju_mulQuat(
            quat, yaw_quat(float(rng.uniform(-math.pi, math.pi))), self.home_pose[3:]
        )
        return np.array([xy[0], xy[1], s.top_z, *quat])

    def check_graspable(self) -> None:
        """Refuses a scene whose object no open gripper can take from the container's top (a
        phone or a book lying flat: the fingers would go into the top), so that the run goes
        on with the next scene instead of failing every episode with ``no_grasp``. Looks at
        the object's starts of the first :data:`GRASP_CHECK_SEEDS` seeds, the part closed.

        Raises:
            TaskError: no collision-free grasp at any of them (names the object, its size
                and what to ask for instead).
        """
        from factory.scenes.task_words import STOW_OBJECTS

        for seed in range(GRASP_CHECK_SEEDS):
            try:
                qpos = self.initial_qpos(seed)
            except TaskError:
                continue
            if self._grasps(qpos, np.random.default_rng(seed)):
                return
        s = self.setup
        d = s.pick.dimensions
        choices = ", ".join(o.replace("_", " ") for o in STOW_OBJECTS)
        raise TaskError(
            f"scene {s.scene.id!r}: no collision-free grasp on {s.pick.id!r} "
            f"({d.width:.3f} x {d.length:.3f} x {d.height:.3f} m) standing on the top of "
            f"{s.container.id!r}: too flat or too wide for the open gripper to take from a "
            f"surface; ask for an object such as {choices}"
        )

    def initial_qpos(self, seed: int) -> np.ndarray:
        """The initial qpos (nq,) of seed ``seed`` (the demos' and the env's): the part closed,
        the arm at the start posture, the object at :meth:`object_pose` of the seed.

        Raises:
            TaskError: no spot for the object.
        """
        pose = self.object_pose(np.random.default_rng(seed))
        q = initial_state(self.setup.art, 0.0)
        q[self.setup.pick_adr : self.setup.pick_adr + 7] = pose
        return q

    def _set_object(self, pose: np.ndarray) -> None:
        """Writes the object's pose (7) into the model's ``qpos0``: the articulated planner's
        scenes (:func:`~factory.tasks.articulated.plan.initial_state`) start from it."""
        a = self.setup.pick_adr
        self.model.qpos0[a : a + 7] = pose

    # -- where the object goes ---------------------------------------------------------------

    def place_xy(self, q_open: float) -> np.ndarray:
        """Where the object is set (2,) (m, world frame): the middle of the drawer's floor
        standing out of the cabinet with the part at ``q_open``, :data:`MARGIN` plus the
        object's radius from its walls and from the cabinet's front; behind a door, the
        middle of the level's width, :data:`DOOR_DEPTH` plus :data:`MARGIN` plus the radius
        behind its front edge."""
        s = self.setup
        inner = s.interior
        if s.behind_door:
            d = s.pick.dimensions
            r = 0.5 * math.hypot(d.width, d.length)
            v = min(inner.lo[1] + r + MARGIN + DOOR_DEPTH, 0.5 * (inner.lo[1] + inner.hi[1]))
            u = 0.5 * (inner.lo[0] + inner.hi[0])
            return (s.pose_container() @ np.array([u, v, 0.0, 1.0]))[:2]
        axis = np.array(s.art.part.joint.axis, float)
        shift = axis * q_open  # the link's displacement, the container's frame
        lo, hi = inner.lo + shift, inner.hi + shift
        front = float(s.top_rect[1])  # the case's front (-y) in the container's frame
        d = s.pick.dimensions
        r = 0.5 * math.hypot(d.width, d.length)
        y_hi = min(hi[1], front) - r - MARGIN
        y_lo = lo[1] + r + MARGIN
        v = 0.5 * (y_lo + y_hi) if y_hi > y_lo else y_hi
        u = 0.5 * (lo[0] + hi[0])
        return (s.pose_container() @ np.array([u, v, 0.0, 1.0]))[:2]

    def floor_z(self, q_open: float) -> float:
        """The interior support's height (m, world frame) with the part at ``q_open`` (a
        drawer's floor moves with it; a door's level does not)."""
        s = self.setup
        if s.behind_door:
            return float(s.container.position.z + s.interior.floor_z)
        axis = np.array(s.art.part.joint.axis, float)
        return float(s.container.position.z + s.interior.floor_z + axis[2] * q_open)

    def insert_offset(self) -> np.ndarray:
        """Where the object's place pose is approached from, relative to it (3,) (m, world
        frame): :data:`LIFT` above for a drawer; behind a door, out of the opening along the
        container's front (-y) to :data:`DOOR_OUT` in front of the level's front edge, 1 cm
        up."""
        s = self.setup
        if not s.behind_door:
            return np.array([0.0, 0.0, LIFT])
        d = s.pick.dimensions
        r = 0.5 * math.hypot(d.width, d.length)
        front = s.pose_container()[:3, 1]  # the container's +y: into the case
        xy = self.place_xy(0.0)
        depth = float(np.dot(np.append(xy, 0.0) - s.pose_container()[:3, 3], front))
        out = depth - s.interior.lo[1] + r + DOOR_OUT
        return -front * out + np.array([0.0, 0.0, 0.01])

    def place_turns(self, grasp: np.ndarray, xy: np.ndarray) -> list[float]:
        """The turns (rad, about the world's z) of the object from its pick pose to its place
        pose, in the order tried: 0, then quarter and eighth turns; behind a door first the
        turns that point the hand's approach (the tool's +z at the grasp ``grasp`` (4, 4),
        world frame) into the case (the container's +y), along the reach from the robot's
        base to the place point ``xy`` (2,) (m, world frame) and between the two, so that the
        hand comes in through the opening."""
        out = [0.0, np.pi / 2, -np.pi / 2, np.pi, np.pi / 4, -np.pi / 4]
        s = self.setup
        a = grasp[:2, 2]
        if not s.behind_door or float(np.linalg.norm(a)) < 0.3:  # no level part to turn
            return out
        into = s.pose_container()[:2, 1]
        reach = xy - s.placement.pos()[:2]
        heading = math.atan2(a[1], a[0])
        aims = [math.atan2(into[1], into[0]), math.atan2(reach[1], reach[0])]
        aims.append(aims[0] + 0.5 * math.remainder(aims[1] - aims[0], 2 * math.pi))
        return [math.remainder(t - heading, 2 * math.pi) for t in aims] + out

    def retreat_pose(self, place: np.ndarray) -> np.ndarray:
        """The open hand's pose (4, 4) after it let go of the object at the tool pose
        ``place``: :data:`LIFT` above for a drawer; behind a door, :data:`DOOR_RETREAT` back
        along its approach axis."""
        up = place.copy()
        if self.setup.behind_door:
            up[:3, 3] -= place[:3, 2] * DOOR_RETREAT
        else:
            up[2, 3] += LIFT
        return up

    # -- planning ------------------------------------------------------------------------------

    def _grasps(self, qpos: np.ndarray, rng: np.random.Generator) -> list[Grasp]:
        m, s = self.model, self.setup
        data = mujoco.MjData(m)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        pose = pose_matrix(data.xpos[s.pick_body], data.xmat[s.pick_body])
        cands = self.pool.candidates(pose[:3, :3], rng)
        cands = facing_order(cands, pose, s.art.placement.pos()[:2], 1.0)
        if s.behind_door:
            com = pose[:3, :3] @ m.body_ipos[s.pick_body] + pose[:3, 3]
            cands.sort(key=lambda g: _door_rank(g, pose, com))
        back = np.eye(4)
        back[2, 3] = -self.grasp_cfg.pregrasp
        out = []
        for g in cands:
            tool = pose @ g.pose_tool_in_obj
            clear, bodies = self.grasp_cfg.clearance, self.robot.bodies
            free = gripper_clear(m, data, self.shape, tool, clear, bodies)
            if free and gripper_clear(m, data, self.shape, tool @ back, clear, bodies):
                out.append(g)
            if len(out) >= MAX_GRASPS:
                break
        return out

    def _ik(self, pose: np.ndarray, seeds: list[np.ndarray]) -> np.ndarray | None:
        base_inv = np.linalg.inv(self.setup.art.placement.matrix())
        return self.ik.solve(base_inv @ pose, seeds, accept=self.checker.valid)

    def _line(self, a: np.ndarray, b: np.ndarray, q_a: np.ndarray) -> np.ndarray | None:
        """Arm configurations (k, 7) moving the tool on the straight line from pose ``a`` (where
        the arm is ``q_a``) to pose ``b`` (4, 4, world frame; the orientation kept): a
        waypoint every :data:`LINE_STEP`, IK seeded by the previous one, each step
        collision-free and without a joint jump over
        :data:`~factory.tasks.articulated.plan.MAX_JUMP`; None when it breaks off. (Sliding
        the object in behind a door: the straight line in joint space between the ends
        leaves the line in space and runs into the opening's frame.)"""
        from factory.tasks.articulated.plan import MAX_JUMP

        n = max(1, math.ceil(float(np.linalg.norm(b[:3, 3] - a[:3, 3])) / LINE_STEP))
        out = [q_a]
        for k in range(1, n + 1):
            pose = a.copy()
            pose[:3, 3] = a[:3, 3] + (b[:3, 3] - a[:3, 3]) * k / n
            q = self._ik(pose, [out[-1]])
            if q is None or float(np.max(np.abs(q - out[-1]))) > MAX_JUMP:
                return None
            if not self.checker.segment_valid(out[-1], q):
                return None
            out.append(q)
        return np.array(out)

    def _approach(
        self, pre: np.ndarray, grasp: np.ndarray, seeds: list[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The arm at the pre-grasp ``pre`` and at the grasp ``grasp`` (tool poses (4, 4),
        world frame), the segment between them collision-free; None when not found. Behind a
        door up to :data:`DOOR_PLACE_BRANCHES` pre-grasp branches from
        :data:`DOOR_PLACE_RESTARTS` random starts more (the level approach to an object near
        the top's front, the open door beside it); for a drawer the first branch."""
        ck = self.checker
        if not self.setup.behind_door:
            q_pre = self._ik(pre, seeds)
            q_grasp = None if q_pre is None else self._ik(grasp, [q_pre])
            if q_pre is None or q_grasp is None or not ck.segment_valid(q_pre, q_grasp):
                return None
            return q_pre, q_grasp
        base_inv = np.linalg.inv(self.setup.art.placement.matrix())
        found = self.ik.solutions(base_inv @ pre, seeds, ck.valid, restarts=DOOR_PLACE_RESTARTS)
        for q_pre in itertools.islice(found, DOOR_PLACE_BRANCHES):
            q_grasp = self._ik(grasp, [q_pre])
            if q_grasp is not None and ck.segment_valid(q_pre, q_grasp):
                return q_pre, q_grasp
        return None

    def _slide_in(
        self, place: np.ndarray, preplace: np.ndarray, seeds: list[np.ndarray]
    ) -> np.ndarray | None:
        """Behind a door, the arm configurations (k, 7) sliding the held object in from tool
        pose ``preplace`` to ``place`` (4, 4, world frame) on the straight line
        (:meth:`_line`, planned from ``place`` outwards); up to :data:`DOOR_PLACE_BRANCHES`
        collision-free arm branches at ``place`` are tried, from ``seeds``, the ready and grasp
        seeds, the home pose and :data:`DOOR_PLACE_RESTARTS` random starts (the first branch
        IK finds inside the case often has its elbow against the open door or the opening's
        frame, or leaves the line on the way out); None when none slides out."""
        base_inv = np.linalg.inv(self.setup.art.placement.matrix())
        starts = [*seeds, READY_QPOS, *GRASP_SEEDS]
        found = self.ik.solutions(
            base_inv @ place, starts, self.checker.valid, restarts=DOOR_PLACE_RESTARTS
        )
        for q_place in itertools.islice(found, DOOR_PLACE_BRANCHES):
            way = self._line(place, preplace, q_place)
            if way is not None:
                return way[::-1]
        return None

    def _pick_place(
        self,
        g: Grasp,
        qpos: np.ndarray,
        q_from: np.ndarray,
        q_open: float,
        rng: np.random.Generator,
        counts: Counter[str],
        seconds: dict[str, float],
    ) -> tuple[list[tuple[str, np.ndarray, str]], np.ndarray, np.ndarray] | None:
        """The pick-and-place motions of one grasp: [(phase, joint path, kind)], the place
        pose of the object (4, 4), the arm after the retreat (7,); None (counted) when they
        do not plan."""
        s, ck = self.setup, self.checker
        a = s.pick_adr
        obj = pose_matrix(qpos[a : a + 3], _quat_mat(qpos[a + 3 : a + 7]))
        grasp = obj @ g.pose_tool_in_obj
        pre = grasp.copy()
        pre[:3, 3] -= grasp[:3, 2] * self.grasp_cfg.pregrasp
        lift = grasp.copy()
        lift[2, 3] += LIFT
        ck.set_scene(qpos)
        ck.attach(None)
        ck.ignore_bodies([])
        picked = self._approach(pre, grasp, [q_from, READY_QPOS])
        if picked is None:
            counts["ik_failed"] += 1
            return None
        q_pre, q_grasp = picked
        pose_obj_in_tool = np.linalg.inv(grasp) @ obj
        ck.attach(Attachment(s.pick_body, a, pose_obj_in_tool))
        ck.ignore_bodies([self.model.body(s.container.id).id])
        q_lift = self._ik(lift, [q_grasp])
        ok_lift = q_lift is not None and ck.segment_valid(q_grasp, q_lift)
        ck.ignore_bodies([])
        if q_lift is None or not ok_lift:
            counts["ik_failed"] += 1
            return None
        xy = self.place_xy(q_open)
        z = self.floor_z(q_open) + PLACE_DROP
        found = None
        for turn in self.place_turns(grasp, xy):
            place_obj = np.eye(4)
            place_obj[:3, :3] = rot_z(turn) @ obj[:3, :3]
            place_obj[:3, 3] = [xy[0], xy[1], z]
            place = place_obj @ np.linalg.inv(pose_obj_in_tool)
            preplace = place.copy()
            preplace[:3, 3] += self.insert_offset()
            if s.behind_door:  # the arm's branch inside the case first, then the way in
                way_in = self._slide_in(place, preplace, [q_lift, q_from])
                if way_in is None:
                    continue
            else:
                q_preplace = self._ik(preplace, [q_lift])
                q_place = None if q_preplace is None else self._ik(place, [q_preplace])
                if q_preplace is None or q_place is None:
                    continue
                if not ck.segment_valid(q_preplace, q_place):
                    continue
                way_in = np.stack([q_preplace, q_place])
            found = (way_in, place, place_obj)
            break
        if found is None:
            counts["ik_failed"] += 1
            return None
        way_in, place, place_obj = found
        q_preplace, q_place = way_in[0], way_in[-1]
        ck.attach(None)
        ck.ignore_bodies([s.pick_body])
        up = self.retreat_pose(place)
        q_up = self._ik(up, [q_place])
        ok_up = q_up is not None and ck.segment_valid(q_place, q_up)
        ck.ignore_bodies([])
        if q_up is None or not ok_up:
            counts["ik_failed"] += 1
            return None
        seed = int(rng.integers(2**31 - 1))
        reach = plan(ck, q_from, q_pre, self.planner_cfg, seed)
        seconds["pick_reach"] = reach.seconds
        if reach.path is None:
            counts["plan_failed"] += 1
            return None
        ck.attach(Attachment(s.pick_body, a, pose_obj_in_tool))
        carry = plan(ck, q_lift, q_preplace, self.planner_cfg, seed + 1)
        ck.attach(None)
        seconds["transport"] = carry.seconds
        if carry.path is None:
            counts["plan_failed"] += 1
            return None
        moves = [
            ("pick_reach", reach.path, "fast_open"),
            ("pick_approach", np.stack([q_pre, q_grasp]), "slow_open"),
            ("pick_close", q_grasp[None], "hold_closed"),
            ("pick_lift", np.stack([q_grasp, q_lift]), "slow_closed"),
            ("transport", carry.path, "slow_closed"),
            ("lower", way_in, "slow_closed"),
            ("place_release", q_place[None], "hold_open"),
            ("place_retreat", np.stack([q_place, q_up]), "slow_open"),
        ]
        return moves, place_obj, q_up

    def plan_episode(self, seed: int) -> PlaceInsidePlan | PlanFailure:
        """Plans one episode (deterministic in ``seed``; module docstring)."""
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed)
        ck = self.checker
        try:
            start = self.object_pose(rng)
        except TaskError as e:
            return PlanFailure("no_object_pose", str(e), time.perf_counter() - t0)
        self._set_object(start)
        try:
            return self._plan(rng, t0)
        finally:
            self._set_object(self.home_pose)
            ck.attach(None)
            ck.ignore_bodies([])

    def _plan(self, rng: np.random.Generator, t0: float) -> PlaceInsidePlan | PlanFailure:
        s = self.setup
        opened = self.opener.plan_episode(int(rng.integers(2**31 - 1)))
        if isinstance(opened, PlanFailure):
            return PlanFailure(
                opened.reason, f"open: {opened.detail}", time.perf_counter() - t0, opened.counts
            )
        q_open = float(opened.q_goal)
        q_from = opened.targets[-1, :7]
        qpos = initial_state(s.art, q_open)
        counts: Counter[str] = Counter()
        grasps = self._grasps(qpos, rng)
        if not grasps:
            return PlanFailure(
                "no_grasp",
                f"no collision-free grasp on {s.pick.id!r}",
                time.perf_counter() - t0,
            )
        seconds = dict(opened.plan_seconds)
        for attempt, g in enumerate(grasps):
            res = self._pick_place(g, qpos, q_from, q_open, rng, counts, seconds)
            if res is None:
                continue
            moves, place_obj, q_up = res
            closing = self._close(place_obj, q_open, q_up, rng, counts, seconds)
            if closing is None:
                continue
            out = self._timeline(opened, moves, closing, g.width)
            out.plan_seconds = seconds
            out.attempts = attempt + 1
            out.q_open = q_open
            out.pose_obj_place = place_obj
            out.pose_tool_in_link_open = opened.pose_tool_in_link
            out.pose_tool_in_link_close = closing[0].grasp
            out.seconds = time.perf_counter() - t0
            return out
        tried = f"{s.pick.id} into {s.art.part.key}: {len(grasps)} grasps tried"
        return PlanFailure.of_counts(counts, "no_grasp", tried, t0)

    def _close(
        self,
        place_obj: np.ndarray,
        q_open: float,
        q_from: np.ndarray,
        rng: np.random.Generator,
        counts: Counter[str],
        seconds: dict[str, float],
    ) -> tuple[HandleMotion, np.ndarray] | None:
        """The close motion (the object resting at ``place_obj`` in the open drawer) and the
        reach to its pre-grasp from ``q_from``; None (counted) when they do not plan."""
        s = self.setup
        placed = np.zeros(7)
        placed[:3] = place_obj[:3, 3]
        mujoco.mju_mat2Quat(placed[3:], place_obj[:3, :3].flatten())
        before = np.array(self.model.qpos0[s.pick_adr : s.pick_adr + 7])
        self._set_object(placed)
        try:
            return self._close_from(q_open, q_from, rng, counts, seconds)
        finally:
            self._set_object(before)

    def _close_from(
        self,
        q_open: float,
        q_from: np.ndarray,
        rng: np.random.Generator,
        counts: Counter[str],
        seconds: dict[str, float],
    ) -> tuple[HandleMotion, np.ndarray] | None:
        s, ck = self.setup, self.checker
        pregrasp = float(rng.uniform(0.8, 1.2)) * self.motion.pregrasp
        grasps = grasps_in_link(s.art.part)
        for gi in rng.permutation(len(grasps)):
            res = grasp_and_follow(
                self.closer, self.kin, self.ik, ck, q_open, 0.0, grasps[gi], pregrasp, self.motion
            )
            if isinstance(res, str):
                counts[f"close_{res}"] += 1
                continue
            ck.set_scene(initial_state(s.art, q_open))
            ck.attach(None)
            ck.ignore_bodies([])
            reach = plan(ck, q_from, res.q_pre, self.planner_cfg, int(rng.integers(2**31 - 1)))
            seconds["close_reach"] = reach.seconds
            if reach.path is None:
                counts["plan_failed"] += 1
                continue
            return res, reach.path
        return None

    def _timeline(
        self,
        opened: ArticulatedPlan,
        moves: list[tuple[str, np.ndarray, str]],
        closing: tuple[HandleMotion, np.ndarray],
        width: float,
    ) -> PlaceInsidePlan:
        mo = self.motion
        tl = _Timeline(self.dt)
        for name, path, kind in moves:
            opening = GRIP_CLOSED if kind.endswith("closed") else GRIP_OPEN
            if kind.startswith("hold"):
                secs = mo.close if kind == "hold_closed" else mo.release
                tl.hold(name, path[0], secs, opening)
            else:
                tl.move(name, path, self.fast if kind.startswith("fast") else self.slow, opening)
        res, reach = closing
        tl.move("close_reach", reach, self.fast, GRIP_OPEN)
        tl.move("close_approach", np.stack([res.q_pre, res.q_grasp]), self.slow, GRIP_OPEN)
        tl.hold("close_grasp", res.q_grasp, mo.close, GRIP_CLOSED)
        tl.along("close_push", np.vstack([res.q_grasp[None], res.path]), self.pull, GRIP_CLOSED)
        tl.hold("close_release", res.path[-1], mo.release, GRIP_OPEN)
        tl.move("close_retreat", np.stack([res.path[-1], res.q_back]), self.slow, GRIP_OPEN)
        tl.hold("hold", res.q_back, mo.hold, GRIP_OPEN)
        n0 = len(opened.ctrl)
        phases = {f"open_{k}" if k != "end" else "open_end": v for k, v in opened.phases.items()}
        phases.update({k: v + n0 for k, v in tl.phases.items()})
        phases["end"] = n0 + len(tl.arm)
        ctrl = targets_to_ctrl(
            self.model, self.robot, np.asarray(tl.arm), np.asarray(tl.vel), tl.grip
        )
        targets = np.concatenate([np.asarray(tl.arm), np.asarray(tl.grip)[:, None]], axis=1)
        qpos0 = opened.qpos0.copy()
        return PlaceInsidePlan(
            qpos0,
            np.concatenate([opened.ctrl, ctrl]),
            np.concatenate([opened.targets, targets]),
            phases,
            float(width),
            {},
            0.0,
            0,
        )


def _door_rank(g: Grasp, pose: np.ndarray, com: np.ndarray) -> tuple[bool, int, float]:
    """How a grasp suits an object slid in behind a door, lower first: a steep approach (more
    than 55 deg from level: the wrist high, into the top of the opening) last; then the
    horizontal distance (cm) of the object's centre of mass from the grip (the contacts'
    middle: gravity turns an object held from the side about the grip when its centre is off
    it; a can held by its front edge turned over in the hand); then the most level approach.

    Args:
        g: the grasp (object frame).
        pose: the object's pose (4, 4), world frame.
        com: its centre of mass (3,) (m, world frame)."""
    down = -float((pose @ g.pose_tool_in_obj)[2, 2])  # 1: straight down, 0: level
    grip = pose[:3, :3] @ g.contacts_in_obj.mean(axis=0) + pose[:3, 3]
    off = float(np.hypot(*(com - grip)[:2]))
    return down > 0.82, round(100.0 * off), round(down, 1)


def _quat_mat(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    out = np.zeros(9)
    mujoco.mju_quat2Mat(out, np.asarray(quat, float))
    return out.reshape(3, 3)
