"""The local scene of a set of moving objects: what their new poses can affect, and no more.

Augmentation re-poses a few objects (the task objects) many times over; simulating the whole
scene for every candidate costs about ten times more than simulating what the candidates can
touch. The local scene keeps

* *dynamic* (free bodies, judged by the protocol): the moving objects, their support chains
  down to the floor, everything standing (transitively) on a dynamic object, and, repeatedly,
  every free object whose box comes within ``touch`` of a dynamic object's box (it may rest
  against it, so it moves with it), with its own support chain;
* *context* (welded obstacles): every other object whose footprint comes within ``margin`` of a
  dynamic object's footprint in the plane (at any height);
* the rooms (floor, walls) as they are;

and leaves out every other object. A moving object's box is the box of the support surfaces it
may be put on, up to its height. A candidate is judged by simulating the local scene with the
strict protocol; the objects outside the dynamic set are judged once, by the whole-scene check
of the parent (:func:`factory.augment.check.parent_verdict`). MuJoCo solves contact islands
separately and nothing outside the dynamic set rests against it, so the verdicts agree with
the whole-scene check unless an object outside moves far enough during its own settling to
reach the dynamic ones (``stage=augment`` re-checks every kept variant with the ordinary
whole-scene check, batched).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from factory.augment.rects import corners, rect_rows, rects_overlap
from factory.schema import Scene, SceneObject

CONTEXT_MARGIN = 0.3
"""Default reach of the static context around the dynamic objects (m, in the plane)."""

TOUCH = 0.01
"""Boxes closer than this (m) may be in contact: a free object that close joins the dynamic
set."""


@dataclass(frozen=True)
class LocalScene:
    """A reduced scene for batched checks.

    Attributes:
        scene: the reduced scene (context objects marked static); compile it, do not save it.
        dynamic: ids of the objects simulated as free bodies (scene order).
        context: ids of the objects kept as static collision geometry (scene order).
        absent: ids of the objects left out (scene order).
    """

    scene: Scene
    dynamic: tuple[str, ...]
    context: tuple[str, ...]
    absent: tuple[str, ...]


def _rect(obj: SceneObject) -> list[float]:
    d = obj.dimensions
    return [obj.position.x, obj.position.y, d.width / 2, d.length / 2, math.radians(obj.rotation.z)]


def _box(obj: SceneObject) -> np.ndarray:
    """``(2, 3)`` axis-aligned box (m, world) of an upright object's extents."""
    c = corners(np.array(_rect(obj)))
    z0 = obj.position.z
    return np.array([[*c.min(axis=0), z0], [*c.max(axis=0), z0 + obj.dimensions.height]])


def _mover_box(obj: SceneObject, support: SceneObject) -> np.ndarray:
    """Where a moving object may end up: over its support's footprint, from its support's base
    to the object's height above the support's top."""
    box = _box(support)
    box[1, 2] = support.position.z + support.dimensions.height + obj.dimensions.height
    return box


def _near(boxes: np.ndarray, box: np.ndarray, gap: float) -> np.ndarray:
    """``(n,)`` whether each of ``boxes (n, 2, 3)`` comes within ``gap`` of ``box (2, 3)``."""
    sep = np.maximum(boxes[:, 0] - box[1], box[0] - boxes[:, 1])
    return np.asarray(sep.max(axis=1) <= gap)


def local_scene(
    scene: Scene, moving: list[str], margin: float = CONTEXT_MARGIN, touch: float = TOUCH
) -> LocalScene:
    """The local scene of ``moving`` (ids of free objects of ``scene``, each on a support).

    Args:
        scene: the whole scene (not modified).
        moving: the objects whose poses change.
        margin: objects within this distance of a dynamic object's footprint (m) stay as static
            context.
        touch: see :data:`TOUCH` (m).
    """
    objs = scene.objects
    by_id = {o.id: o for o in objs}
    index = {o.id: i for i, o in enumerate(objs)}
    boxes = np.stack([_box(o) for o in objs]) if objs else np.zeros((0, 2, 3))
    for oid in moving:
        sup = by_id.get(by_id[oid].placement.support_id or "")
        if sup is not None:
            boxes[index[oid]] = _mover_box(by_id[oid], sup)
    dyn = np.zeros(len(objs), bool)

    def add(i: int) -> None:
        """Object ``i``, its support chain and what stands on them."""
        cur: SceneObject | None = objs[i]
        while cur is not None and not dyn[index[cur.id]]:
            dyn[index[cur.id]] = True
            sup = cur.placement.support_id
            cur = by_id.get(sup or "") if cur.placement.kind == "on_top" else None

    for oid in moving:
        add(index[oid])
    grew = True
    while grew:
        grew = False
        for i, obj in enumerate(objs):
            if dyn[i] or obj.is_static:
                continue
            standing = (
                obj.placement.kind == "on_top" and dyn[index.get(obj.placement.support_id or "", i)]
            )
            touching = bool(_near(boxes[dyn], boxes[i], touch).any())
            if standing or touching:
                add(i)
                grew = True
    near = np.zeros(len(objs), bool)
    rest = np.flatnonzero(~dyn)
    if len(rest):
        rects = rect_rows(*np.array([_rect(o) for o in objs]).T)
        hit = rects_overlap(rects[dyn][:, None, :], rects[rest][None, :, :], margin / 2)
        near[rest] = hit.any(axis=0)
    reduced = copy.copy(scene)
    reduced.objects = []
    for i, obj in enumerate(objs):
        if dyn[i]:
            reduced.objects.append(obj)
        elif near[i]:
            fixed = copy.copy(obj)
            fixed.physics = copy.copy(obj.physics)
            fixed.physics.static = True
            reduced.objects.append(fixed)
    return LocalScene(
        scene=reduced,
        dynamic=tuple(o.id for i, o in enumerate(objs) if dyn[i]),
        context=tuple(o.id for i, o in enumerate(objs) if near[i]),
        absent=tuple(o.id for i, o in enumerate(objs) if not dyn[i] and not near[i]),
    )
