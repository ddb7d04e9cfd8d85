"""The three augmentation levels (paper: "Scaling the Scene for Embodied AI").

* :func:`configuration`: new poses for the task-relevant objects on their current supports.
* :func:`category`: a text variation of selected objects (same category; new size, colour,
  material or finish) built as a new asset and put back with the same support relation; floor
  and wall materials may change too.
* :func:`layout`: a new room (geometry and every task-irrelevant object, by the generation
  agent) with the task-relevant objects and their supports carried over: same assets, same
  relations (the mug stays on the nightstand).

Each takes a scene and returns a new one (or raises :class:`AugmentError` with the reason);
placements of small objects are judged by the physics critic.
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.assets import AssetLibrary
from factory.errors import FactoryError
from factory.scenes.placement import SceneState, place_floor, place_on, place_wall
from factory.schema import Scene, SceneObject

log = logging.getLogger(__name__)

SIZES = ("small", "large", "tall", "short", "wide", "slim")
COLOURS = (
    "red",
    "blue",
    "green",
    "yellow",
    "black",
    "white",
    "grey",
    "pink",
    "orange",
    "purple",
    "teal",
    "beige",
    "navy",
    "brown",
)
MATERIALS = (
    "ceramic",
    "porcelain",
    "glass",
    "plastic",
    "metal",
    "steel",
    "oak",
    "walnut",
    "pine",
    "fabric",
    "leather",
    "marble",
    "brass",
    "rubber",
)
FINISHES = ("matte", "glossy", "rustic", "modern", "retro", "minimalist")


class AugmentError(FactoryError):
    """A variant cannot be made (no task objects, no room for an object, ...)."""


@dataclass
class Variant:
    """A variant scene and what was done to make it."""

    scene: Scene
    params: dict[str, Any] = field(default_factory=dict)


def task_objects(scene: Scene, ids: list[str] | None = None) -> list[SceneObject]:
    """The task-relevant objects: the configured ids, else those with a ``task_role``."""
    if ids:
        return [scene.object(i) for i in ids]
    return [o for o in scene.objects if o.task_role]


def _state(scene: Scene, library: AssetLibrary, seed: int) -> SceneState:
    state = SceneState(scene, library, seed)
    for obj in scene.objects:
        if obj.asset is not None and obj.asset.asset_id:
            state.metas[obj.id], _ = state.meta_of(obj)
    return state


def _children(scene: Scene, oid: str) -> list[SceneObject]:
    return [o for o in scene.objects if o.placement.support_id == oid]


def configuration(
    scene: Scene, library: AssetLibrary, seed: int, critic: Any, ids: list[str] | None = None
) -> Variant:
    """Resamples the poses of the task objects on their current supports (first stable,
    collision-free candidate per object, judged by ``critic``)."""
    new = copy.deepcopy(scene)
    objs = task_objects(new, ids)
    if not objs:
        raise AugmentError(
            f"scene {scene.id!r} has no task-relevant objects for configuration-level "
            "augmentation: give objects a task_role or set augment.task_objects"
        )
    state = _state(new, library, seed)
    moved = {}
    for obj in objs:
        sup = obj.placement.support_id
        if obj.placement.kind != "on_top" or sup is None:
            raise AugmentError(f"task object {obj.id!r} is not on a support surface")
        if _children(new, obj.id):
            raise AugmentError(f"task object {obj.id!r} carries other objects; cannot move it")
        old = (obj.position.x, obj.position.y)
        meta_res = state.meta_of(obj)
        new.objects.remove(obj)
        state.reuse = meta_res
        res = place_on(state, obj.description or obj.category, sup, critic, task_role=obj.task_role)
        if not res.ok:
            raise AugmentError(f"no new stable pose for {obj.id!r} on {sup}: {res.reason}")
        placed = new.object(res.object_id)  # type: ignore[arg-type]
        placed.id = obj.id
        placed.description = obj.description
        state.metas[obj.id] = state.metas.pop(res.object_id, meta_res[0])  # type: ignore[arg-type]
        moved[obj.id] = {
            "from": [round(v, 3) for v in old],
            "to": [round(placed.position.x, 3), round(placed.position.y, 3)],
            "yaw_deg": round(placed.rotation.z, 1),
        }
    return Variant(new, {"level": "configuration", "moved": moved})


def variation_text(category: str, rng: np.random.Generator) -> str:
    """A text variation that keeps the category: "a tall matte black ceramic mug"."""
    words = []
    if rng.uniform() < 0.6:
        words.append(str(rng.choice(SIZES)))
    if rng.uniform() < 0.5:
        words.append(str(rng.choice(FINISHES)))
    words.append(str(rng.choice(COLOURS)))
    if rng.uniform() < 0.7:
        words.append(str(rng.choice(MATERIALS)))
    return " ".join([*words, category.replace("_", " ")])


def category(
    scene: Scene,
    library: AssetLibrary,
    seed: int,
    critic: Any,
    ids: list[str] | None = None,
    floors: bool = True,
) -> Variant:
    """New instances (text variations of the same category) of the selected objects, put back
    on the same support; optionally new floor and wall materials."""
    from factory.assets import resolve
    from factory.scenes.rooms import ROOM_TYPES

    rng = np.random.default_rng(seed)
    new = copy.deepcopy(scene)
    objs = task_objects(new, ids)
    if not objs:
        objs = [
            o for o in new.objects if o.placement.kind == "on_top" and not _children(new, o.id)
        ][:3]
    if not objs:
        raise AugmentError(f"scene {scene.id!r} has no objects to vary")
    state = _state(new, library, seed)
    changed = {}
    for obj in objs:
        if _children(new, obj.id):
            continue  # things stand on it: keep its geometry
        text = variation_text(obj.category, rng)
        res_text = resolve(text, seed=seed)
        if res_text.spec.category != obj.category:
            continue
        meta, res = library.from_text(text, seed=int(rng.integers(2**31)))
        new.objects.remove(obj)
        state.reuse = (meta, res)
        sup = obj.placement.support_id
        if obj.placement.kind == "on_top" and sup is not None:
            placed = place_on(state, text, sup, critic, task_role=obj.task_role)
        elif obj.placement.kind == "wall":
            placed = place_wall(state, text, obj.position.z, room_id=obj.room_id)
        else:
            placed = place_floor(state, text, "free", room_id=obj.room_id, task_role=obj.task_role)
        if not placed.ok:
            raise AugmentError(
                f"the variation {text!r} of {obj.id!r} does not fit: {placed.reason}"
            )
        p = new.object(placed.object_id)  # type: ignore[arg-type]
        p.id = obj.id
        p.description = text
        changed[obj.id] = {"text": text, "asset_id": meta.asset_id}
    materials = {}
    if floors:
        for room in new.rooms:
            rt = ROOM_TYPES.get(room.room_type)
            if rt is None:
                continue
            room.floor_material = str(rng.choice(rt.floors))
            wall = str(rng.choice(rt.walls))
            for w in room.walls:
                w.material = wall
            materials[room.id] = {"floor": room.floor_material, "walls": wall}
    return Variant(new, {"level": "category", "changed": changed, "materials": materials})


def layout(
    scene: Scene,
    library: AssetLibrary,
    seed: int,
    critic: Any,
    ids: list[str] | None = None,
    physics: bool = True,
) -> Variant:
    """A new room and background around the task objects and their supports (kept: same
    assets, same relations)."""
    from factory.scenes.brain import AgentConfig, generate_scene

    keep_objs = task_objects(scene, ids)
    if not keep_objs:
        raise AugmentError(f"scene {scene.id!r} has no task-relevant objects to keep")
    chain: list[SceneObject] = []
    for obj in keep_objs:  # the object and every support under it
        cur: SceneObject | None = obj
        while cur is not None and cur not in chain:
            chain.append(cur)
            sup = cur.placement.support_id
            cur = scene.object(sup) if cur.placement.kind == "on_top" and sup else None
    supports = [o for o in chain if o.placement.kind != "on_top"]
    on_top = [o for o in reversed(chain) if o.placement.kind == "on_top"]
    request = scene.description or scene.rooms[0].room_type
    base_state = _state(copy.deepcopy(scene), library, seed)
    from factory.scenes.tools import ToolSession

    session = ToolSession(library, physics=physics)
    first = session.init_scene(request, seed)
    if not first.get("ok"):
        raise AugmentError(f"layout: {first.get('error')}")
    state = session.state
    assert state is not None
    ids_map: dict[str, str] = {}
    for obj in supports:  # the kept furniture goes first, somewhere sensible
        for rule in ("wall", "free"):
            state.reuse = base_state.meta_of(obj)
            res = place_floor(state, obj.description or obj.category, rule)
            if res.ok:
                break
        else:
            raise AugmentError(f"layout: the kept {obj.id!r} fits nowhere in the new room")
        ids_map[obj.id] = res.object_id  # type: ignore[assignment]
    for obj in on_top:
        state.reuse = base_state.meta_of(obj)
        sup = ids_map.get(obj.placement.support_id or "", obj.placement.support_id)
        res = place_on(
            state, obj.description or obj.category, str(sup), critic, task_role=obj.task_role
        )
        if not res.ok:
            raise AugmentError(f"layout: no stable place for the kept {obj.id!r}: {res.reason}")
        ids_map[obj.id] = res.object_id  # type: ignore[assignment]
    for old, new_id in ids_map.items():  # kept objects keep their ids
        state.scene.object(new_id).id = old
        state.metas[old] = state.metas.pop(new_id)
    # the rest of the room, by the generation agent, around what is already there
    cfg = AgentConfig(physics_critic=physics, task_objects=False)
    generated, report = generate_scene(
        request, library, seed, cfg, session=session, caller=_skip_init(session)
    )
    generated.task = copy.deepcopy(scene.task)
    return Variant(
        generated, {"level": "layout", "kept": sorted(ids_map), "tool_calls": report["tool_calls"]}
    )


def _skip_init(session: Any) -> Any:
    """A caller that answers ``init_scene`` with the room already built (kept objects in)."""

    def call(name: str, **args: Any) -> dict[str, Any]:
        if name == "init_scene":
            scene = session.scene
            room = scene.rooms[0]
            return {
                "ok": True,
                "scene_id": scene.id,
                "room_id": room.id,
                "room_type": room.room_type,
                "rooms": [{"id": r.id, "room_type": r.room_type} for r in scene.rooms],
            }
        result: dict[str, Any] = getattr(session, name)(**args)
        return result

    return call
