"""The offline heuristic brain of the scene agent and :func:`generate_scene`.

The agent follows the paper's loop with the generator tools of :mod:`.placement`: build the
room (:func:`~.floorplan.init_scene`), place floor and wall furniture (depth-first over grid
candidates), simulate once and drop unstable pieces, then place the small objects on every
support surface with the physics critic judging each placement, then make sure the task objects
exist and are reachable. Every tool call and its result go into the trace saved in
``report.json``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.assets import AssetLibrary
from factory.scenes.request import parse_request, parse_task, style_of
from factory.scenes.rooms import ROOM_TYPES, Item
from factory.schema import Scene, Task, check_id

log = logging.getLogger(__name__)


@dataclass
class AgentConfig:
    """Knobs of the heuristic agent."""

    physics_critic: bool = True
    max_objects: int = 120
    """Per room."""
    critic_batch: int = 4
    task_objects: bool = True
    """Place the task's objects read from the request (off when they already exist)."""
    extra_fill: int = 6


@dataclass
class Trace:
    """Tool calls and their results."""

    calls: list[dict[str, Any]] = field(default_factory=list)


Caller = Callable[..., dict[str, Any]]


def _count(item: Item, rng: np.random.Generator) -> int:
    if item.p < 1.0 and rng.uniform() > item.p:
        return 0
    return int(rng.integers(item.count[0], item.count[1] + 1))


def heuristic_agent(
    call: Caller, request: str, seed: int, cfg: AgentConfig, task: str | None = None
) -> dict[str, Any]:
    """The offline brain: a deterministic sequence of tool calls driven by room knowledge
    and the tools' results (what got placed, what the critics say).

    Args:
        call: ``call(tool_name, **arguments) -> result dict`` (a ToolSession, or MCP).
    """
    rng = np.random.default_rng(seed + 7919)
    first = call("init_scene", request=request, seed=seed)
    if not first.get("ok"):
        raise ValueError(first.get("error", "init_scene failed"))
    style = style_of(request)
    keyed: dict[str, list[str]] = {}
    n_objects = 0

    def styled(text: str) -> str:
        return f"{style} {text}" if style else text

    def place(**args: Any) -> dict[str, Any]:
        nonlocal n_objects
        res = call("place_objects", **args)
        n_objects = int(res.get("objects", n_objects))
        return res

    # 1. floor and wall furniture, room by room
    small: list[tuple[Item, int, str]] = []
    rooms = first.get("rooms") or [{"id": first["room_id"], "room_type": first["room_type"]}]
    budget = cfg.max_objects * len(rooms)
    fillers_by_room: dict[str, tuple[str, ...]] = {}
    for room in rooms:
        rt = ROOM_TYPES[room["room_type"]]
        fillers_by_room[room["id"]] = rt.fillers
        for item in rt.items:
            n = _count(item, rng)
            key = f"{room['id']}:{item.key}" if item.key else ""
            if item.rule.startswith("on:"):
                small.append((item, n, f"{room['id']}:{item.rule.split(':', 1)[1]}"))
                continue
            rule, _, ref = item.rule.partition(":")
            for _ in range(n):
                targets = keyed.get(f"{room['id']}:{ref}", [])
                if rule in ("near", "around") and not targets:
                    break
                if rule == "mount":
                    res = place(
                        text=styled(item.text),
                        placement="wall",
                        height=item.height,
                        room_id=room["id"],
                    )
                else:
                    res = place(
                        text=styled(item.text),
                        placement="floor",
                        rule=rule,
                        target=targets[0] if targets else None,
                        room_id=room["id"],
                    )
                if res.get("ok") and key:
                    keyed.setdefault(key, []).extend(res["placed"])
    # 2. simulate once; drop unstable floor furniture (the paper's shortcut)
    physics = call("physics_critic")
    for oid in physics.get("unstable", []):
        call("remove_object", object_id=oid)
    alive = {o["id"] for o in call("get_scene_info").get("objects", [])}
    keyed = {k: [i for i in v if i in alive] for k, v in keyed.items()}
    # 3. task objects first, on the largest table-like surface
    spec = None
    if cfg.task_objects:  # the request's own task is read from its English reading
        spec = parse_task(task) if task else parse_request(request).task
    if spec is not None:
        objects = call("get_scene_info")["objects"]
        tables = [o for o in objects if o["category"] in TABLES]
        if not tables:
            res = place(text="dining table", placement="floor", rule="center")
            tables = [{"id": res["placed"][0], "size": [1, 1, 1]}] if res.get("ok") else []
        if tables:
            table = max(tables, key=lambda o: o["size"][0] * o["size"][1])
            for text, role in ((spec.target, "place_target"), (spec.pick, "pick")):
                place(text=text, placement="on_top", target=table["id"], task_role=role)
    # 4. small objects on surfaces, multi-level, each judged by the physics critic
    for item, n, ref in small:
        supports = keyed.get(ref, [])
        for k in range(n):
            if not supports or n_objects >= budget:
                break
            place(text=styled(item.text), placement="on_top", target=supports[k % len(supports)])
    # 5. the visual critic's suggestions: companions and sparse areas
    for suggestion in call("visual_critic").get("suggestions", [])[: cfg.extra_fill]:
        args = dict(suggestion["call"]["args"])
        if suggestion["call"]["tool"] != "place_objects" or "text" not in args:
            continue
        if n_objects >= budget:
            break
        args["text"] = styled(args["text"])
        place(**args)
    fillers = list(rt.fillers) * 2
    rng.shuffle(fillers)
    for text in fillers[: cfg.extra_fill]:
        if n_objects >= budget:
            break
        place(
            text=styled(text), placement="floor", rule="corner" if rng.uniform() < 0.5 else "wall"
        )
    return {"task": None if spec is None else spec.__dict__}


TABLES = (
    "dining_table",
    "coffee_table",
    "desk",
    "kitchen_island",
    "side_table",
    "conference_table",
    "console_table",
    "kitchen_cabinet",
    "workbench",
)


def generate_scene(
    request: str,
    library: AssetLibrary,
    seed: int = 0,
    config: AgentConfig | None = None,
    task: str | None = None,
    scene_id: str | None = None,
    caller: Caller | None = None,
    session: Any = None,
) -> tuple[Scene, dict[str, Any]]:
    """Generates one furnished, physically checked scene for a text request.

    The heuristic brain drives the generator tools of a :class:`~.tools.ToolSession`, either
    directly or through ``caller`` (e.g. an MCP client, see :class:`SyncMCPCaller`; then pass
    the server's ``session`` to read the result).

    Returns:
        the scene and a report (``trace`` of tool calls, counts, timings).
    """
    from factory.scenes.tools import ToolSession

    cfg = config or AgentConfig()
    t0 = time.perf_counter()
    trace = Trace()
    if session is None:
        session = ToolSession(library, physics=cfg.physics_critic)
    direct = caller or (lambda name, **kw: getattr(session, name)(**kw))

    def call(name: str, **args: Any) -> dict[str, Any]:
        result = direct(name, **args)
        trace.calls.append({"tool": name, "args": args, "result": _brief(result)})
        return result

    info = heuristic_agent(call, request, seed, cfg, task)
    scene = session.scene
    if scene_id is not None:
        scene.id = check_id(scene_id, "scene id")
    if info["task"] is not None:
        scene.task = Task(kind="pick_place", instruction=info["task"]["instruction"])
    report = {
        "agent": "heuristic",
        "request": request,
        "seed": seed,
        "objects": len(scene.objects),
        "tool_calls": len(trace.calls),
        "seconds": round(time.perf_counter() - t0, 2),
        "trace": trace.calls,
    }
    return scene, report


def _brief(result: dict[str, Any]) -> dict[str, Any]:
    """A result short enough for the trace (object lists are summarised)."""
    if "objects" in result and isinstance(result["objects"], list):
        return {**result, "objects": len(result["objects"])}
    return result
