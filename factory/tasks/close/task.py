"""``task=close``: the Panda closes a named part (a drawer, a cabinet or fridge door) of an
articulated object by its handle, from 60-100 % of its span open to at most 5 % of its range
(the shared machinery: :mod:`factory.tasks.articulated`)."""

from __future__ import annotations

from typing import ClassVar

from factory.tasks.articulated.task import ArticulatedTask

__all__ = ["CloseTask"]


class CloseTask(ArticulatedTask):
    """``task=close``."""

    name: ClassVar[str] = "close"
    description: ClassVar[str] = "close an open drawer or door of a cabinet, fridge or microwave"
    direction: ClassVar[str] = "close"
    layout: ClassVar[str] = "articulated_close"
    example_scene: ClassVar[str | None] = "tasks/close/kitchen_cabinet_drawer_close"
    request_verbs: ClassVar[tuple[str, ...]] = (
        "close",
        "closes",
        "closing",
        "shut",
        "shuts",
        "shutting",
        "push shut",
        "pushes shut",
    )
