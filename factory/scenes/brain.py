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
from typing import Any

import numpy as np

from factory.assets import AssetLibrary
from factory.scenes.brain_steps import (
    TABLES,
    AgentConfig,
    Brain,
    BrainState,
    Caller,
    Trace,
    brief,
    task_kind,
)
from factory.scenes.request import parse_request, style_of
from factory.schema import Scene, Task, check_id

log = logging.getLogger(__name__)

__all__ = ["TABLES", "AgentConfig", "generate_scene", "heuristic_agent", "task_kind"]


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
    rooms = first.get("rooms") or [{"id": first["room_id"], "room_type": first["room_type"]}]
    brain = Brain(
        call, cfg, BrainState(rng, style_of(request), budget=cfg.max_objects * len(rooms))
    )
    brain.furnish(rooms)
    brain.drop_unstable()
    spec = brain.task_objects(request, task)
    brain.small_objects()
    brain.fill()
    brain.keep_route()
    brain.stored_objects()  # inside furniture: the route is not theirs to change
    return {"task": None if spec is None else spec.__dict__}


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
    the server's ``session`` to read the result). A request for several rooms driven directly
    is generated room by room, the rooms in parallel worker processes
    (:func:`~.per_room.generate_home`, ``config.workers``).

    Returns:
        the scene and a report (``trace`` of tool calls, counts, timings).
    """
    from factory.scenes.tools import ToolSession

    cfg = config or AgentConfig()
    if caller is None and len(parse_request(request).room_types) > 1:
        from factory.scenes.per_room import generate_home

        home, report = generate_home(request, library, seed, cfg, task, session, cfg.workers)
        if scene_id is not None:
            home.id = check_id(scene_id, "scene id")
        return home, report
    t0 = time.perf_counter()
    trace = Trace()
    if session is None:
        session = ToolSession(library, physics=cfg.physics_critic, critic_scope=cfg.critic_scope)
    direct = caller or (lambda name, **kw: getattr(session, name)(**kw))

    def call(name: str, **args: Any) -> dict[str, Any]:
        result = direct(name, **args)
        trace.calls.append({"tool": name, "args": args, "result": brief(result)})
        return result

    info = heuristic_agent(call, request, seed, cfg, task)
    scene = session.scene
    if scene_id is not None:
        scene.id = check_id(scene_id, "scene id")
    if info["task"] is not None:
        scene.task = Task(kind=task_kind(info["task"]), instruction=info["task"]["instruction"])
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
