"""Vision-language model calls (OpenAI-compatible endpoint with image input).

* :func:`describe_image`: an image-conditioned request becomes a text request first ("a bright
  Scandinavian living room with a grey sofa ..."), which the agent then builds.
* :func:`vlm_critic`: the five renders of a scene and the request go to the VLM, which answers
  structured suggestions (JSON) in the same form as the rule-based visual critic.

The endpoint comes from arguments or ``FACTORY_VLM_BASE_URL`` / ``FACTORY_VLM_MODEL`` /
``FACTORY_VLM_API_KEY``. Failures raise :class:`~.agent.AgentError` with the reason.
"""

from __future__ import annotations

import base64
import json
import os
import re
from pathlib import Path
from typing import Any

from factory.scenes.agent import AgentError

CRITIC_PROMPT = (
    "These are renders (top view and four corner views) of a generated room for the request "
    'below. Answer only JSON: {"satisfied": bool, "suggestions": [{"issue": str, '
    '"detail": str, "call": {"tool": "place_objects"|"move_object"|"remove_object", '
    '"args": {...}}}]}. Suggest missing objects that belong with others, objects to move or '
    "remove because they look implausible, and sparse areas to fill.\nRequest: "
)


def _client(
    base_url: str | None, model: str | None, api_key: str | None, timeout: float
) -> tuple[Any, str, str]:
    from openai import OpenAI

    base_url = base_url or os.environ.get("FACTORY_VLM_BASE_URL")
    model = model or os.environ.get("FACTORY_VLM_MODEL")
    if not base_url or not model:
        raise AgentError("no VLM endpoint: set FACTORY_VLM_BASE_URL and FACTORY_VLM_MODEL")
    key = api_key or os.environ.get("FACTORY_VLM_API_KEY", "not-needed")
    return OpenAI(base_url=base_url, api_key=key, timeout=timeout, max_retries=1), base_url, model


def _image_part(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise AgentError(f"image {p} does not exist")
    data = base64.b64encode(p.read_bytes()).decode()
    mime = "image/png" if p.suffix.lower() == ".png" else "image/jpeg"
    return {"type": "image_url", "image_url": {"url": f"data:{mime};base64,{data}"}}


def _ask(client: Any, base_url: str, model: str, content: list[dict[str, Any]]) -> str:
    try:
        reply = client.chat.completions.create(
            model=model, messages=[{"role": "user", "content": content}]
        )
        text = reply.choices[0].message.content
    except Exception as e:  # connection errors, HTTP errors, bodies that are not completions
        raise AgentError(f"the VLM endpoint {base_url} failed: {type(e).__name__}: {e}") from None
    if not text or not str(text).strip():
        raise AgentError(f"the VLM endpoint {base_url} answered an empty message")
    return str(text).strip()


def describe_image(
    image: str | Path,
    hint: str = "",
    base_url: str | None = None,
    model: str | None = None,
    api_key: str | None = None,
    timeout: float = 60.0,
) -> str:
    """A one-paragraph text request describing the room in ``image`` (plus ``hint``)."""
    client, url, name = _client(base_url, model, api_key, timeout)
    prompt = (
        "Describe this room as a request for a 3-D scene generator: room type, style, "
        "main furniture and small objects, colours and materials. One paragraph."
    )
    if hint:
        prompt += f" The user adds: {hint}"
    return _ask(client, url, name, [{"type": "text", "text": prompt}, _image_part(image)])


def vlm_critic(
    images: dict[str, str],
    request: str,
    base_url: str | None = None,
    model: str | None = None,
    api_key: str | None = None,
    timeout: float = 120.0,
) -> dict[str, Any]:
    """Structured suggestions from the VLM for the rendered scene.

    Raises:
        AgentError: the endpoint failed or did not answer the JSON asked for.
    """
    client, url, name = _client(base_url, model, api_key, timeout)
    content = [{"type": "text", "text": CRITIC_PROMPT + request}]
    content += [_image_part(p) for p in images.values()]
    text = _ask(client, url, name, content)
    match = re.search(r"\{.*\}", text, re.S)
    try:
        data = json.loads(match.group(0) if match else text)
    except json.JSONDecodeError:
        raise AgentError(f"the VLM critic did not answer JSON: {text[:200]!r}") from None
    if not isinstance(data, dict) or not isinstance(data.get("suggestions", []), list):
        raise AgentError(f"the VLM critic's JSON has no suggestions list: {text[:200]!r}")
    data.setdefault("satisfied", not data.get("suggestions"))
    data.setdefault("suggestions", [])
    return data
