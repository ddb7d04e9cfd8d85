"""Per-room generation of a multi-room home, the rooms in parallel worker processes.

The rooms of a home share walls and nothing else: furniture stays inside its room's interior,
and the physics critic's neighbourhood of a placement (:mod:`factory.sim.local_critic`) ends
at the walls. So each room is furnished by the heuristic brain (:class:`~.brain.Brain`) in a
session of its own, a one-room scene with the room's objects and random streams drawn from
``(seed, room index)``, in two phases:

1. ``furnish``: floor and wall furniture, then one simulation of the room that drops unstable
   pieces;
2. between the phases, on the whole home: the task's objects on the largest table;
3. ``fill``: small objects on the room's surfaces (the physics critic judging each), the
   visual critic's suggestions for the room, and the room's fillers.

After each phase the rooms' objects are merged in room order; an id a room chose that another
room already holds is renamed to the next free ``<category>_<n>`` (supports and keys follow).
The result depends on the seed only: the same rooms, streams and merge order whether the rooms
run in this process or in ``workers`` ``spawn``ed processes.
"""

from __future__ import annotations

import logging
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from factory.assets import AssetLibrary
from factory.cores import usable_cores
from factory.scenes.brain_steps import AgentConfig, Brain, BrainState, Trace, brief, task_kind
from factory.scenes.placement import SceneState
from factory.scenes.request import style_of
from factory.scenes.tools import ToolSession
from factory.schema import AssetMeta, Scene, SceneObject, Task, check_id

log = logging.getLogger(__name__)

PHASES: tuple[str, ...] = ("furnish", "fill")


@dataclass
class RoomWork:
    """One room of a home between phases (sent to a worker and back).

    Attributes:
        index: the room's position in the home.
        scene: a one-room scene: the room and its objects.
        metas: asset metadata of the room's objects, by object id.
        brain: the brain's state for this room.
        place_rng: the placement sampler's random stream for this room.
        calls: the room's tool calls so far (the trace).
        seconds: time spent in the phases so far (s).
    """

    index: int
    scene: Scene
    metas: dict[str, AssetMeta]
    brain: BrainState
    place_rng: np.random.Generator
    calls: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0


@dataclass(frozen=True)
class RoomSettings:
    """What every room's session shares."""

    library: AssetLibrary
    cfg: AgentConfig
    critic_chunk: int


def run_phase(phase: str, work: RoomWork, settings: RoomSettings) -> RoomWork:
    """Runs one phase of the brain on one room (here or in a worker process).

    Raises:
        ValueError: an unknown phase.
    """
    if phase not in PHASES:
        raise ValueError(f"phase {phase!r} must be one of {PHASES}")
    t0 = time.perf_counter()
    session = ToolSession(
        settings.library,
        physics=settings.cfg.physics_critic,
        critic_scope=settings.cfg.critic_scope,
        critic_chunk=settings.critic_chunk,
    )
    state = SceneState(work.scene, settings.library)
    state.rng = work.place_rng
    state.metas = dict(work.metas)
    session.state = state
    calls = list(work.calls)

    def call(name: str, **args: Any) -> dict[str, Any]:
        result = getattr(session, name)(**args)
        calls.append({"tool": name, "args": args, "result": brief(result), "room": work.index})
        return result

    brain = Brain(call, settings.cfg, work.brain)
    if phase == "furnish":
        room = work.scene.rooms[0]
        brain.furnish([{"id": room.id, "room_type": room.room_type}])
        brain.drop_unstable()
    else:
        brain.small_objects()
        brain.fill()
        brain.stored_objects()
    return RoomWork(
        work.index,
        state.scene,
        state.metas,
        brain.state,
        state.rng,
        calls,
        work.seconds + time.perf_counter() - t0,
    )


def _room_scene(home: Scene, k: int) -> Scene:
    room = home.rooms[k]
    return replace(
        home, rooms=[room], objects=[o for o in home.objects if o.room_id == room.id], task=None
    )


def _next_free(category: str, taken: set[str]) -> str:
    n = 0
    while f"{category}_{n}" in taken:
        n += 1
    return f"{category}_{n}"


def merge_rooms(works: list[RoomWork], before: list[set[str]]) -> list[SceneObject]:
    """The rooms' objects in room order, with unique ids.

    Args:
        works: the rooms after a phase (changed in place).
        before: per room, the ids its objects had before the phase (unique in the home).

    An object new in this phase whose id is taken (by an object from before anywhere in the
    home, or by an earlier room's new one) gets the next free ``<category>_<n>``; its room's
    supports, keys and metas follow.
    """
    taken = set().union(*before) if before else set()
    out: list[SceneObject] = []
    for work, old in zip(works, before, strict=True):
        rename: dict[str, str] = {}
        for o in work.scene.objects:
            if o.id in old:
                continue
            if o.id in taken:
                rename[o.id] = check_id(_next_free(o.category, taken), "object id")
            taken.add(rename.get(o.id, o.id))
        for o in work.scene.objects:
            if o.id not in old:
                o.id = rename.get(o.id, o.id)
            sup = o.placement.support_id
            if sup in rename and sup not in old:
                o.placement.support_id = rename[sup]
        work.metas = {rename.get(k, k) if k not in old else k: v for k, v in work.metas.items()}
        work.brain.keyed = {
            key: [i if i in old else rename.get(i, i) for i in ids]
            for key, ids in work.brain.keyed.items()
        }
        out += work.scene.objects
    return out


def default_workers(rooms: int) -> int:
    """Worker processes for a home of ``rooms`` rooms: one per room up to the CPU cores (the
    rooms run here, one after the other, with one core or inside a daemonic process, which may
    not start processes)."""
    if multiprocessing.current_process().daemon:
        return 1
    return max(1, min(rooms, usable_cores()))


class _Rooms:
    """Runs a phase over all rooms: here, or in a pool of ``spawn``ed workers."""

    def __init__(self, settings: RoomSettings, workers: int) -> None:
        self.settings = settings
        self.pool: ProcessPoolExecutor | None = None
        if workers > 1:
            ctx = multiprocessing.get_context("spawn")
            self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)

    def run(self, phase: str, works: list[RoomWork]) -> list[RoomWork]:
        if self.pool is None:
            return [run_phase(phase, w, self.settings) for w in works]
        futures = [self.pool.submit(run_phase, phase, w, self.settings) for w in works]
        return [f.result() for f in futures]

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(cancel_futures=True)


def generate_home(
    request: str,
    library: AssetLibrary,
    seed: int,
    cfg: AgentConfig,
    task: str | None = None,
    session: ToolSession | None = None,
    workers: int | None = None,
) -> tuple[Scene, dict[str, Any]]:
    """Generates a multi-room home room by room (see the module's description).

    Args:
        request: the request (it names a home or several rooms).
        library: the asset library.
        seed: the random seed; the scene depends on it only, not on ``workers``.
        cfg: the agent's knobs (``max_objects`` per room).
        task: a robot task whose objects go on the largest table.
        session: the tool session that holds the result (a new one by default).
        workers: processes for the rooms (default :func:`default_workers`; 1: here).

    Returns:
        the scene and the report (trace of tool calls with their room, per-room seconds).
    """
    t0 = time.perf_counter()
    session = session or ToolSession(
        library, physics=cfg.physics_critic, critic_scope=cfg.critic_scope
    )
    trace = Trace()

    def call(name: str, **args: Any) -> dict[str, Any]:
        result = getattr(session, name)(**args)
        trace.calls.append({"tool": name, "args": args, "result": brief(result)})
        return result

    first = call("init_scene", request=request, seed=seed)
    if not first.get("ok"):
        raise ValueError(first.get("error", "init_scene failed"))
    home = session.scene
    n = len(home.rooms)
    workers = default_workers(n) if workers is None else max(1, min(workers, n))
    if multiprocessing.current_process().daemon:
        workers = 1  # a daemonic process may not start processes
    chunk = max(1, usable_cores() // workers)
    style = style_of(request)
    works = [
        RoomWork(
            k,
            _room_scene(home, k),
            {},
            BrainState(np.random.default_rng([seed, k, 7919]), style, cfg.max_objects),
            np.random.default_rng([seed, k]),
        )
        for k in range(n)
    ]
    rooms = _Rooms(RoomSettings(library, cfg, chunk), workers)
    try:
        works = rooms.run("furnish", works)
        home.objects = merge_rooms(works, [set() for _ in works])
        state = SceneState(home, library, seed)
        state.metas = {k: v for w in works for k, v in w.metas.items()}
        session.state = state
        home_rng = np.random.default_rng([seed, n, 7919])
        brain = Brain(call, cfg, BrainState(home_rng, style, n * cfg.max_objects))
        spec = brain.task_objects(request, task)
        for k, w in enumerate(works):  # the task objects join their table's room
            w.scene = _room_scene(home, k)
            w.metas = {o.id: state.metas[o.id] for o in w.scene.objects if o.id in state.metas}
            w.brain.n_objects = len(w.scene.objects)
        before = [{o.id for o in w.scene.objects} for w in works]
        works = rooms.run("fill", works)
        home.objects = merge_rooms(works, before)
        state.metas = {k: v for w in works for k, v in w.metas.items()}
    finally:
        rooms.close()
    brain.keep_route()  # the rooms' fillers may have closed the way between the supports
    if spec is not None:
        home.task = Task(kind=task_kind(spec.__dict__), instruction=spec.instruction)
    calls = trace.calls[:1] + [c for w in works for c in w.calls] + trace.calls[1:]
    report = {
        "agent": "heuristic",
        "request": request,
        "seed": seed,
        "objects": len(home.objects),
        "tool_calls": len(calls),
        "seconds": round(time.perf_counter() - t0, 2),
        "rooms": [
            {
                "id": w.scene.rooms[0].id,
                "objects": len(w.scene.objects),
                "seconds": round(w.seconds, 2),
            }
            for w in works
        ],
        "workers": workers,
        "trace": calls,
    }
    return home, report


__all__ = ["RoomWork", "default_workers", "generate_home", "merge_rooms", "run_phase"]
