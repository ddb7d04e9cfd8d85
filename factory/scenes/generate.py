"""Scene generation with the offline heuristic agent, and ``stage=generate``.

The agent follows the paper's loop with the generator tools of :mod:`.placement`: build the
room (:func:`init_scene`), place floor and wall furniture (depth-first over grid candidates),
simulate once and drop unstable pieces, then place the small objects on every support surface
with the physics critic judging each placement, then make sure the task objects exist and
are reachable. Every tool call and its result go into the trace saved in ``report.json``.
"""

from __future__ import annotations

import hashlib
import itertools
import logging
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from factory.scenes.assets import AssetLibrary
from factory.scenes.rooms import ROOM_TYPES, Item, room_type_of
from factory.schema import Door, Room, Scene, Size3, Task, Vec3, Wall, Window, check_id

log = logging.getLogger(__name__)

STYLE_WORDS = (
    "mid-century",
    "cyberpunk",
    "fairy-tale",
    "princess",
    "scandinavian",
    "industrial",
    "rustic",
    "farmhouse",
    "modern",
    "minimalist",
    "victorian",
    "japanese",
    "boho",
    "art deco",
    "coastal",
    "gothic",
    "retro",
    "futuristic",
)


@dataclass
class TaskSpec:
    """A pick-and-place task read from text: what to pick and where to put it."""

    pick: str
    target: str
    relation: str = "in"
    instruction: str = ""


def parse_task(text: str) -> TaskSpec | None:
    """Reads "pick up the mug and put it in the bowl" style instructions."""
    m = re.search(
        r"(?:pick(?:s)?(?: up)?|grab(?:s)?|move(?:s)?|take(?:s)?)\s+(?:the|a|an)\s+([a-z ]+?)"
        r"\s+(?:and\s+(?:put|place|drop)s?\s+it\s+|from\s+the\s+[a-z ]+?\s+)?"
        r"(in|into|on|onto|to)\s+(?:the|a|an)\s+([a-z ]+)",
        text.lower(),
    )
    if not m:
        return None
    return TaskSpec(
        pick=m.group(1).strip(),
        target=m.group(3).strip().rstrip("."),
        relation=m.group(2),
        instruction=text,
    )


def _style(text: str) -> str:
    low = text.lower()
    return next((s for s in STYLE_WORDS if s in low), "")


NUMBERS = {"one": 1, "two": 2, "three": 3, "four": 4, "single": 1, "double": 2}

MULTI_ROOM_WORDS = ("apartment", "house", "flat", "condo", "townhouse")
_MULTI_RE = re.compile(r"\b(" + "|".join(MULTI_ROOM_WORDS) + r")\b")


def room_types_in(request: str) -> list[str]:
    """The room types a request asks for: several for an apartment or house, else one."""
    from factory.scenes.rooms import ROOM_TYPES as RT

    low = request.lower()
    found: list[tuple[int, str]] = []
    for name, rt in RT.items():
        if name == "studio":
            continue
        for phrase in (name, *rt.aliases):
            i = low.find(phrase)
            if i >= 0 and not any(n == name for _, n in found):
                found.append((i, name))
    mentioned = [n for _, n in sorted(found)]
    if _MULTI_RE.search(low):
        rooms = []
        for name in mentioned:  # "two bedrooms", "2-bedroom"
            m = re.search(rf"\b({'|'.join(NUMBERS)}|\d)[\s-]*{re.escape(name)}", low)
            n = (
                1
                if m is None
                else NUMBERS.get(m.group(1), int(m.group(1)) if m.group(1).isdigit() else 1)
            )
            rooms += [name] * max(1, min(n, 3))
        for extra in ("living room", "kitchen", "bathroom"):
            if extra not in rooms:
                rooms.append(extra)
        if "bedroom" not in rooms and "studio" not in low:
            rooms.insert(0, "bedroom")
        return rooms[:6]
    return [room_type_of(request)]


def _room(
    rid: str,
    rt_name: str,
    x0: float,
    width: float,
    length: float,
    height: float,
    rng: np.random.Generator,
) -> Room:
    rt = ROOM_TYPES[rt_name]
    pts = [(x0, 0.0), (x0 + width, 0.0), (x0 + width, length), (x0, length)]
    names = ["south", "east", "north", "west"]
    walls = [
        Wall(
            id=f"{rid}_{n}",
            start=Vec3(*pts[i], 0.0),
            end=Vec3(*pts[(i + 1) % 4], 0.0),
            height=height,
            material=str(rng.choice(rt.walls)),
        )
        for i, n in enumerate(names)
    ]
    north = walls[2]
    return Room(
        id=rid,
        room_type=rt_name,
        position=Vec3(x0, 0, 0),
        dimensions=Size3(width, length, height),
        walls=walls,
        windows=[
            Window(
                id=f"{rid}_window",
                wall_id=north.id,
                position_on_wall=0.5,
                width=min(1.4, 0.4 * north.length),
                height=1.2,
                sill_height=0.9,
            )
        ],
        floor_material=str(rng.choice(rt.floors)),
        ceiling_height=height,
    )


def init_scene(
    request: str, seed: int = 0, scene_id: str | None = None, room_type: str | None = None
) -> tuple[Scene, dict[str, Any]]:
    """Builds the empty floor plan for the request: one room, or several in a row joined by
    doors for an apartment or house; sizes, materials, walls, doors, windows.

    Raises:
        ValueError: a request too small to hold a room (e.g. "0.5 m wide").
    """
    rng = np.random.default_rng(seed)
    types = [room_type] if room_type else room_types_in(request)
    m = re.search(r"(\d+(?:\.\d+)?)\s*(?:m|meters?|metres?)\s*(?:wide|by)", request.lower())
    forced_width = float(m.group(1)) if m else None
    if forced_width is not None and forced_width < 1.5:
        raise ValueError(
            f"a room {forced_width} m wide cannot hold furniture: ask for at least 1.5 m"
        )
    height = 2.7
    sizes = []
    for t in types:
        (w0, w1), (l0, l1) = ROOM_TYPES[t].size
        sizes.append((forced_width or float(rng.uniform(w0, w1)), float(rng.uniform(l0, l1))))
    length = max(ln for _, ln in sizes) if len(types) > 1 else sizes[0][1]
    rooms: list[Room] = []
    x = 0.0
    used: dict[str, int] = {}
    for t, (width, _) in zip(types, sizes, strict=True):
        base = re.sub(r"[^a-z0-9]+", "_", t).strip("_") or "room"
        used[base] = used.get(base, 0) + 1
        rid = check_id(base if used[base] == 1 else f"{base}_{used[base]}", "room id")
        rooms.append(_room(rid, t, x, width, length, height, rng))
        x += width
    # doors: an entrance on the first room's south wall, and one in each shared wall
    first = rooms[0]
    first.doors.append(
        Door(
            id=f"{first.id}_entrance",
            wall_id=first.walls[0].id,
            position_on_wall=float(rng.uniform(0.3, 0.7)),
            width=0.9,
            height=2.1,
        )
    )
    for a, b in itertools.pairwise(rooms):
        p = float(rng.uniform(0.3, 0.7))
        a.doors.append(
            Door(
                id=f"{a.id}_to_{b.id}",
                wall_id=a.walls[1].id,
                position_on_wall=p,
                width=0.9,
                height=2.1,
                opening=True,
            )
        )
        b.doors.append(
            Door(
                id=f"{b.id}_to_{a.id}",
                wall_id=b.walls[3].id,
                position_on_wall=1.0 - p,
                width=0.9,
                height=2.1,
                opening=True,
            )
        )
    digest = hashlib.sha1(f"{request}|{seed}".encode()).hexdigest()[:8]
    sid = scene_id or f"{first.id}_{digest}"
    scene = Scene(
        id=sid,
        rooms=rooms,
        description=request,
        source="text",
        seed=seed,
        building_style=_style(request),
    )
    info: dict[str, Any] = {
        "room_type": first.room_type,
        "room_id": first.id,
        "rooms": [
            {
                "id": r.id,
                "room_type": r.room_type,
                "size_m": [round(r.dimensions.width, 2), round(r.dimensions.length, 2)],
            }
            for r in rooms
        ],
        "size_m": [round(first.dimensions.width, 2), round(first.dimensions.length, 2)],
        "floor": first.floor_material,
    }
    if room_type is None and not _names_a_room(request):
        info["approximated"] = True
        info["note"] = (
            f"no known room type in {request!r} (another language?); built a {first.room_type}"
        )
        log.warning("%s", info["note"])
    return scene, info


def _names_a_room(request: str) -> bool:
    low = request.lower()
    return bool(_MULTI_RE.search(low)) or any(
        phrase in low for name, rt in ROOM_TYPES.items() for phrase in (name, *rt.aliases)
    )


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
    style = _style(request)
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
    spec = parse_task(task or request) if cfg.task_objects else None
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


class SyncMCPCaller:
    """A synchronous ``call(name, **args)`` over an MCP client session.

    One ``mcp.Client`` connected to ``server`` (an ``MCPServer`` in-process,
    ``StdioServerParameters`` or an HTTP URL) lives in a task of an event loop on a background
    thread; calls are queued to it. Use as a context manager.
    """

    def __init__(self, server: Any) -> None:
        self.server = server

    def __enter__(self) -> SyncMCPCaller:
        import asyncio
        import concurrent.futures
        import threading

        self.loop = asyncio.new_event_loop()
        self.ready: concurrent.futures.Future[None] = concurrent.futures.Future()
        self.thread = threading.Thread(
            target=self.loop.run_until_complete, args=(self._serve(),), daemon=True
        )
        self.thread.start()
        self.ready.result(120)
        return self

    async def _serve(self) -> None:
        import asyncio

        from mcp import Client

        self.queue: asyncio.Queue[Any] = asyncio.Queue()
        try:
            async with Client(self.server) as client:
                self.ready.set_result(None)
                while True:
                    item = await self.queue.get()
                    if item is None:
                        break
                    name, args, fut = item
                    try:
                        fut.set_result(await client.call_tool(name, args))
                    except Exception as e:  # delivered to the caller's thread
                        fut.set_exception(e)
        except Exception as e:
            if not self.ready.done():
                self.ready.set_exception(e)
            raise

    def __call__(self, name: str, **args: Any) -> dict[str, Any]:
        import concurrent.futures
        import json as _json

        fut: concurrent.futures.Future[Any] = concurrent.futures.Future()
        self.loop.call_soon_threadsafe(self.queue.put_nowait, (name, args, fut))
        result = fut.result(600)
        text = result.content[0].text if result.content else "{}"
        if getattr(result, "is_error", False):
            return {"ok": False, "error": text}
        data: dict[str, Any] = _json.loads(text)
        return data

    def __exit__(self, *exc: object) -> None:
        self.loop.call_soon_threadsafe(self.queue.put_nowait, None)
        self.thread.join(30)


def _read_prompts(cfg: Any) -> list[str]:
    prompts = list(cfg.prompts or [])
    if cfg.prompts_file:
        path = Path(cfg.prompts_file)
        if not path.is_file():
            from factory.errors import ConfigError

            raise ConfigError(f"generate.prompts_file {path} does not exist")
        prompts += [
            ln.strip()
            for ln in path.read_text().splitlines()
            if ln.strip() and not ln.startswith("#")
        ]
    if cfg.task and not prompts:
        prompts = [cfg.task]
    if cfg.image:
        from factory.scenes.vlm import describe_image

        hint = " ".join(prompts)
        prompts = [describe_image(cfg.image, hint, base_url=cfg.vlm_base_url, model=cfg.vlm_model)]
        log.info("image %s described as: %s", cfg.image, prompts[0])
    return prompts


def _generate_with(
    gcfg: Any, prompt: str, library: AssetLibrary, seed: int, agent_cfg: AgentConfig, scene_id: str
) -> tuple[Scene, dict[str, Any]]:
    """One scene with the configured brain and transport."""
    from factory.scenes.tools import ToolSession

    session = ToolSession(library, physics=agent_cfg.physics_critic)
    if gcfg.agent == "llm":
        from factory.scenes.agent import AgentError, LLMConfig, run_llm_agent

        llm = LLMConfig(
            base_url=gcfg.llm_base_url,
            model=gcfg.llm_model,
            timeout=gcfg.llm_timeout,
            retries=gcfg.llm_retries,
        )
        try:
            report = run_llm_agent(session, prompt, llm, seed)
            scene = session.scene
            scene.id = check_id(scene_id, "scene id")
            return scene, {**report, "request": prompt, "seed": seed, "objects": len(scene.objects)}
        except AgentError as e:
            if not gcfg.llm_fallback:
                raise
            log.warning(
                "llm agent failed for %r (%s); falling back to the heuristic agent", prompt, e
            )
            scene, report = generate_scene(
                prompt, library, seed, agent_cfg, task=gcfg.task or None, scene_id=scene_id
            )
            return scene, {**report, "fallback_from": "llm", "llm_error": str(e)}
    import contextlib

    mcp_ctx: Any = contextlib.nullcontext(None)
    if gcfg.transport == "mcp":
        from factory.scenes.mcp_server import build_server

        mcp_ctx = SyncMCPCaller(build_server(session))
    with mcp_ctx as caller:
        scene, report = generate_scene(
            prompt,
            library,
            seed,
            agent_cfg,
            task=gcfg.task or None,
            scene_id=scene_id,
            caller=caller,
            session=session,
        )
    if gcfg.vlm_base_url:
        report["vlm_critic"] = _apply_vlm_critic(session, prompt, gcfg)
    return session.scene, report


def _apply_vlm_critic(session: Any, prompt: str, gcfg: Any, limit: int = 8) -> dict[str, Any]:
    """Renders the scene, asks the VLM critic, applies its tool-call suggestions once."""
    import tempfile

    from factory.scenes.agent import AgentError
    from factory.scenes.vlm import vlm_critic

    with tempfile.TemporaryDirectory() as tmp:
        session.out_dir = Path(tmp)
        try:
            views = session.render_views(256, 192)
            verdict = vlm_critic(
                views.get("images", {}), prompt, base_url=gcfg.vlm_base_url, model=gcfg.vlm_model
            )
        except AgentError as e:
            log.warning("VLM critic failed: %s", e)
            return {"error": str(e)}
        finally:
            session.out_dir = None
    applied = []
    for suggestion in verdict.get("suggestions", [])[:limit]:
        call = suggestion.get("call") or {}
        tool, args = call.get("tool"), call.get("args") or {}
        if tool in ("place_objects", "move_object", "remove_object") and isinstance(args, dict):
            try:
                result = getattr(session, tool)(**args)
            except TypeError as e:
                result = {"ok": False, "error": str(e)}
            applied.append({"tool": tool, "args": args, "result": result})
    return {"suggestions": verdict.get("suggestions", []), "applied": applied}


def run(ctx: Any) -> dict[str, Any]:
    """Stage entry point: ``stage=generate``."""
    from factory.errors import ConfigError
    from factory.runner import run_items
    from factory.scenes.build import compile_one
    from factory.schema import scene_to_json, validate

    store = ctx.require_store()
    gcfg = ctx.cfg.generate
    prompts = _read_prompts(gcfg)
    if not prompts:
        raise ConfigError(
            "stage=generate needs generate.prompts=[...], generate.prompts_file or generate.task"
        )
    for p in prompts:
        if not p.strip() or len(p) > 2000:
            raise ConfigError(f"prompt {p[:40]!r}... is empty or too long (2000 characters max)")
    jobs = []
    for i, prompt in enumerate(prompts):
        for k in range(gcfg.scenes_per_prompt):
            seed = ctx.cfg.seed + 1000 * i + k
            digest = hashlib.sha1(f"{prompt}|{seed}".encode()).hexdigest()[:8]
            rt = re.sub(r"[^a-z0-9]+", "_", room_type_of(prompt)).strip("_")
            jobs.append((f"{rt}_{digest}_{k}", prompt, seed))
    mine = ctx.shard.select(jobs)
    by_id = {j[0]: j for j in mine}
    if gcfg.agent not in ("heuristic", "llm"):
        raise ConfigError(f"generate.agent={gcfg.agent!r} must be heuristic or llm")
    if gcfg.transport not in ("direct", "mcp"):
        raise ConfigError(f"generate.transport={gcfg.transport!r} must be direct or mcp")
    library = AssetLibrary.from_config(ctx.cfg.assets, store.assets_dir)
    agent_cfg = AgentConfig(physics_critic=gcfg.physics_critic, max_objects=gcfg.max_objects)

    def one(scene_id: str) -> str:
        _, prompt, seed = by_id[scene_id]
        if store.scene_json(scene_id).is_file() and not ctx.cfg.force:
            return "skipped"
        try:
            scene, report = _generate_with(gcfg, prompt, library, seed, agent_cfg, scene_id)
        except ValueError as e:
            raise ConfigError(f"prompt {prompt!r}: {e}") from None
        validate(scene)
        from factory.store import atomic_write_json, atomic_write_text

        atomic_write_json(store.report_json(scene_id), {"schema_version": 1, "generate": report})
        atomic_write_text(store.scene_json(scene_id), scene_to_json(scene))
        compile_one(store, scene_id, ctx.cfg.compile, force=True)
        if gcfg.render:
            from factory.scenes.build import render_one

            render_one(store, scene_id, ctx.cfg.render, force=True)
        return "done"

    result = run_items("generate", list(by_id), one)
    return {**result, "scenes": len(store.scene_ids())}


__all__ = ["AgentConfig", "generate_scene", "init_scene", "parse_task", "run"]
