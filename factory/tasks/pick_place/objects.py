"""The pick-and-place task in a scene: which objects, where the robot stands, per-episode object
poses (configuration-level randomization) and the success check.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from factory.errors import TaskError
from factory.robots.panda import GRIP_OPEN, HOME_QPOS, RobotIndex, RobotPlacement, rot_z, yaw_quat
from factory.schema import Scene, SceneObject


@dataclass(frozen=True)
class TaskObjects:
    """The objects of a pick-and-place task.

    Attributes:
        pick: the object to move; target: where it goes; support: what the pick stands on.
        relation: ``in`` or ``on``.
    """

    pick: SceneObject
    target: SceneObject
    support: SceneObject
    relation: str = "in"


def _by_text(scene: Scene, text: str, exclude: set[str]) -> SceneObject | None:
    from factory.assets.resolver import resolve

    category = resolve(text).spec.category
    for obj in scene.objects:
        if obj.id not in exclude and obj.category == category and not obj.is_static:
            return obj
    return None


def task_objects(scene: Scene) -> TaskObjects:
    """The pick object, the target and the pick's support of a scene.

    Objects with ``task_role`` ``pick`` / ``place_target`` decide; without them the scene's task
    instruction ("pick up the mug and put it in the bowl") is read.

    Raises:
        TaskError: the scene lacks the objects (the message says what is missing).
    """
    pick = next((o for o in scene.objects if o.task_role == "pick"), None)
    target = next((o for o in scene.objects if o.task_role == "place_target"), None)
    relation = "in"
    if (pick is None or target is None) and scene.task is not None and scene.task.instruction:
        from factory.scenes.request import parse_task

        spec = parse_task(scene.task.instruction)
        if spec is not None:
            relation = "on" if spec.relation in ("on", "onto") else "in"
            pick = pick or _by_text(scene, spec.pick, set())
            target = target or _by_text(scene, spec.target, {pick.id} if pick else set())
    if pick is None or target is None:
        missing = "pick object" if pick is None else "place target"
        raise TaskError(
            f"scene {scene.id!r} has no {missing}: give objects task_role 'pick' and "
            "'place_target', or a task instruction naming objects in the scene"
        )
    if pick.placement.support_id is None:
        raise TaskError(f"scene {scene.id!r}: pick object {pick.id!r} stands on no support")
    support = scene.object(pick.placement.support_id)
    return TaskObjects(pick, target, support, relation)


def _footprint_radius(obj: SceneObject) -> float:
    return 0.5 * math.hypot(obj.dimensions.width, obj.dimensions.length)


def _support_frame(support: SceneObject) -> tuple[np.ndarray, float, float, float]:
    """Centre (x, y), yaw (rad), half width and half length of a support's top."""
    yaw = math.radians(support.rotation.z)
    c = np.array([support.position.x, support.position.y])
    return c, yaw, support.dimensions.width / 2, support.dimensions.length / 2


def base_candidates(
    objects: TaskObjects, standoff: float = 0.22, spacing: float = 0.25
) -> list[RobotPlacement]:
    """Base spots around the support's edges, facing it, ordered by distance to the pick.

    Args:
        objects: the task objects.
        standoff: distance of the base centre outside the support's edge (m).
        spacing: spacing of spots along an edge (m).
    """
    c, yaw, hw, hl = _support_frame(objects.support)
    rot = rot_z(yaw)[:2, :2]
    top = objects.pick.position.z
    out: list[tuple[float, RobotPlacement]] = []
    pick_xy = np.array([objects.pick.position.x, objects.pick.position.y])
    for normal, along, half_edge, half_depth in (
        (np.array([1.0, 0.0]), np.array([0.0, 1.0]), hl, hw),
        (np.array([-1.0, 0.0]), np.array([0.0, 1.0]), hl, hw),
        (np.array([0.0, 1.0]), np.array([1.0, 0.0]), hw, hl),
        (np.array([0.0, -1.0]), np.array([1.0, 0.0]), hw, hl),
    ):
        n_spots = max(1, int(2 * max(half_edge - 0.15, 0.0) / spacing) + 1)
        for s in np.linspace(-max(half_edge - 0.15, 0.0), max(half_edge - 0.15, 0.0), n_spots):
            local = normal * (half_depth + standoff) + along * s
            xy = c + rot @ local
            face = rot @ (-normal)
            heading = math.atan2(face[1], face[0])
            dist = float(np.linalg.norm(xy - pick_xy))
            out.append((dist, RobotPlacement(float(xy[0]), float(xy[1]), top, heading)))
    out.sort(key=lambda t: t[0])
    return [p for _, p in out]


def move_robot(model: mujoco.MjModel, placement: RobotPlacement, base_body: int) -> None:
    """Moves the (static) robot base and the world cameras of a composed model in place."""
    old_pos = np.array(model.body_pos[base_body])
    old_yaw = 2 * math.atan2(model.body_quat[base_body][3], model.body_quat[base_body][0])
    model.body_pos[base_body] = placement.pos()
    model.body_quat[base_body] = placement.quat()
    dyaw = placement.yaw - old_yaw
    rz = rot_z(dyaw)
    qz = yaw_quat(dyaw)
    for cam in ("camera_left", "camera_right"):
        cid = model.camera(cam).id
        model.cam_pos[cid] = rz @ (model.cam_pos[cid] - old_pos) + placement.pos()
        out = np.zeros(4)
        mujoco.mju_mulQuat(out, qz, model.cam_quat[cid])
        model.cam_quat[cid] = out


@dataclass(frozen=True)
class Workspace:
    """Where task objects may be put for an episode: on the support, within the arm's reach.

    Attributes:
        reach_min, reach_max: horizontal distance from the base (m).
        max_angle_deg: largest angle from the base's heading.
        margin: clearance from the support's edge and between objects (m).
    """

    reach_min: float = 0.35
    reach_max: float = 0.68
    max_angle_deg: float = 65.0
    margin: float = 0.03


def _free_joint(model: mujoco.MjModel, body_name: str) -> int:
    jid = int(model.body(body_name).jntadr[0])
    if jid < 0 or model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_FREE:
        raise TaskError(f"object {body_name!r} is not a free body (static objects cannot be moved)")
    return int(model.jnt_qposadr[jid])


def initial_state(model: mujoco.MjModel, robot: RobotIndex) -> np.ndarray:
    """The scene's initial qpos (nq,) with the robot at home and the hand open."""
    q = np.array(model.qpos0)
    q[robot.qpos] = HOME_QPOS
    q[robot.finger_qpos] = robot.finger_pos(GRIP_OPEN)
    return q


def randomize(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    scene: Scene,
    objects: TaskObjects,
    placement: RobotPlacement,
    ws: Workspace,
    rng: np.random.Generator,
    tries: int = 400,
    rounds: int = 8,
) -> np.ndarray:
    """Re-places the pick object and the target on the support within reach (new qpos).

    Other objects on the support stay; the two task objects keep clear of them and of each
    other, and turn by a random yaw. The target is placed first, then the pick object; where
    the target's spot leaves the pick object none (a support with little free room within
    reach), both are drawn again, up to ``rounds`` times (a seed that succeeds at once draws
    the same numbers as with one round).

    Raises:
        TaskError: no free spot within reach after ``tries`` samples per object in each of
            ``rounds`` rounds.
    """
    c, yaw, hw, hl = _support_frame(objects.support)
    rot = rot_z(yaw)[:2, :2]
    others = [
        (np.array([o.position.x, o.position.y]), _footprint_radius(o))
        for o in scene.objects
        if o.placement.support_id == objects.support.id
        and o.id not in (objects.pick.id, objects.target.id)
    ]

    def spot(r: float, taken: list[tuple[np.ndarray, float]]) -> np.ndarray | None:
        """A free spot (x, y) in the world frame for a footprint of radius ``r`` (m)."""
        for _ in range(tries):
            dist = rng.uniform(ws.reach_min, ws.reach_max)
            ang = math.radians(rng.uniform(-ws.max_angle_deg, ws.max_angle_deg)) + placement.yaw
            xy = placement.pos()[:2] + dist * np.array([math.cos(ang), math.sin(ang)])
            local = rot.T @ (xy - c)
            if abs(local[0]) > hw - r - ws.margin or abs(local[1]) > hl - r - ws.margin:
                continue
            if any(np.linalg.norm(xy - p) < r + pr + ws.margin for p, pr in taken):
                continue
            return xy
        return None

    blocked = objects.target
    for _ in range(rounds):
        placed: list[tuple[np.ndarray, float]] = []  # (x, y) in the world frame, radius (m)
        turns: list[float] = []  # yaw turn of each placed object (rad)
        for obj in (objects.target, objects.pick):
            r = _footprint_radius(obj)
            xy = spot(r, others + placed)
            if xy is None:
                blocked = obj
                break
            placed.append((xy, r))
            turns.append(rng.uniform(-math.pi, math.pi))
        else:
            break
    else:
        raise TaskError(
            f"no free spot for {blocked.id!r} on {objects.support.id!r} within the arm's reach"
        )
    q = np.array(qpos)
    for obj, (xy, _), turn in zip((objects.target, objects.pick), placed, turns, strict=True):
        adr = _free_joint(model, obj.id)
        q[adr : adr + 2] = xy
        q[adr + 2] = obj.position.z
        quat = np.zeros(4)
        mujoco.mju_mulQuat(quat, yaw_quat(turn), q[adr + 3 : adr + 7])
        q[adr + 3 : adr + 7] = quat
    return q


@dataclass
class Outcome:
    """The success check of one executed episode.

    Attributes:
        success: the object ends in/on the target, stable and released.
        reason: ``""`` on success, else ``slip``, ``not_on_target``, ``unstable``,
            ``not_released`` or ``collision``.
        details: numbers behind the verdict.
    """

    success: bool
    reason: str
    details: dict[str, float]


def check_success(
    model: mujoco.MjModel,
    final_qpos: np.ndarray,
    before_qpos: np.ndarray,
    lifted_z: float,
    start_z: float,
    objects: TaskObjects,
    robot: RobotIndex,
    max_robot_penetration: float,
    settle_tol: float = 0.005,
) -> Outcome:
    """Whether an executed pick-and-place succeeded.

    Args:
        model: the composed model.
        final_qpos: state at the end (nq,); before_qpos: state ``settle`` seconds earlier.
        lifted_z: the pick object's height at the end of the lift (m); start_z: at the start.
        objects: the task objects.
        robot: its index.
        max_robot_penetration: deepest contact of the robot with the scene (other than the
            pick object) during execution (m).
        settle_tol: the object moved less than this between the two states (m) if stable.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = final_qpos
    mujoco.mj_forward(model, data)
    pick = model.body(objects.pick.id).id
    target = model.body(objects.target.id).id
    p = data.xpos[pick]
    t = data.xpos[target]
    tdim = objects.target.dimensions
    horiz = float(np.linalg.norm(p[:2] - t[:2]))
    inside_r = 0.5 * min(tdim.width, tdim.length)
    adr = _free_joint(model, objects.pick.id)
    moved = float(np.linalg.norm(final_qpos[adr : adr + 3] - before_qpos[adr : adr + 3]))
    touching_target = touching_fingers = False
    for c in data.contact[: data.ncon]:
        bodies = {int(model.geom_bodyid[c.geom[0]]), int(model.geom_bodyid[c.geom[1]])}
        if pick in bodies and target in bodies:
            touching_target = True
        if pick in bodies and np.isin(list(bodies), robot.bodies).any():
            touching_fingers = True
    details = {
        "lift_m": float(lifted_z - start_z),
        "xy_offset_m": horiz,
        "target_radius_m": inside_r,
        "z_above_target_m": float(p[2] - t[2]),
        "settle_motion_m": moved,
        "robot_penetration_m": max_robot_penetration,
    }
    if lifted_z - start_z < 0.03:
        return Outcome(False, "slip", details)
    if max_robot_penetration > 0.02:
        return Outcome(False, "collision", details)
    on = horiz < inside_r and (touching_target or p[2] - t[2] < tdim.height)
    if not on:
        return Outcome(False, "not_on_target", details)
    if touching_fingers:
        return Outcome(False, "not_released", details)
    if moved > settle_tol:
        return Outcome(False, "unstable", details)
    return Outcome(True, "", details)


def object_poses(data: mujoco.MjData, bodies: tuple[int, int]) -> np.ndarray:
    """The environment state (14,): position (m) and quaternion wxyz of the pick object, then
    of the target, world frame (their bodies' frames; ``data`` needs current kinematics)."""
    return np.concatenate([np.concatenate([data.xpos[b], data.xquat[b]]) for b in bodies])
