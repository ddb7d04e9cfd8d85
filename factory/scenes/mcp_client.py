"""A synchronous MCP client for the scene tools (the agent's ``call(name, **args)``)."""

from __future__ import annotations

import logging
from typing import Any

log = logging.getLogger(__name__)


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
