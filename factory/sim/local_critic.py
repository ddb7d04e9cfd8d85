"""What a candidate placement can touch: the neighbourhood the local physics critic simulates.

The whole-scene check simulates every free object of the scene for each candidate pose, so
its cost grows with the scene. The local check simulates a sub-scene instead:

* **dynamic** (free bodies, judged by the protocol): the candidate, every object it or its
  support chain rests against (the connected groups of free objects whose boxes touch, through
  ``placement.support_id`` and bounding-box contact), and the groups of free objects it could
  reach while staying within the protocol's thresholds;
* **static** (welded obstacles): every other object within reach of a dynamic one;
* **absent**: the rest; the rooms (walls, openings) near the dynamic bodies are kept.

Why the verdicts agree: MuJoCo solves contact islands separately, and the rest of a scene under
construction is at rest on its own (every earlier placement passed the check), so bodies that
share no contact with the candidate's island neither move nor push. A body the candidate
reaches only after moving farther than ``reach`` has already failed the candidate. Bodies are
boxed by their ``dimensions`` (the asset's extents) at their pose, grown by ``pad``.

Not covered (the verdicts may then differ): a rest of the scene that is not at rest on its
own (the whole-scene check fails every candidate then; this one judges the candidate), and a
body the candidate pushes less than the thresholds that then knocks a third one, static here,
beyond them. ``tests/scenes/test_local_critic.py`` checks the verdicts on a fixed set.

Frames and units: world frame, metres; poses ``[x, y, z, qw, qx, qy, qz]`` of the object's
bottom centre.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from factory.errors import ConfigError
from factory.schema import Scene, SceneObject

REACH = 0.25
"""How far (m) beyond its box a body can still move without failing the protocol's 0.2 m
translation, with a margin (the sweep of a turn is added per body from its size)."""

TURN_DEG = 8.0
"""The protocol's largest turn (deg) of a stable body."""

TOUCH = 0.01
"""Boxes closer than this (m) may be in contact: their objects belong to one group."""

PAD = 0.01
"""Slack (m) added around each box for collision hulls that poke past the extents."""


@dataclass(frozen=True)
class Neighbourhood:
    """The part of a scene one placement check simulates.

    Attributes:
        object_id: the object being placed.
        dynamic: ids simulated as free bodies (the placed object first, then scene order).
        static: ids kept as welded obstacles (scene order).
        rooms: ids of the rooms whose architecture is kept.
        objects: objects in the whole scene.
    """

    object_id: str
    dynamic: tuple[str, ...]
    static: tuple[str, ...]
    rooms: tuple[str, ...]
    objects: int

    def as_dict(self) -> dict[str, int]:
        """Counts, JSON-ready."""
        return {"dynamic": len(self.dynamic), "static": len(self.static), "of": self.objects}


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotation matrices of unit quaternions ``(n, 4)`` (w, x, y, z)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


_CORNERS = np.array(
    [[sx / 2, sy / 2, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (0, 1)], float
)
"""The 8 corners of a unit box standing on its bottom centre (x, y in -0.5..0.5, z in 0..1)."""


def _boxes(poses: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """``(n, 2, 3)`` axis-aligned boxes of boxes ``sizes (n, 3)`` at ``poses (n, 7)``."""
    rot = _quat_matrix(np.asarray(poses[:, 3:7], float))
    corners = _CORNERS[None] * sizes[:, None, :]
    world = np.einsum("nij,nkj->nki", rot, corners) + poses[:, None, :3]
    return np.stack([world.min(axis=1), world.max(axis=1)], axis=1)


def boxes_of(objects: list[SceneObject]) -> np.ndarray:
    """``(n, 2, 3)`` axis-aligned boxes (min, max corners; m, world frame) of objects at their
    poses, from their ``dimensions`` (width x, length y, height z over the bottom centre)."""
    if not objects:
        return np.zeros((0, 2, 3))
    poses = np.array(
        [[o.position.x, o.position.y, o.position.z, *o.rotation.quat_wxyz()] for o in objects]
    )
    sizes = np.array([o.dimensions.as_tuple() for o in objects], float)
    return _boxes(poses, sizes)


def box_of(obj: SceneObject, poses: np.ndarray) -> np.ndarray:
    """``(2, 3)`` axis-aligned box around an object at all of ``poses (n, 7)``."""
    poses = np.atleast_2d(np.asarray(poses, float))
    sizes = np.tile(np.array(obj.dimensions.as_tuple(), float), (len(poses), 1))
    b = _boxes(poses, sizes)
    return np.stack([b[:, 0].min(axis=0), b[:, 1].max(axis=0)])


def _gaps(boxes: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Largest per-axis separation (m; <= 0 where overlapping) of ``boxes (k, 2, 3)`` from
    ``box (2, 3)``."""
    sep = np.maximum(boxes[:, 0] - box[1], box[0] - boxes[:, 1])
    return np.asarray(sep.max(axis=1))


def _sweep(box: np.ndarray, turn_deg: float) -> float:
    """Extra reach (m) of a body's far corners when it turns by ``turn_deg``."""
    return float(np.linalg.norm(box[1] - box[0])) * math.radians(turn_deg)


def neighbourhood(
    scene: Scene,
    object_id: str,
    poses: np.ndarray,
    *,
    reach: float = REACH,
    turn_deg: float = TURN_DEG,
    touch: float = TOUCH,
    pad: float = PAD,
) -> Neighbourhood:
    """The objects one batch of candidate poses of ``object_id`` can touch.

    Args:
        scene: the scene (the object's own pose in it is ignored).
        object_id: the object being placed (a free object of the scene).
        poses: ``(n, 7)`` candidate poses, world frame.
        reach: see :data:`REACH` (m).
        turn_deg: see :data:`TURN_DEG` (deg).
        touch: see :data:`TOUCH` (m).
        pad: see :data:`PAD` (m).

    Raises:
        ConfigError: ``object_id`` is not a free object of the scene.
    """
    objs = scene.objects
    ids = [o.id for o in objs]
    if object_id not in ids:
        raise ConfigError(f"{object_id!r} is not an object of scene {scene.id!r}")
    me = ids.index(object_id)
    if objs[me].is_static:
        raise ConfigError(f"{object_id!r} is static: only free objects can be judged")
    boxes = boxes_of(objs)
    boxes[me] = box_of(objs[me], poses)
    boxes[:, 0] -= pad
    boxes[:, 1] += pad
    free = np.array([not o.is_static for o in objs])
    index = {oid: i for i, oid in enumerate(ids)}

    # groups of free objects that may rest against each other (union-find)
    parent = list(range(len(objs)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(i: int, j: int) -> None:
        parent[root(i)] = root(j)

    others = [i for i in range(len(objs)) if free[i] and i != me]
    for i in others:
        near = _gaps(boxes, boxes[i]) <= touch
        for j in np.flatnonzero(near & free).tolist():
            if j != me and j != i:
                join(i, j)
        sup = index.get(objs[i].placement.support_id or "")
        if sup is not None and free[sup] and sup != me:
            join(i, sup)

    reachable = _gaps(boxes, boxes[me]) <= reach + _sweep(boxes[me], turn_deg)
    seeds: set[int] = set(np.flatnonzero(free & reachable).tolist())
    seeds.discard(me)
    chain: set[int] = set()
    sup_id = objs[me].placement.support_id
    while sup_id in index and index[sup_id] not in chain:  # the support chain, even where a
        k = index[sup_id]  # box test would miss it
        chain.add(k)
        if free[k]:
            seeds.add(k)
        sup_id = objs[k].placement.support_id
    groups = {root(int(i)) for i in seeds}
    dynamic = [me] + [i for i in others if root(i) in groups]
    dyn = set(dynamic)
    near = np.zeros(len(objs), bool)
    for j in dynamic:
        near |= _gaps(boxes, boxes[j]) <= reach + _sweep(boxes[j], turn_deg)
    static = [i for i in np.flatnonzero(near).tolist() if i not in dyn]
    lo = boxes[dynamic, 0].min(axis=0) - reach
    hi = boxes[dynamic, 1].max(axis=0) + reach
    rooms = []
    for r in scene.rooms:
        t = max((w.thickness for w in r.walls), default=0.1)
        x0, y0 = r.position.x - t, r.position.y - t
        x1 = r.position.x + r.dimensions.width + t
        y1 = r.position.y + r.dimensions.length + t
        if x0 <= hi[0] and lo[0] <= x1 and y0 <= hi[1] and lo[1] <= y1:
            rooms.append(r.id)
    return Neighbourhood(
        object_id=object_id,
        dynamic=tuple(ids[i] for i in dynamic),
        static=tuple(ids[i] for i in static),
        rooms=tuple(rooms or [r.id for r in scene.rooms]),
        objects=len(objs),
    )


def local_scene(scene: Scene, hood: Neighbourhood) -> Scene:
    """The sub-scene of a neighbourhood: its rooms, its dynamic objects as they are and its
    static ones welded (``physics.static``); nothing else. Shares no mutable state with
    ``scene`` that compiling would change."""
    dynamic, static = set(hood.dynamic), set(hood.static)
    objects = []
    for o in scene.objects:
        if o.id in dynamic:
            objects.append(o)
        elif o.id in static:
            objects.append(
                dataclasses.replace(o, physics=dataclasses.replace(o.physics, static=True))
            )
    keep = set(hood.rooms)
    return dataclasses.replace(
        scene, rooms=[r for r in scene.rooms if r.id in keep], objects=objects
    )
