"""Corner views that nothing blocks, chosen with rays in the compiled scene.

A corner camera (:func:`factory.scenes.render.view_cameras`) stands in a room's corner near the
ceiling; a lamp shade or a cabinet right in front of it fills the picture. Here each corner
view tries eyes from the corner towards the room's centre, then along its walls (and lower),
and takes the first where

* **nothing blocks it**: a fan of :data:`FAN` x :data:`FAN` rays through the view's frustum
  hits no object's geom within :data:`CLEAR_M` of the eye (walls, floors and ceilings do not
  count), and
* **it shows the room**: at least :data:`MIN_SHARE` of the room's objects are seen: inside the
  frustum, and the ray from the eye to the object's middle hits that object first (objects
  stored inside furniture, on a shelf board below their support's top, are not counted);

or, where no eye does both, the one that shows the most with nothing in front. Rays are
MuJoCo's (``mj_ray``) on the visible geoms at the model's initial state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from factory.schema import Room, Scene

__all__ = ["CLEAR_M", "MIN_SHARE", "ViewCheck", "check_eye", "clear_eye", "rays_in"]

CLEAR_M = 1.0
"""Nothing within this distance of the eye (m) in the view's frustum."""
MIN_SHARE = 0.5
"""Least share of the room's objects a view shows."""
FAN = 9
"""Rays per side of the fan that looks for blockers (FAN x FAN)."""
STEPS_M = (0.0, 0.4, 0.8, 1.2)
"""Eyes tried along the line from the corner to the room's centre (m from the corner)."""
WALL_STEPS_M = (0.6, 1.2)
"""... then along either wall of the corner (m from the corner): away from a tall cabinet."""
LOWER_M = (0.0, 0.45)
"""... at the corner's eye height and this much lower (m)."""
VISIBLE_GROUPS = (0, 1, 2)
"""Geom groups the renderer draws (walls, floors, visual meshes; not collision pieces)."""


@dataclass(frozen=True)
class ViewCheck:
    """What an eye sees: ``blocked``: an object within :data:`CLEAR_M` in the frustum;
    ``seen``/``objects``: the room's objects it shows, of how many."""

    eye: tuple[float, float, float]
    blocked: bool
    seen: int
    objects: int

    @property
    def share(self) -> float:
        """Share of the room's objects shown (1 for an empty room)."""
        return self.seen / self.objects if self.objects else 1.0

    @property
    def good(self) -> bool:
        """Nothing in front and at least :data:`MIN_SHARE` shown."""
        return not self.blocked and self.share >= MIN_SHARE


def _object_of_geom(model: mujoco.MjModel, scene: Scene) -> np.ndarray:
    """(ngeom,) index into ``scene.objects`` of each geom's object (its body, or the nearest
    ancestor named as an object: a static object may hang below its support's body), -1 for
    none (walls, floors, ceilings)."""
    index = {o.id: i for i, o in enumerate(scene.objects)}
    owner = np.full(model.nbody, -1, dtype=np.int64)
    for b in range(1, model.nbody):  # parents come before their children
        i = index.get(model.body(b).name, -1)
        owner[b] = i if i >= 0 else owner[int(model.body_parentid[b])]
    return owner[model.geom_bodyid]


def _stored(scene: Scene) -> set[int]:
    """Indices of the objects stored inside furniture (on a shelf board below their
    support's top: in a cabinet, a wardrobe), which no view is meant to show."""
    by_id = {o.id: o for o in scene.objects}
    out = set()
    for i, o in enumerate(scene.objects):
        support = by_id.get(o.placement.support_id or "")
        if o.placement.kind == "on_top" and support is not None:
            top = support.position.z + support.dimensions.height
            if o.position.z + o.dimensions.height < top - 0.01:
                out.add(i)
    return out


def _frame(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return fwd, right, np.cross(right, fwd)


class _Rays:
    """Ray casts in one compiled scene at its initial state."""

    def __init__(self, model: mujoco.MjModel, scene: Scene) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_forward(model, self.data)
        self.scene = scene
        self.owner = _object_of_geom(model, scene)
        self.stored = _stored(scene)
        self.groups = np.zeros(6, np.uint8)
        self.groups[list(VISIBLE_GROUPS)] = 1
        self._hit = np.zeros(1, np.int32)

    def cast(self, eye: np.ndarray, direction: np.ndarray) -> tuple[float, int]:
        """Distance (m; inf: none) and object index (-1: structure or none) of the first
        visible geom along a unit ``direction`` from ``eye``."""
        d = mujoco.mj_ray(self.model, self.data, eye, direction, self.groups, 1, -1, self._hit)
        if d < 0:
            return math.inf, -1
        return float(d), int(self.owner[int(self._hit[0])])

    def check(
        self, room: Room, eye: np.ndarray, target: np.ndarray, fovy: float, aspect: float
    ) -> ViewCheck:
        fwd, right, up = _frame(eye, target)
        tv = math.tan(math.radians(fovy / 2))
        th = tv * aspect
        blocked = False
        for a in np.linspace(-th, th, FAN):
            for b in np.linspace(-tv, tv, FAN):
                ray = fwd + a * right + b * up
                ray /= np.linalg.norm(ray)
                dist, obj = self.cast(eye, ray)
                if obj >= 0 and dist < CLEAR_M:
                    blocked = True
                    break
            if blocked:
                break
        seen = total = 0
        for i, o in enumerate(self.scene.objects):
            if o.room_id != room.id or i in self.stored:
                continue
            total += 1
            mid = np.array([o.position.x, o.position.y, o.position.z + o.dimensions.height / 2])
            to = mid - eye
            dist = float(np.linalg.norm(to))
            if dist < 1e-6:
                continue
            to /= dist
            f = float(to @ fwd)
            if f <= 0 or abs(to @ right) / f > th or abs(to @ up) / f > tv:
                continue  # outside the frustum
            hit, obj = self.cast(eye, to)
            if obj == i or hit >= dist - 0.02:
                seen += 1
        return ViewCheck(tuple(float(v) for v in eye), blocked, seen, total)  # type: ignore[arg-type]


def rays_in(model: mujoco.MjModel, scene: Scene) -> _Rays:
    """A ray caster in the compiled ``model`` of ``scene`` (at its initial state), for
    several :func:`clear_eye` calls."""
    return _Rays(model, scene)


def check_eye(
    model: mujoco.MjModel,
    scene: Scene,
    room: Room,
    eye: tuple[float, float, float],
    target: tuple[float, float, float],
    fovy: float,
    aspect: float,
) -> ViewCheck:
    """What a camera at ``eye`` looking at ``target`` (m, world; ``fovy`` deg, ``aspect``
    width / height) sees of ``room`` in the compiled ``model`` of ``scene``."""
    return _Rays(model, scene).check(
        room, np.array(eye, float), np.array(target, float), fovy, aspect
    )


def clear_eye(
    rays_or_model: mujoco.MjModel | _Rays,
    scene: Scene,
    room: Room,
    eye: tuple[float, float, float],
    target: tuple[float, float, float],
    fovy: float,
    aspect: float,
) -> ViewCheck:
    """The eye for a corner view: the first of the eyes tried (:data:`STEPS_M` towards the
    room's centre, then :data:`WALL_STEPS_M` along either wall; each also :data:`LOWER_M`
    lower) that is :attr:`ViewCheck.good`, else the unblocked one that shows the most, else
    the one that shows the most.

    Args:
        rays_or_model: the compiled scene (or a reused ray caster).
        scene: the scene.
        room: the room the view looks into.
        eye: the corner's eye (m, world).
        target: where the view looks (m, world).
        fovy: vertical field of view (deg).
        aspect: width / height.
    """
    rays = rays_or_model if isinstance(rays_or_model, _Rays) else _Rays(rays_or_model, scene)
    e0, t = np.array(eye, float), np.array(target, float)
    flat = t[:2] - e0[:2]
    reach = float(np.linalg.norm(flat))
    along = flat / reach if reach > 1e-6 else np.zeros(2)
    walls = [
        np.array([math.copysign(1.0, flat[0]), 0.0]),
        np.array([0.0, math.copysign(1.0, flat[1])]),
    ]
    offsets = [step * along for step in STEPS_M if step <= 0.6 * reach]
    offsets += [step * w for w in walls for step in WALL_STEPS_M if step <= 0.6 * reach]
    tried: list[ViewCheck] = []
    for offset in offsets:
        for lower in LOWER_M:
            e = np.array([*(e0[:2] + offset), e0[2] - lower])
            v = rays.check(room, e, t, fovy, aspect)
            if v.good:
                return v
            tried.append(v)
    return max(tried, key=lambda v: (not v.blocked, v.share))
