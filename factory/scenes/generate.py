"""Scene generation with the offline heuristic agent, and ``stage=generate``.

The agent follows the paper's loop with the generator tools of :mod:`.placement`: build the
room (:func:`init_scene`), place floor and wall furniture (depth-first over grid candidates),
simulate once and drop unstable pieces, then place the small objects on every support surface
with the physics critic judging each placement, then make sure the task objects exist and
are reachable. Every tool call and its result go into the trace saved in ``report.json``.
"""

from __future__ import annotations

import hashlib
import logging
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from factory.scenes.assets import AssetLibrary
from factory.scenes.placement import SceneState, place_floor, place_on, place_wall
from factory.scenes.rooms import ROOM_TYPES, Item, room_type_of
from factory.schema import Door, Room, Scene, Size3, Task, Vec3, Wall, Window, check_id
from factory.sim.critic import physics_critic
from factory.sim.stability import FreeBodies, StabilityProtocol, check_stability

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


def init_scene(
    request: str, seed: int = 0, scene_id: str | None = None, room_type: str | None = None
) -> tuple[Scene, dict[str, Any]]:
    """Builds an empty room for the request: type, size, materials, walls, a door, windows.

    Raises:
        ValueError: a request too small to hold a room (e.g. "0.5 m wide").
    """
    rng = np.random.default_rng(seed)
    rt_name = room_type or room_type_of(request)
    rt = ROOM_TYPES[rt_name]
    (w0, w1), (l0, l1) = rt.size
    width, length = float(rng.uniform(w0, w1)), float(rng.uniform(l0, l1))
    m = re.search(r"(\d+(?:\.\d+)?)\s*(?:m|meters?|metres?)\s*(?:wide|by)", request.lower())
    if m:
        width = float(m.group(1))
        if width < 1.5:
            raise ValueError(f"a room {width} m wide cannot hold furniture: ask for at least 1.5 m")
    height = 2.7
    rid = check_id(re.sub(r"[^a-z0-9]+", "_", rt_name).strip("_") or "room", "room id")
    pts = [(0, 0), (width, 0), (width, length), (0, length)]
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
    door_wall = walls[int(rng.integers(4))]
    window_wall = next(w for w in walls if w is not door_wall and w.id.endswith(("north", "east")))
    room = Room(
        id=rid,
        room_type=rt_name,
        position=Vec3(0, 0, 0),
        dimensions=Size3(width, length, height),
        walls=walls,
        doors=[
            Door(
                id=f"{rid}_door",
                wall_id=door_wall.id,
                position_on_wall=float(rng.uniform(0.25, 0.75)),
                width=0.9,
                height=2.1,
            )
        ],
        windows=[
            Window(
                id=f"{rid}_window",
                wall_id=window_wall.id,
                position_on_wall=0.5,
                width=min(1.4, 0.4 * window_wall.length),
                height=1.2,
                sill_height=0.9,
            )
        ],
        floor_material=str(rng.choice(rt.floors)),
        ceiling_height=height,
    )
    digest = hashlib.sha1(f"{request}|{seed}".encode()).hexdigest()[:8]
    sid = scene_id or f"{rid}_{digest}"
    scene = Scene(
        id=sid,
        rooms=[room],
        description=request,
        source="text",
        seed=seed,
        building_style=_style(request),
    )
    return scene, {
        "room_type": rt_name,
        "size_m": [round(width, 2), round(length, 2)],
        "floor": room.floor_material,
    }


@dataclass
class AgentConfig:
    """Knobs of the heuristic agent."""

    physics_critic: bool = True
    max_objects: int = 120
    critic_batch: int = 4
    extra_fill: int = 6


@dataclass
class Trace:
    """Tool calls and their results."""

    calls: list[dict[str, Any]] = field(default_factory=list)

    def log(self, tool: str, args: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
        self.calls.append({"tool": tool, "args": args, "result": result})
        return result


def _count(item: Item, rng: np.random.Generator) -> int:
    if item.p < 1.0 and rng.uniform() > item.p:
        return 0
    return int(rng.integers(item.count[0], item.count[1] + 1))


def _remove_unstable(state: SceneState, trace: Trace) -> None:
    """The paper's shortcut: simulate once after floor and wall objects, drop the unstable."""
    from factory.sim.compile import compile_scene

    if not state.scene.objects:
        return
    model = compile_scene(state.scene, state.library.assets_dir).model
    result = check_stability(
        model, protocol=StabilityProtocol(penetration_tol=math.inf, resettle=False)
    )
    free = FreeBodies.of(model)
    bad = [free.names[j] for j in np.flatnonzero(~result.stable_object[0])]
    for oid in bad:
        state.scene.objects = [o for o in state.scene.objects if o.id != oid]
    trace.log(
        "physics_critic",
        {"scope": "floor and wall objects"},
        {"unstable_removed": bad, "objects": len(state.scene.objects)},
    )


def generate_scene(
    request: str,
    library: AssetLibrary,
    seed: int = 0,
    config: AgentConfig | None = None,
    task: str | None = None,
    scene_id: str | None = None,
) -> tuple[Scene, dict[str, Any]]:
    """Generates one furnished, physically checked scene for a text request.

    Returns:
        the scene and a report (``trace`` of tool calls, counts, timings).
    """
    cfg = config or AgentConfig()
    t0 = time.perf_counter()
    trace = Trace()
    scene, info = init_scene(request, seed, scene_id)
    trace.log("init_scene", {"request": request, "seed": seed}, info)
    state = SceneState(scene, library, seed)
    rng = state.rng
    rt = ROOM_TYPES[info["room_type"]]
    style = _style(request)
    keyed: dict[str, list[str]] = {}

    def styled(text: str) -> str:
        return f"{style} {text}" if style else text

    critic = None
    if cfg.physics_critic:

        def critic(sc: Scene, oid: str, poses: list[list[float]]) -> dict[str, Any]:
            return physics_critic(
                sc,
                oid,
                poses,
                assets_root=library.assets_dir,
                protocol=StabilityProtocol(resettle=True),
            )

    # 1. floor and wall furniture
    small: list[tuple[Item, int]] = []
    for item in rt.items:
        n = _count(item, rng)
        if item.rule.startswith("on:"):
            small.append((item, n))
            continue
        for _ in range(n):
            rule, _, target = item.rule.partition(":")
            tgt_ids = keyed.get(target, [])
            if rule in ("near", "around") and not tgt_ids:
                continue
            args = {
                "text": styled(item.text),
                "rule": rule,
                "target": tgt_ids[0] if tgt_ids else None,
            }
            if rule == "mount":
                res = place_wall(state, styled(item.text), item.height)
            else:
                res = place_floor(
                    state, styled(item.text), rule, target=tgt_ids[0] if tgt_ids else None
                )
            trace.log("place_objects", args, res.as_dict())
            if res.ok and item.key:
                keyed.setdefault(item.key, []).append(res.object_id)  # type: ignore[arg-type]
    _remove_unstable(state, trace)
    alive = {o.id for o in scene.objects}
    keyed = {k: [i for i in v if i in alive] for k, v in keyed.items()}

    # 2. task objects first, so they get the best spots
    task_spec = parse_task(task or request)
    if task_spec is not None:
        _place_task(state, task_spec, critic, trace, cfg)

    # 3. small objects on surfaces (multi-level), judged by the physics critic
    for item, n in small:
        supports = keyed.get(item.rule.split(":", 1)[1], [])
        for k in range(n):
            if not supports or len(scene.objects) >= cfg.max_objects:
                break
            sup = supports[k % len(supports)]
            res = place_on(state, styled(item.text), sup, critic, batch=cfg.critic_batch)
            trace.log("place_objects", {"text": item.text, "on": sup}, res.as_dict())
    # 4. fill sparse floor space with background objects
    fillers = list(rt.fillers) * 2
    rng.shuffle(fillers)
    for text in fillers[: cfg.extra_fill]:
        if len(scene.objects) >= cfg.max_objects:
            break
        res = place_floor(state, styled(text), "corner" if rng.uniform() < 0.5 else "wall")
        trace.log("place_objects", {"text": text, "rule": "fill"}, res.as_dict())
    if task_spec is not None:
        scene.task = Task(kind="pick_place", instruction=task_spec.instruction)
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


def _place_task(
    state: SceneState, spec: TaskSpec, critic: Any, trace: Trace, cfg: AgentConfig
) -> None:
    """Puts the task's pick object and target on a free table near its edge."""
    scene = state.scene
    tables = [
        o
        for o in scene.objects
        if o.category
        in (
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
    ]
    if not tables:
        res = place_floor(state, "dining table", "center")
        trace.log(
            "place_objects", {"text": "dining table", "why": "task needs a surface"}, res.as_dict()
        )
        if not res.ok:
            return
        tables = [scene.object(res.object_id)]  # type: ignore[arg-type]
    table = max(tables, key=lambda o: o.dimensions.width * o.dimensions.length)
    for text, role in ((spec.target, "place_target"), (spec.pick, "pick")):
        res = place_on(
            state, text, table.id, critic, task_role=role, batch=cfg.critic_batch, max_batches=5
        )
        trace.log("place_objects", {"text": text, "on": table.id, "task_role": role}, res.as_dict())


def _read_prompts(cfg: Any) -> list[str]:
    prompts = list(cfg.prompts or [])
    if cfg.prompts_file:
        from pathlib import Path

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
    return prompts


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
    if gcfg.agent != "heuristic":
        raise ConfigError(f"generate.agent={gcfg.agent!r} is not available: use heuristic")
    library = AssetLibrary.from_config(ctx.cfg.assets, store.assets_dir)
    agent_cfg = AgentConfig(physics_critic=gcfg.physics_critic, max_objects=gcfg.max_objects)

    def one(scene_id: str) -> str:
        _, prompt, seed = by_id[scene_id]
        if store.scene_json(scene_id).is_file() and not ctx.cfg.force:
            return "skipped"
        try:
            scene, report = generate_scene(
                prompt, library, seed, agent_cfg, task=gcfg.task or None, scene_id=scene_id
            )
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
