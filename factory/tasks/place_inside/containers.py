"""Which container part and which object a ``place_inside`` scene's episodes use.

The container part is a part (:func:`~factory.tasks.articulated.parts.scene_parts`) whose moving
link carries an interior support and volume (``meta.json``'s ``supports`` and ``containers``
with ``link``: a drawer's floor and tray; docs/ASSETS.md, "Articulated categories"), of an
object with a top (``case_top``) to stand the object on, big enough for the object. Empty
drawers come first; a drawer with something stored on its floor (a plate in a kitchen drawer,
a book in a dresser's) comes after them, what is stored in it taken out of the scene when it
is chosen (:attr:`Container.stored`). The object is the scene's ``task_role`` ``pick`` object,
else the first movable object of :data:`PICK_CATEGORIES`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from factory.errors import TaskError
from factory.schema import Scene, SceneObject
from factory.tasks.articulated.parts import Part, names_part, scene_parts

__all__ = [
    "LOW_DROP",
    "MARGIN",
    "PICK_CATEGORIES",
    "Container",
    "Interior",
    "container_parts",
    "container_top",
    "on_top",
    "pick_object",
    "without",
]

PICK_CATEGORIES = ("mug", "cup", "can", "apple", "orange", "jar")
"""Small objects the task puts away when the scene names no pick object (``task_role``)."""
MARGIN = 0.03
"""Clearance (m) between the object and the interior's walls, and from the top's edges."""
LOW_DROP = 0.35
"""A drawer whose floor lies more than this (m) below its object's top is *low*: offered after
the others. The base spot stands at the handle's height minus 0.1 m, and from one in front of
a dresser's middle drawer (floor 0.51 m under the 0.8 m top) the arm reached the object on the
top and the drawer's floor in 1 of 15 attempts (``ik_failed``); a kitchen base cabinet's
drawer (0.20 m under its top), a nightstand's (0.16 m) and a dresser's top drawer (0.25 m)
are not low."""


@dataclass(frozen=True)
class Interior:
    """The interior behind a part: the support and volume its link carries.

    Attributes:
        floor_z: the support's height (m, object frame, scaled).
        lo, hi: the interior volume's corners (3,) (m, object frame in the closed pose, which is
            the link's frame; scaled).
    """

    floor_z: float
    lo: np.ndarray
    hi: np.ndarray


@dataclass(frozen=True)
class Container:
    """A drawer the object may be put in.

    Attributes:
        part: the drawer.
        interior: its interior support and volume.
        stored: the objects standing on its floor in the scene (taken out of the scene, with
            what stands on them, when the drawer is chosen); empty for an empty drawer.
    """

    part: Part
    interior: Interior
    stored: tuple[str, ...] = ()


def _interior(part: Part, assets_root: str | Path) -> Interior | None:
    """The interior support and volume carried by the part's link, or None (a door's link
    carries none: the case behind it does not move)."""
    from factory.assets.cache import cached

    assert part.obj.asset is not None
    meta = cached(Path(assets_root), part.obj.asset.asset_id)
    if meta is None:
        return None
    s = np.array(part.scale, float)
    sup = [x for x in meta.supports if x.get("link") == part.joint.link]
    vol = [x for x in meta.containers if x.get("link") == part.joint.link]
    if not sup or not vol:
        return None
    return Interior(
        float(sup[0]["z"]) * s[2], np.array(vol[0]["lo"], float) * s, np.array(vol[0]["hi"]) * s
    )


def container_top(obj: SceneObject, assets_root: str | Path) -> tuple[float, np.ndarray] | None:
    """The container's top surface: its height (m, object frame, scaled) and rectangle
    ``[x0, y0, x1, y1]`` (m, object frame, scaled), or None."""
    from factory.assets.cache import cached

    assert obj.asset is not None
    meta = cached(Path(assets_root), obj.asset.asset_id)
    if meta is None:
        return None
    tops = [x for x in meta.supports if x.get("name") == "case_top"]
    if not tops:
        return None
    sc = obj.asset.scale
    rect = np.array(tops[0]["rect"], float) * np.array([sc.x, sc.y, sc.x, sc.y])
    return float(tops[0]["z"]) * sc.z, rect


def pick_object(scene: Scene) -> SceneObject:
    """The object to put away: the scene's ``task_role`` ``pick`` object, else the first
    movable object of :data:`PICK_CATEGORIES`.

    Raises:
        TaskError: none (lists the categories looked for).
    """
    for o in scene.objects:
        if o.task_role == "pick" and not o.is_static:
            return o
    for cat in PICK_CATEGORIES:
        for o in scene.objects:
            if o.category == cat and not o.is_static:
                return o
    raise TaskError(
        f"scene {scene.id!r}: no object to put away (task_role 'pick', or one of "
        f"{', '.join(PICK_CATEGORIES)})"
    )


def _stored_on(scene: Scene, link_part: Part, interior: Interior, pick: str) -> list[str]:
    """Objects but ``pick`` standing on the part's interior support (by height, in the
    scene's closed pose)."""
    obj = link_part.obj
    out = []
    for o in scene.objects:
        if o.placement.support_id != obj.id or o.id == pick:
            continue
        if abs((o.position.z - obj.position.z) - interior.floor_z) < 0.02:
            out.append(o.id)
    return out


def container_parts(
    scene: Scene, assets_root: str | Path, pick: SceneObject, why: Counter[str]
) -> list[Container]:
    """The drawers the object can be put in: parts whose link carries an interior support
    and volume, whose object has a top to stand the object on, with room for the object (its
    height + :data:`MARGIN` under the volume's top, its footprint + 2 :data:`MARGIN`
    across); in scene order the empty ones, then those with something stored on their floor
    (:attr:`Container.stored`), then the low ones (:data:`LOW_DROP`) in the same order. A
    scene made for the task (``task.kind`` ``place_inside``) whose instruction names parts
    (role word and category, as :func:`~factory.tasks.articulated.parts.names_part` reads
    them: "put the mug in the drawer of the base cabinet") offers only those. Counted into
    ``why``: ``not_named``, ``no_interior`` and ``too_small`` (refused), ``occupied`` and
    ``low`` (offered later)."""
    ranked: list[tuple[bool, bool, Container]] = []
    d = pick.dimensions
    foot = max(d.width, d.length)
    parts = scene_parts(scene, assets_root)
    task = scene.task
    if task is not None and task.kind == "place_inside" and task.instruction:
        named = [p for p in parts if names_part(str(task.instruction), p)]
        why["not_named"] += len(parts) - len(named)
        parts = named or parts
    for part in parts:
        inner = _interior(part, assets_root)
        if inner is None or container_top(part.obj, assets_root) is None:
            why["no_interior"] += 1
            continue
        size = inner.hi - inner.lo
        if size[2] < d.height + MARGIN or min(size[0], size[1]) < foot + 2 * MARGIN:
            why["too_small"] += 1
            continue
        stored = _stored_on(scene, part, inner, pick.id)
        top = container_top(part.obj, assets_root)
        low = top is not None and top[0] - inner.floor_z > LOW_DROP
        if stored:
            why["occupied"] += 1
        if low:
            why["low"] += 1
        ranked.append((low, bool(stored), Container(part, inner, tuple(stored))))
    ranked.sort(key=lambda r: (r[0], r[1]))  # stable: scene order within a rank
    return [r[2] for r in ranked]


def without(scene: Scene, ids: tuple[str, ...]) -> Scene:
    """``scene`` without the objects ``ids`` and what stands on them."""
    if not ids:
        return scene
    gone = scene.with_dependents(set(ids))
    return replace(scene, objects=[o for o in scene.objects if o.id not in gone])


def on_top(scene: Scene, container: SceneObject, top_z: float, pick: SceneObject) -> Scene:
    """``scene`` with ``pick`` standing upright on the container's top (its centre, its yaw
    kept; an object the generated scene left lying on its side, fallen off its support, is
    stood up) and everything else on the top taken out (with what stands on it)."""
    on = {
        o.id
        for o in scene.objects
        if o.placement.support_id == container.id
        and o.id != pick.id
        and o.position.z - container.position.z >= top_z - 1e-3
    }
    gone = scene.with_dependents(on) if on else set()
    gone.discard(pick.id)
    moved = replace(
        pick,
        position=replace(
            pick.position,
            x=container.position.x,
            y=container.position.y,
            z=container.position.z + top_z,
        ),
        rotation=replace(pick.rotation, x=0.0, y=0.0),  # upright (it may have toppled)
        placement=replace(pick.placement, kind="on_top", support_id=container.id),
    )
    objects = [moved if o.id == pick.id else o for o in scene.objects if o.id not in gone]
    return replace(scene, objects=objects)
