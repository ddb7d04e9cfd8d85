"""The scene tools over MCP (official ``mcp`` SDK): stdio, or streamable HTTP on 127.0.0.1.

    python -m factory.scenes.mcp_server --assets runs/x/assets                 # stdio
    python -m factory.scenes.mcp_server --transport http --port 8765 --assets runs/x/assets

Each tool has a typed input schema derived from its signature; arguments are validated by the
SDK, and a tool that fails returns ``{"ok": false, "error": ...}`` instead of crashing the
server.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path
from typing import Any, Literal

from factory.sim.gl import configure_gl


def build_server(session: Any) -> Any:
    """An ``MCPServer`` exposing the tools of a :class:`~.tools.ToolSession`."""
    from mcp.server.mcpserver import MCPServer

    server = MCPServer(
        name="factory-scene-tools",
        version="0.1.0",
        instructions="Build a furnished, physically valid room: init_scene, then "
        "place_objects (floor, wall, on_top), check with visual_critic, "
        "physics_critic and (for a mobile task) route_critic, fix with "
        "move_object/remove_object, finish with "
        "get_scene_json.",
    )

    @server.tool()
    def init_scene(request: str, seed: int = 0) -> str:
        """Create an empty room for the request (room type, size, materials, door, window)."""
        return json.dumps(session.init_scene(request, seed))

    @server.tool()
    def place_objects(
        text: str,
        placement: Literal["floor", "wall", "on_top", "inside"] | None = None,
        rule: Literal[
            "wall", "corner", "free", "center", "near", "around", "facing", "away"
        ] = "wall",
        target: str | None = None,
        height: float = 1.3,
        count: int = 1,
        task_role: str | None = None,
        room_id: str | None = None,
    ) -> str:
        """Place objects described by text: on the floor by a rule, mounted on a wall at a
        height (m), on top of / inside the target object, or stored inside an articulated target
        (placement=inside: behind its door, in its drawer); room_id picks the room. Without
        placement, the text may say where: "a lamp on the nightstand", "a tv stand facing the
        sofa", "a plant in the corner", "a painting on the wall"."""
        return json.dumps(
            session.place_objects(text, placement, rule, target, height, count, task_role, room_id)
        )

    @server.tool()
    def move_object(
        object_id: str,
        placement: Literal["floor", "wall", "on_top"] = "floor",
        rule: Literal[
            "wall", "corner", "free", "center", "near", "around", "facing", "away"
        ] = "free",
        target: str | None = None,
        room_id: str | None = None,
    ) -> str:
        """Move an object elsewhere (room_id picks the room); it stays put if no place is
        found."""
        return json.dumps(session.move_object(object_id, placement, rule, target, room_id))

    @server.tool()
    def remove_object(object_id: str) -> str:
        """Remove an object and whatever stands on it."""
        return json.dumps(session.remove_object(object_id))

    @server.tool()
    def get_scene_info() -> str:
        """The rooms and objects of the scene."""
        return json.dumps(session.get_scene_info())

    @server.tool()
    def render_views(width: int = 320, height: int = 240) -> str:
        """Render the top view and four corner views to PNG files."""
        return json.dumps(session.render_views(width, height))

    @server.tool()
    def visual_critic() -> str:
        """Suggestions: missing task objects, companions, sparse areas, blocked doors."""
        return json.dumps(session.visual_critic())

    @server.tool()
    def physics_critic() -> str:
        """Collision and stability metrics of the whole scene."""
        return json.dumps(session.physics_critic())

    @server.tool()
    def route_critic(clear: bool = False) -> str:
        """The mobile task's route: can the robot's base work at the pick's support and at the
        place support (1.5 m apart at least) and drive between them; with clear, the light
        objects whose removal would open the way."""
        return json.dumps(session.route_critic(clear))

    @server.tool()
    def get_scene_json() -> str:
        """The validated scene (scene.json content)."""
        return json.dumps(session.get_scene_json())

    return server


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m factory.scenes.mcp_server", description=__doc__)
    p.add_argument("--transport", choices=["stdio", "http"], default="stdio")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=8765)
    p.add_argument("--assets", required=True, help="asset cache folder")
    p.add_argument("--out", default=None, help="folder for render_views images")
    p.add_argument("--no-physics", action="store_true", help="skip the physics critic")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    configure_gl("auto")
    from factory.assets import AssetLibrary
    from factory.scenes.tools import ToolSession

    session = ToolSession(
        AssetLibrary(Path(args.assets)), physics=not args.no_physics, out_dir=args.out
    )
    server = build_server(session)
    if args.transport == "stdio":
        server.run("stdio")
    else:
        server.run("streamable-http", host=args.host, port=args.port)
    return 0


if __name__ == "__main__":
    sys.exit(main())
