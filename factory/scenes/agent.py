"""The LLM brain of the scene agent: an OpenAI-compatible chat endpoint with tool calling.

The loop: the model sees the request and the tool schemas, answers with tool calls; each call
runs on the :class:`~.tools.ToolSession` (the same tools the MCP server exposes) and its JSON
result goes back as a tool message; until the model stops calling tools or a budget (tool
calls, seconds) ends. A malformed call (arguments that are not JSON, an unknown tool, bad
arguments) is answered with the error so that the model can correct itself. An endpoint that
is down, slow or answers garbage raises :class:`AgentError` after the configured retries; the
caller may fall back to the heuristic agent.

The endpoint, model and key come from the config or the environment
(``FACTORY_LLM_BASE_URL``, ``FACTORY_LLM_MODEL``, ``FACTORY_LLM_API_KEY``).
"""

from __future__ import annotations

import inspect
import json
import logging
import os
import time
import typing
from dataclasses import dataclass
from typing import Any

from factory.errors import FactoryError
from factory.scenes.tools import TOOLS, ToolSession

log = logging.getLogger(__name__)

SYSTEM_PROMPT = (
    "You build simulation-ready indoor scenes for robot learning by calling tools. Start with "
    "init_scene, place large furniture on the floor and on walls, then small objects on top "
    "of surfaces (shelves, tables, nightstands), check with visual_critic and physics_critic "
    "(and route_critic when the robot moves an object from one support to another), "
    "fix problems, and stop when the room is densely and plausibly furnished."
)


class AgentError(FactoryError):
    """The LLM endpoint failed (down, slow, or answering nonsense)."""


@dataclass
class LLMConfig:
    """Endpoint and budgets of the LLM agent."""

    base_url: str | None = None
    model: str | None = None
    api_key: str | None = None
    timeout: float = 60.0
    retries: int = 2
    max_tool_calls: int = 200
    max_seconds: float = 600.0


def _json_type(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return _json_type(args[0])
    return {
        str: {"type": "string"},
        int: {"type": "integer"},
        float: {"type": "number"},
        bool: {"type": "boolean"},
    }.get(tp, {"type": "string"})


def tool_schemas() -> list[dict[str, Any]]:
    """OpenAI ``tools`` definitions from the ToolSession methods' signatures and docstrings."""
    out = []
    for name in TOOLS:
        fn = getattr(ToolSession, name)
        fn = getattr(fn, "__wrapped__", fn)
        hints = typing.get_type_hints(fn)
        sig = inspect.signature(fn)
        props, required = {}, []
        for pname, param in sig.parameters.items():
            if pname == "self":
                continue
            props[pname] = _json_type(hints.get(pname, str))
            if param.default is inspect.Parameter.empty:
                required.append(pname)
        out.append(
            {
                "type": "function",
                "function": {
                    "name": name,
                    "description": (fn.__doc__ or "").strip().split("\n\n")[0],
                    "parameters": {"type": "object", "properties": props, "required": required},
                },
            }
        )
    return out


def run_llm_agent(
    session: ToolSession, request: str, config: LLMConfig, seed: int = 0
) -> dict[str, Any]:
    """Runs the LLM loop on ``session`` for ``request``; returns the trace.

    Raises:
        AgentError: no endpoint configured, the endpoint failed, or no scene was built.
    """
    from openai import APIConnectionError, APIError, APITimeoutError, OpenAI

    base_url = config.base_url or os.environ.get("FACTORY_LLM_BASE_URL")
    model = config.model or os.environ.get("FACTORY_LLM_MODEL")
    if not base_url or not model:
        raise AgentError(
            "the llm agent needs an endpoint: set generate.llm.base_url and "
            "generate.llm.model (or FACTORY_LLM_BASE_URL / FACTORY_LLM_MODEL)"
        )
    client = OpenAI(
        base_url=base_url,
        api_key=config.api_key or os.environ.get("FACTORY_LLM_API_KEY", "not-needed"),
        timeout=config.timeout,
        max_retries=config.retries,
    )
    messages: list[dict[str, Any]] = [
        {"role": "system", "content": SYSTEM_PROMPT},
        {"role": "user", "content": f"Request: {request}\nUse seed {seed} for init_scene."},
    ]
    tools = tool_schemas()
    trace: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    calls = 0
    while calls < config.max_tool_calls and time.perf_counter() - t0 < config.max_seconds:
        try:
            reply = client.chat.completions.create(
                model=model,
                messages=messages,  # type: ignore[arg-type]
                tools=tools,  # type: ignore[arg-type]
            )
        except (APIConnectionError, APITimeoutError) as e:
            raise AgentError(f"the LLM endpoint {base_url} is unreachable or slow: {e}") from None
        except APIError as e:
            raise AgentError(f"the LLM endpoint {base_url} answered an error: {e}") from None
        except (ValueError, TypeError, KeyError) as e:  # a body that is not a chat completion
            raise AgentError(
                f"the LLM endpoint {base_url} answered something that is not a chat "
                f"completion ({type(e).__name__}: {e})"
            ) from None
        if not getattr(reply, "choices", None):
            raise AgentError(f"the LLM endpoint {base_url} answered without choices")
        msg = reply.choices[0].message
        tool_calls: list[Any] = list(msg.tool_calls or [])
        messages.append(
            {
                "role": "assistant",
                "content": msg.content or "",
                "tool_calls": [tc.model_dump() for tc in tool_calls] or None,
            }
        )
        if not tool_calls:
            trace.append({"assistant": msg.content or ""})
            break
        for tc in tool_calls:
            calls += 1
            name = tc.function.name
            try:
                args = json.loads(tc.function.arguments or "{}")
                if not isinstance(args, dict):
                    raise ValueError("arguments must be a JSON object")
            except (json.JSONDecodeError, ValueError) as e:
                result: dict[str, Any] = {
                    "ok": False,
                    "error": f"malformed arguments for {name}: {e}; send a JSON object",
                }
            else:
                if name not in TOOLS:
                    result = {
                        "ok": False,
                        "error": f"unknown tool {name!r}; tools: {', '.join(TOOLS)}",
                    }
                else:
                    try:
                        result = getattr(session, name)(**args)
                    except TypeError as e:
                        result = {"ok": False, "error": f"bad arguments for {name}: {e}"}
            trace.append({"tool": name, "args": tc.function.arguments, "result": result})
            messages.append(
                {"role": "tool", "tool_call_id": tc.id, "content": json.dumps(result)[:20000]}
            )
    if session.state is None:
        raise AgentError("the LLM agent never called init_scene: no scene was built")
    return {
        "agent": "llm",
        "model": model,
        "tool_calls": calls,
        "trace": trace,
        "seconds": round(time.perf_counter() - t0, 2),
    }
