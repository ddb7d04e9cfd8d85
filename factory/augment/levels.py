"""The three augmentation levels (paper: "Scaling the Scene for Embodied AI").

* :func:`configuration`: new poses for the task-relevant objects on their current supports.
* :func:`category`: a text variation of selected objects (same category; new size, colour,
  material or finish) built as a new asset and put back with the same support relation; floor
  and wall materials may change too.
* :func:`layout`: a new room (geometry and every task-irrelevant object, by the generation
  agent) with the task-relevant objects and their supports carried over: same assets, same
  relations (the mug stays on the nightstand). A mobile task's place support is put away
  from the pick's support, and the agent's last step keeps the route between them
  (``Brain.keep_route``); ``stage=augment`` drops a variant whose route check still fails.

Each takes a scene and returns a new one (or raises :class:`AugmentError` with the reason).
Objects put on supports are posed jointly, many candidate configurations per batched physics
call (:mod:`factory.augment.joint`); :func:`configurations` returns many distinct variants of
one scene from the same batched calls.
"""

from __future__ import annotations

import copy
import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.assets import AssetLibrary
from factory.augment.check import PhysicsCheck
from factory.augment.distinct import Distinctness
from factory.errors import FactoryError
from factory.scenes.placement import SceneState, place_floor, place_wall
from factory.schema import Euler, Placement, Scene, SceneObject, Vec3

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


def _state(
    scene: Scene, library: AssetLibrary, seed: int, only: set[str] | None = None
) -> SceneState:
    """A placement state over ``scene`` with the assets of its objects (or of ``only``)."""
    state = SceneState(scene, library, seed)
    for obj in scene.objects:
        if only is not None and obj.id not in only:
            continue
        if obj.asset is not None and obj.asset.asset_id:
            state.metas[obj.id], _ = state.meta_of(obj)
    return state


def _children(scene: Scene, oid: str) -> list[SceneObject]:
    return [o for o in scene.objects if o.placement.support_id == oid]


def _set_pose(obj: SceneObject, pose: np.ndarray) -> None:
    """Puts ``obj`` at ``[x, y, z, yaw_deg]`` (upright), the floats the batched check used."""
    x, y, z, yaw = (float(v) for v in pose)
    obj.position = Vec3(x, y, z)
    obj.rotation = Euler(0.0, 0.0, yaw)


def _current(scene: Scene, ids: list[str]) -> np.ndarray:
    """``(1, k, 4)`` the objects' present ``[x, y, z, yaw_deg]``."""
    return np.array(
        [[[*scene.object(i).position.as_tuple(), scene.object(i).rotation.z] for i in ids]]
    )


@dataclass
class ConfigurationBatch:
    """Configuration-level variants of one scene, kept as poses until asked for.

    Attributes:
        parent: the scene the variants are made from (not modified).
        ids: the re-posed task objects, ``k`` of them.
        poses: ``(m, k, 4)`` ``[x, y, z, yaw_deg]`` per variant (world frame).
        stats: what the joint placement did (draws, rows simulated, valid, timings) and the
            parent check, JSON-ready.
    """

    parent: Scene
    ids: list[str]
    poses: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.poses)

    def variant(self, i: int) -> Variant:
        """The ``i``-th variant as a scene (a copy of the parent with the task objects moved)."""
        new = copy.deepcopy(self.parent)
        moved = {}
        for j, oid in enumerate(self.ids):
            obj = new.object(oid)
            old = (obj.position.x, obj.position.y)
            _set_pose(obj, self.poses[i, j])
            moved[oid] = {
                "from": [round(v, 3) for v in old],
                "to": [round(obj.position.x, 3), round(obj.position.y, 3)],
                "yaw_deg": round(obj.rotation.z, 1),
            }
        return Variant(new, {"level": "configuration", "moved": moved})


def _movable_task_objects(scene: Scene, ids: list[str] | None) -> list[str]:
    """The task objects configuration variants re-pose: ``ids``, else those with a
    ``task_role`` except a mobile task's place support standing on the floor (the desk the
    object goes onto is furniture the task uses where it stands, as the pick's support is).

    Raises:
        AugmentError: none, or one is not on a support surface or carries other objects.
    """
    objs = task_objects(scene, ids)
    if not ids:
        objs = [o for o in objs if not (o.task_role == "place_support" and _on_floor(o))]
    if not objs:
        raise AugmentError(
            f"scene {scene.id!r} has no task-relevant objects for configuration-level "
            "augmentation: give objects a task_role or set augment.task_objects"
        )
    for obj in objs:
        if obj.placement.kind != "on_top" or obj.placement.support_id is None:
            raise AugmentError(f"task object {obj.id!r} is not on a support surface")
        if _children(scene, obj.id):
            raise AugmentError(f"task object {obj.id!r} carries other objects; cannot move it")
    return [o.id for o in objs]


def _on_floor(obj: SceneObject) -> bool:
    return obj.placement.kind != "on_top" or obj.placement.support_id is None


def configurations(
    scene: Scene,
    library: AssetLibrary,
    seed: int,
    count: int,
    check: PhysicsCheck | None,
    ids: list[str] | None = None,
    distinct: Distinctness | None = None,
    parent_check: bool = True,
) -> ConfigurationBatch:
    """Up to ``count`` distinct, valid configurations of the task objects on their supports.

    Thousands of joint poses are drawn at once, filtered by footprint, and judged in batched
    physics calls on the local scene of the task objects (:mod:`factory.augment.joint`).
    With ``parent_check``, the parent is first checked whole, once: an object outside the
    local scene that is unstable or colliding would fail every variant.

    Args:
        scene: the parent scene (not modified).
        library: the run's asset library.
        seed: the seed of every draw.
        count: variants wanted.
        check: physics settings; ``None``: footprint-free poses, not simulated.
        ids: the task objects (default: those with a ``task_role``).
        distinct: when two variants differ (each also differs from the parent).
        parent_check: check the parent whole first (see above).

    Raises:
        AugmentError: no task objects, a task object not on a support or carrying others,
            no room on the supports, or a parent that fails whatever moves.
    """
    from factory.augment.check import parent_verdict
    from factory.augment.joint import JointOptions, PlacementError, place_jointly
    from factory.augment.local import local_scene
    from factory.augment.sampling import SamplingError

    moving = _movable_task_objects(scene, ids)
    stats: dict[str, Any] = {}
    if check is not None and parent_check:
        verdict = parent_verdict(scene, check)
        dynamic = set(local_scene(scene, moving, check.context_margin).dynamic)
        blocking = verdict.blocking(dynamic)
        stats["parent_check_seconds"] = round(verdict.seconds, 3)
        if blocking:
            raise AugmentError(
                f"parent fails the whole-scene check whatever the task objects do: "
                f"{', '.join(blocking[:4])}"
            )
    supports = {scene.object(i).placement.support_id or "" for i in moving}
    state = _state(scene, library, seed, only=supports)
    options = JointOptions(count=count, distinct=distinct or Distinctness())
    try:
        placed = place_jointly(
            state, moving, check, np.random.default_rng(seed), options, _current(scene, moving)
        )
    except (PlacementError, SamplingError) as e:
        raise AugmentError(f"no room for the task objects: {e}") from None
    return ConfigurationBatch(scene, moving, placed.poses, {**stats, **placed.stats})


def configuration(
    scene: Scene,
    library: AssetLibrary,
    seed: int,
    check: PhysicsCheck | None,
    ids: list[str] | None = None,
) -> Variant:
    """New poses of the task objects on their current supports: the first distinct valid
    configuration of :func:`configurations` (no parent check: the caller checks the result)."""
    batch = configurations(scene, library, seed, 1, check, ids, parent_check=False)
    if not len(batch):
        why = ", ".join(f"{k} x{v}" for k, v in batch.stats.get("failures", {}).items())
        raise AugmentError(
            f"no new stable pose for {', '.join(batch.ids)}: "
            f"{batch.stats.get('checked', 0)} candidates failed ({why or 'none simulated'})"
        )
    return batch.variant(0)


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


def _place_jointly_once(
    state: SceneState, ids: list[str], check: PhysicsCheck | None, seed: int, what: str
) -> None:
    """Poses ``ids`` (already in ``state.scene``, each on its support) together: the first valid
    configuration of one batched check (:func:`factory.augment.joint.place_jointly`)."""
    from factory.augment.joint import JointOptions, PlacementError, place_jointly
    from factory.augment.sampling import SamplingError

    try:
        placed = place_jointly(state, ids, check, np.random.default_rng(seed), JointOptions())
    except (PlacementError, SamplingError) as e:
        raise AugmentError(f"{what}: no room on the supports: {e}") from None
    if not len(placed.poses):
        why = ", ".join(f"{k} x{v}" for k, v in placed.stats.get("failures", {}).items())
        raise AugmentError(
            f"{what}: no stable joint placement of {', '.join(ids)} "
            f"({placed.stats.get('checked', 0)} candidates: {why or 'none simulated'})"
        )
    for j, oid in enumerate(ids):
        _set_pose(state.scene.object(oid), placed.poses[0, j])


def category(
    scene: Scene,
    library: AssetLibrary,
    seed: int,
    check: PhysicsCheck | None,
    ids: list[str] | None = None,
    floors: bool = True,
) -> Variant:
    """New instances (text variations of the same category) of the selected objects, put back
    on the same support; optionally new floor and wall materials.

    Objects on a support are placed together: all their new instances go into the scene, then
    joint poses of all of them are judged in one batched check (floor and wall objects are
    placed first, by the floor and wall rules)."""
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
    joint: dict[str, str] = {}  # placeholder id -> original id, for the on-top ones
    for obj in objs:
        if _children(new, obj.id):
            continue  # things stand on it: keep its geometry
        text = variation_text(obj.category, rng)
        res_text = resolve(text, seed=seed)
        if res_text.spec.category != obj.category:
            continue
        meta, res = library.from_text(text, seed=int(rng.integers(2**31)))
        new.objects.remove(obj)
        sup = obj.placement.support_id
        if obj.placement.kind == "on_top" and sup is not None:
            room = state.room(obj.room_id)
            pos = obj.position.as_tuple()
            p = state.add(
                meta,
                res,
                room,
                pos,
                math.radians(obj.rotation.z),
                Placement("on_top", support_id=sup),
                task_role=obj.task_role,
            )
            joint[p.id] = obj.id
        else:
            state.reuse = (meta, res)
            if obj.placement.kind == "wall":
                placed = place_wall(state, text, obj.position.z, room_id=obj.room_id)
            else:
                placed = place_floor(
                    state, text, "free", room_id=obj.room_id, task_role=obj.task_role
                )
            if not placed.ok:
                raise AugmentError(
                    f"the variation {text!r} of {obj.id!r} does not fit: {placed.reason}"
                )
            p = new.object(placed.object_id)  # type: ignore[arg-type]
        p.description = text
        changed[obj.id] = {"text": text, "asset_id": meta.asset_id}
        if p.id not in joint:
            p.id = obj.id
    if joint:
        _place_jointly_once(
            state, list(joint), check, seed + 1, f"the variations of {', '.join(joint.values())}"
        )
        for tmp, oid in joint.items():
            new.object(tmp).id = oid
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
    check: PhysicsCheck | None,
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
    # a mobile task's place support goes last, away from the pick's support (about 2.5 m)
    supports.sort(key=lambda o: o.task_role == "place_support")
    pick_support = next((o.placement.support_id for o in keep_objs if o.task_role == "pick"), None)
    for obj in supports:  # the kept furniture goes first, somewhere sensible
        anchor = ids_map.get(pick_support or "")
        away = obj.task_role == "place_support" and anchor is not None
        for rule in ("facing", "away", "wall", "free") if away else ("wall", "free"):
            state.reuse = base_state.meta_of(obj)
            res = place_floor(
                state,
                obj.description or obj.category,
                rule,
                target=anchor if away else None,
                task_role=obj.task_role,
            )
            if res.ok:
                break
        else:
            raise AugmentError(f"layout: the kept {obj.id!r} fits nowhere in the new room")
        ids_map[obj.id] = res.object_id  # type: ignore[assignment]
    placed_on: set[str] = set()
    while len(placed_on) < len(on_top):  # kept objects on top, a support level at a time
        waiting = {o.id for o in on_top} - placed_on
        level = [o for o in on_top if o.id in waiting and o.placement.support_id not in waiting]
        if not level:
            raise AugmentError("layout: the kept objects' supports form a cycle")
        group = []
        for obj in level:
            meta, resolution = base_state.meta_of(obj)
            sup = ids_map.get(obj.placement.support_id or "", obj.placement.support_id)
            support = state.scene.object(str(sup))
            p = state.add(
                meta,
                resolution,
                state.room(support.room_id),
                (support.position.x, support.position.y, support.position.z),
                0.0,
                Placement("on_top", support_id=str(sup)),
                task_role=obj.task_role,
            )
            ids_map[obj.id] = p.id
            group.append(p.id)
            placed_on.add(obj.id)
        _place_jointly_once(
            state, group, check, seed + 1 + len(placed_on), "layout: the kept objects"
        )
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
