"""Which container part and which object a ``place_inside`` scene's episodes use.

A container part is a part (:func:`~factory.tasks.articulated.parts.scene_parts`) of an object
with a top (``case_top``) to stand the object on, with an interior support and volume behind
it (``meta.json``'s ``supports`` and ``containers``; docs/ASSETS.md, "Articulated
categories"), big enough for the object:

* a **drawer**: its moving link carries the interior (``link``: the drawer's floor and tray);
* a **door**: the interior is the fixed case behind it (supports and volume with ``access``
  the door's joint and no ``link``: a microwave's cavity floor, a fridge's or a cabinet's
  shelves and floor). One level (floor or shelf) per door is offered: the empty one, then the
  one nearest the height the arm reaches best (:func:`door_level`); the level's interior is
  its support's rectangle up to the next level (its ``clearance``).

Drawers come first, then doors (a scene made for pick-and-place keeps its drawer); within each,
the empty ones first; one with something stored on its floor or shelf (a plate in a kitchen
drawer, a bowl in a microwave) comes after them, what is stored there taken out of the scene
when it is chosen (:attr:`Container.stored`); *low* ones last (:data:`LOW_DROP`,
:data:`LOW_REACH`). A scene made for the task whose instruction names a container ("put the
mug in the microwave") offers only the named object's parts: where none of them works, the
scene is unusable with a reason per part (:attr:`Container.refusal`). The object is the
scene's ``task_role`` ``pick`` object, else the first movable object of
:data:`PICK_CATEGORIES`.
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
    "LOW_REACH",
    "MARGIN",
    "PICK_CATEGORIES",
    "Container",
    "Interior",
    "container_parts",
    "container_top",
    "door_level",
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
LOW_REACH = 0.30
"""A door's level whose support lies more than this (m) below the robot's base (the closed
handle's height minus :data:`~factory.tasks.articulated.plan.BASE_BELOW`) is *low*: offered
after the others (a kitchen base cabinet's floor, 2 cm above the ground, under a base 0.37 m
high)."""
LEVEL_BELOW_BASE = 0.0
"""The height (m) below the robot's base that :func:`door_level` prefers for a door's level:
an object standing there is held with the tool level or a little below it."""


@dataclass(frozen=True)
class Interior:
    """The interior behind a part: the support the object is put on and the volume over it.

    Attributes:
        floor_z: the support's height (m, object frame, scaled).
        lo, hi: the interior volume's corners (3,) (m, object frame in the closed pose, which is
            the link's frame for a drawer; scaled).
        carried: the part's link carries the interior (a drawer: it moves with the part, the
            success check reads it in the link's frame); False for a door's (the fixed case:
            the object's root frame).
        support: the support's name in ``meta.json`` (``drawer_floor``, ``shelf_1``).
    """

    floor_z: float
    lo: np.ndarray
    hi: np.ndarray
    carried: bool = True
    support: str = ""


@dataclass(frozen=True)
class Container:
    """A drawer, or the interior behind a door, the object may be put in.

    Attributes:
        part: the drawer or door.
        interior: the interior support and volume.
        stored: the objects standing on that support in the scene (taken out of the scene,
            with what stands on them, when the container is chosen); empty when it is empty.
    """

    part: Part
    interior: Interior
    stored: tuple[str, ...] = ()

    @property
    def behind_door(self) -> bool:
        """The interior is the fixed case behind a door (not carried by the part)."""
        return not self.interior.carried


def _interiors(part: Part, assets_root: str | Path) -> list[Interior]:
    """The interiors behind the part: the support and volume its link carries (a drawer), else
    every level (floor, shelves) of the fixed case reached through its joint (a door:
    supports with ``access`` the joint and no ``link``), bottom first; empty when none."""
    from factory.assets.cache import cached

    assert part.obj.asset is not None
    meta = cached(Path(assets_root), part.obj.asset.asset_id)
    if meta is None:
        return []
    s = np.array(part.scale, float)
    sup = [x for x in meta.supports if x.get("link") == part.joint.link]
    vol = [x for x in meta.containers if x.get("link") == part.joint.link]
    if sup and vol:
        return [
            Interior(
                float(sup[0]["z"]) * s[2],
                np.array(vol[0]["lo"], float) * s,
                np.array(vol[0]["hi"], float) * s,
                True,
                str(sup[0].get("name", "")),
            )
        ]
    out = []
    for x in meta.supports:
        if x.get("link") or x.get("access") != part.joint.name:
            continue
        z = float(x["z"])
        x0, y0, x1, y1 = (float(v) for v in x["rect"])
        clear = float(x.get("clearance", 0.0))
        lo = np.array([x0, y0, z]) * s
        hi = np.array([x1, y1, z + clear]) * s
        out.append(Interior(z * s[2], lo, hi, False, str(x.get("name", ""))))
    return sorted(out, key=lambda i: i.floor_z)


def base_height(part: Part) -> float:
    """The robot's base height (m, world frame) in front of the part: its closed handle's
    height minus :data:`~factory.tasks.articulated.plan.BASE_BELOW` (as the articulated
    set-up places it)."""
    from factory.tasks.articulated.plan import BASE_BELOW

    center, _, _ = part.handle_in_link()
    return max(0.0, part.obj.position.z + float(center[2]) - BASE_BELOW)


def door_level(part: Part, levels: list[Interior]) -> list[Interior]:
    """A door's levels ordered by how well the arm reaches them: by the distance of the
    support's height from :data:`LEVEL_BELOW_BASE` under the robot's base
    (:func:`base_height`)."""
    want = base_height(part) - part.obj.position.z - LEVEL_BELOW_BASE
    return sorted(levels, key=lambda i: abs(i.floor_z - want))


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


def _too_small(inner: Interior, pick: SceneObject) -> str:
    """Why the interior cannot take the object (``""``: it can): its volume lower than the
    object + :data:`MARGIN` or narrower than its footprint + 2 :data:`MARGIN`."""
    d = pick.dimensions
    foot = max(d.width, d.length)
    size = inner.hi - inner.lo
    if size[2] >= d.height + MARGIN and min(size[0], size[1]) >= foot + 2 * MARGIN:
        return ""
    return (
        f"too_small: its {inner.support or 'interior'} is {size[0]:.2f} x {size[1]:.2f} m, "
        f"{size[2]:.2f} m high; {pick.id!r} needs {foot + 2 * MARGIN:.2f} m across and "
        f"{d.height + MARGIN:.2f} m high"
    )


def named_parts(text: str, parts: list[Part]) -> list[Part]:
    """The parts a ``place_inside`` instruction names: as
    :func:`~factory.tasks.articulated.parts.names_part` reads a part ("put the mug in the
    drawer of the base cabinet"), and, where the instruction says no role word but names an
    object with a door interior ("put the mug in the microwave", "put the cup in the cabinet":
    :func:`factory.scenes.part_read.read_part_task`), that object's doors."""
    from factory.scenes.part_read import read_part_task

    spec = read_part_task(text)
    role = spec.role if spec is not None and spec.item_named else None
    return [p for p in parts if names_part(text, p, role)]


def container_parts(
    scene: Scene,
    assets_root: str | Path,
    pick: SceneObject,
    why: Counter[str],
    refusals: list[str] | None = None,
) -> list[Container]:
    """The containers the object can be put in (module docstring): drawers whose link carries
    an interior, the interiors behind doors (one level each, :func:`door_level`), of objects
    with a top to stand the object on, with room for the object (its height + :data:`MARGIN`
    under the level above, its footprint + 2 :data:`MARGIN` across); ranked: not low before
    low (:data:`LOW_DROP` for a drawer, :data:`LOW_REACH` for a door), drawers before doors,
    empty before occupied, then scene order. A scene made for the task (``task.kind``
    ``place_inside``) whose instruction names parts (:func:`named_parts`) offers only those.
    Counted into ``why``: ``not_named``, ``no_interior`` and ``too_small`` (refused),
    ``occupied`` and ``low`` (offered later); each refusal of a named part is added to
    ``refusals`` with the part and the sizes."""
    ranked: list[tuple[bool, bool, bool, Container]] = []
    parts = scene_parts(scene, assets_root)
    task = scene.task
    named_only = False
    if task is not None and task.kind == "place_inside" and task.instruction:
        named = named_parts(str(task.instruction), parts)
        why["not_named"] += len(parts) - len(named)
        named_only = bool(named)
        parts = named or parts
    for part in parts:
        levels = _interiors(part, assets_root)
        top = container_top(part.obj, assets_root)
        if not levels or top is None:
            why["no_interior"] += 1
            if named_only and refusals is not None:
                refusals.append(f"{part.key} ({part.label}): no interior support behind it")
            continue
        door = not levels[0].carried
        if door:
            levels = door_level(part, levels)
        fits = [i for i in levels if not _too_small(i, pick)]
        if not fits:
            why["too_small"] += 1
            if refusals is not None:
                refusals.append(f"{part.key} ({part.label}): {_too_small(levels[0], pick)}")
            continue
        scored = [(i, _stored_on(scene, part, i, pick.id)) for i in fits]
        inner, stored = min(scored, key=lambda t: bool(t[1]))  # an empty level first
        if door:
            low = inner.floor_z + part.obj.position.z < base_height(part) - LOW_REACH
        else:
            low = top[0] - inner.floor_z > LOW_DROP
        if stored:
            why["occupied"] += 1
        if low:
            why["low"] += 1
        ranked.append((low, door, bool(stored), Container(part, inner, tuple(stored))))
    ranked.sort(key=lambda r: (r[0], r[1], r[2]))  # stable: scene order within a rank
    return [r[3] for r in ranked]


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
