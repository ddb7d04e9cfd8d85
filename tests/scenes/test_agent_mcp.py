"""The LLM agent against a local OpenAI-compatible server (real HTTP, the real ``openai``
client, scripted tool calls including malformed ones), and the MCP server through real MCP
client sessions over stdio and streamable HTTP."""

from __future__ import annotations

import asyncio
import http.server
import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, ClassVar

import pytest

from factory.assets import AssetLibrary
from factory.scenes.agent import AgentError, LLMConfig, run_llm_agent, tool_schemas
from factory.scenes.tools import TOOLS, ToolSession

SCRIPT: list[list[tuple[str, str]]] = [
    [("init_scene", json.dumps({"request": "a cozy bedroom", "seed": 4}))],
    [("place_objects", "{not json")],
    [("teleport", json.dumps({"to": "mars"}))],
    [
        ("place_objects", json.dumps({"text": "bed", "placement": "floor", "rule": "wall"})),
        (
            "place_objects",
            json.dumps(
                {"text": "nightstand", "placement": "floor", "rule": "near", "target": "bed_0"}
            ),
        ),
    ],
    [
        (
            "place_objects",
            json.dumps(
                {"text": "table lamp", "placement": "on_top", "target": "nightstand_0", "bogus": 1}
            ),
        )
    ],
    [
        (
            "place_objects",
            json.dumps({"text": "table lamp", "placement": "on_top", "target": "nightstand_0"}),
        )
    ],
]


class _LLM(http.server.BaseHTTPRequestHandler):
    requests: ClassVar[list[dict[str, Any]]] = []
    mode = "script"

    def do_POST(self) -> None:
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        type(self).requests.append(body)
        if self.mode == "garbage":
            data = b"this is not json"
        else:
            turn = sum(1 for m in body["messages"] if m["role"] == "assistant")
            if turn < len(SCRIPT):
                calls = [
                    {
                        "id": f"call_{turn}_{k}",
                        "type": "function",
                        "function": {"name": n, "arguments": a},
                    }
                    for k, (n, a) in enumerate(SCRIPT[turn])
                ]
                message = {"role": "assistant", "content": None, "tool_calls": calls}
                finish = "tool_calls"
            else:
                message, finish = {"role": "assistant", "content": "The bedroom is done."}, "stop"
            data = json.dumps(
                {
                    "id": "x",
                    "object": "chat.completion",
                    "created": 0,
                    "model": body["model"],
                    "choices": [{"index": 0, "finish_reason": finish, "message": message}],
                    "usage": {"prompt_tokens": 1, "completion_tokens": 1, "total_tokens": 2},
                }
            ).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def llm_server():
    _LLM.requests, _LLM.mode = [], "script"
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _LLM)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/v1"
    server.shutdown()


def test_tool_schemas_are_typed() -> None:
    schemas = {s["function"]["name"]: s["function"] for s in tool_schemas()}
    assert set(schemas) == set(TOOLS)
    params = schemas["place_objects"]["parameters"]
    assert params["required"] == ["text"] and params["properties"]["count"]["type"] == "integer"


def test_llm_agent_against_local_server(tmp_path: Path, llm_server: str) -> None:
    session = ToolSession(AssetLibrary(tmp_path / "assets"), physics=True)
    report = run_llm_agent(session, "a cozy bedroom", LLMConfig(base_url=llm_server, model="m"))
    assert report["tool_calls"] == 7
    results = [t["result"] for t in report["trace"] if "tool" in t]
    assert "malformed arguments" in results[1]["error"]
    assert "unknown tool 'teleport'" in results[2]["error"]
    assert "bad arguments" in results[5]["error"] or "unexpected keyword" in results[5]["error"]
    assert results[6]["ok"], results[6]
    cats = sorted(o.category for o in session.scene.objects)
    assert cats == ["bed", "nightstand", "table_lamp"]
    # the errors went back to the model as tool messages
    last = _LLM.requests[-1]["messages"]
    tool_msgs = [m for m in last if m["role"] == "tool"]
    assert len(tool_msgs) == 7 and "malformed" in tool_msgs[1]["content"]
    assert report["trace"][-1] == {"assistant": "The bedroom is done."}


def test_llm_endpoint_failures(tmp_path: Path, llm_server: str) -> None:
    session = ToolSession(AssetLibrary(tmp_path / "assets"), physics=False)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        dead = f"http://127.0.0.1:{s.getsockname()[1]}/v1"
    with pytest.raises(AgentError, match="unreachable"):
        run_llm_agent(
            session, "a kitchen", LLMConfig(base_url=dead, model="m", retries=0, timeout=2)
        )
    _LLM.mode = "garbage"
    with pytest.raises(AgentError):
        run_llm_agent(session, "a kitchen", LLMConfig(base_url=llm_server, model="m", retries=0))
    with pytest.raises(AgentError, match="needs an endpoint"):
        run_llm_agent(session, "a kitchen", LLMConfig())


async def _exercise(client: Any) -> dict[str, Any]:
    names = [t.name for t in (await client.list_tools()).tools]
    first = json.loads(
        (await client.call_tool("init_scene", {"request": "a modern kitchen", "seed": 1}))
        .content[0]
        .text
    )
    placed = json.loads(
        (
            await client.call_tool(
                "place_objects", {"text": "dining table", "placement": "floor", "rule": "center"}
            )
        )
        .content[0]
        .text
    )
    on_top = json.loads(
        (
            await client.call_tool(
                "place_objects",
                {"text": "bowl", "placement": "on_top", "target": placed["placed"][0]},
            )
        )
        .content[0]
        .text
    )
    bad_schema = await client.call_tool("place_objects", {"text": "bed", "placement": "ceiling"})
    bad_id = json.loads(
        (await client.call_tool("remove_object", {"object_id": "ghost"})).content[0].text
    )
    info = json.loads((await client.call_tool("get_scene_info", {})).content[0].text)
    physics = json.loads((await client.call_tool("physics_critic", {})).content[0].text)
    return {
        "names": names,
        "first": first,
        "placed": placed,
        "on_top": on_top,
        "bad_schema": bad_schema,
        "bad_id": bad_id,
        "info": info,
        "physics": physics,
    }


def _check(r: dict[str, Any]) -> None:
    assert set(r["names"]) == set(TOOLS)
    assert r["first"]["ok"] and r["first"]["room_type"] == "kitchen"
    assert r["placed"]["ok"] and r["on_top"]["ok"], r["on_top"]
    assert r["bad_schema"].is_error
    assert not r["bad_id"]["ok"] and "ghost" in r["bad_id"]["error"]
    assert len(r["info"]["objects"]) == 2
    assert r["physics"]["collision_ratio"] == 0.0 and r["physics"]["stability_ratio"] == 1.0


def test_mcp_over_stdio(tmp_path: Path) -> None:
    from mcp import Client
    from mcp.client.stdio import StdioServerParameters

    params = StdioServerParameters(
        command=sys.executable,
        args=["-m", "factory.scenes.mcp_server", "--assets", str(tmp_path / "assets")],
    )

    async def go() -> dict[str, Any]:
        async with Client(params) as client:
            return await _exercise(client)

    _check(asyncio.run(go()))


def test_mcp_over_http(tmp_path: Path) -> None:
    from mcp import Client

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "factory.scenes.mcp_server",
            "--transport",
            "http",
            "--port",
            str(port),
            "--assets",
            str(tmp_path / "assets"),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.time() + 60
        while time.time() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                break
            except OSError:
                time.sleep(0.2)

        async def go() -> dict[str, Any]:
            async with Client(f"http://127.0.0.1:{port}/mcp") as client:
                return await _exercise(client)

        _check(asyncio.run(go()))
    finally:
        proc.terminate()
        proc.wait(10)


class _VLM(http.server.BaseHTTPRequestHandler):
    seen: ClassVar[list[dict[str, Any]]] = []
    answer = "A bright bedroom with a double bed, two nightstands and a reading lamp."

    def do_POST(self) -> None:
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        type(self).seen.append(body)
        data = json.dumps(
            {
                "id": "v",
                "object": "chat.completion",
                "created": 0,
                "model": body["model"],
                "choices": [
                    {
                        "index": 0,
                        "finish_reason": "stop",
                        "message": {"role": "assistant", "content": self.answer},
                    }
                ],
            }
        )
        raw = data.encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(raw)))
        self.end_headers()
        self.wfile.write(raw)

    def log_message(self, *args: object) -> None:
        pass


def test_vlm_describe_and_critic(tmp_path: Path) -> None:
    from PIL import Image

    from factory.scenes.vlm import describe_image, vlm_critic

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _VLM)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}/v1"
    try:
        img = tmp_path / "room.png"
        Image.new("RGB", (8, 8), (200, 180, 150)).save(img)
        text = describe_image(img, "make it cozy", base_url=url, model="vlm")
        assert "double bed" in text
        sent = _VLM.seen[-1]["messages"][0]["content"]
        assert sent[1]["image_url"]["url"].startswith("data:image/png;base64,")
        _VLM.answer = (
            'Here you go: {"satisfied": false, "suggestions": [{"issue": "missing '
            'companion", "detail": "lamp", "call": {"tool": "place_objects", "args": '
            '{"text": "table lamp", "placement": "on_top", "target": "nightstand_0"}}}]}'
        )
        verdict = vlm_critic(
            {"top": str(img), "corner_0": str(img)}, "a bedroom", base_url=url, model="vlm"
        )
        assert not verdict["satisfied"] and verdict["suggestions"][0]["detail"] == "lamp"
        assert len(_VLM.seen[-1]["messages"][0]["content"]) == 3  # text + two images
        _VLM.answer = "I like it."
        with pytest.raises(AgentError, match="did not answer JSON"):
            vlm_critic({"top": str(img)}, "a bedroom", base_url=url, model="vlm")
    finally:
        server.shutdown()


def test_generate_stage_from_an_image(cli, tmp_path: Path) -> None:
    from PIL import Image

    _VLM.answer = "A bright bedroom with a double bed, two nightstands and a reading lamp."
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _VLM)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        img = tmp_path / "room.jpg"
        Image.new("RGB", (8, 8), (200, 180, 150)).save(img)
        run = tmp_path / "run"
        out = cli(
            "stage=generate",
            f"run_dir={run}",
            f"generate.image={img}",
            f"generate.vlm_base_url=http://127.0.0.1:{server.server_address[1]}/v1",
            "generate.vlm_model=vlm",
            "generate.physics_critic=false",
            "generate.render=false",
        )
        assert out.returncode == 0, out.stderr
        (scene_dir,) = (run / "scenes").iterdir()
        report = json.loads((scene_dir / "report.json").read_text())["generate"]
        assert "double bed" in report["request"] and scene_dir.name.startswith("bedroom")
        assert "error" in report["vlm_critic"]  # the scripted VLM answers prose, not JSON
    finally:
        server.shutdown()
