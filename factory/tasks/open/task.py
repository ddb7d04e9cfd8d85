"""``task=open``: the Panda opens a named part (a drawer, a cabinet or fridge door) of an
articulated object by its handle, from closed to at least 90 % of its span (the shared
machinery: :mod:`factory.tasks.articulated`)."""

from __future__ import annotations

from typing import ClassVar

from factory.tasks.articulated.task import ArticulatedTask

__all__ = ["OpenTask"]


class OpenTask(ArticulatedTask):
    """``task=open``."""

    name: ClassVar[str] = "open"
    description: ClassVar[str] = "open a drawer or door of a cabinet, fridge or microwave"
    direction: ClassVar[str] = "open"
    layout: ClassVar[str] = "articulated_open"
    example_scene: ClassVar[str | None] = "tasks/open/kitchen_cabinet_drawer_open"
    request_verbs: ClassVar[tuple[str, ...]] = (
        "open",
        "opens",
        "opening",
        "pull open",
        "pulls open",
    )
