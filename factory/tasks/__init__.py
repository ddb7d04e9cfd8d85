"""The task registry: every robot task the factory records, trains and evaluates.

A task is one package under ``factory/tasks/`` whose class fills the hooks of
:class:`~factory.tasks.base.Task` (what a scene must hold for it and the check that judges one,
how its episodes are planned and recorded, what it adds to the dataset, how its env reads and
acts), registered here by one line. The registry is a literal dict of import paths resolved
lazily, as :mod:`factory.stages` is: importing it imports no task, so the lower floors
(generation, validation, augmentation) can ask it about a scene, and nothing registers itself
by import. No code outside ``factory/tasks/`` tests a task's name: it asks the task.

Adding a task: a package ``factory/tasks/<name>/`` with a :class:`Task` subclass, and its line
in :data:`TASKS`.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from functools import cache
from typing import TYPE_CHECKING

from factory.errors import ConfigError

if TYPE_CHECKING:
    from factory.schema import Scene
    from factory.tasks.base import Task

__all__ = [
    "DEFAULT_TASK",
    "TASKS",
    "get_task",
    "task_for_scene",
    "task_names",
    "task_of_scenes",
    "tasks",
]

TASKS: dict[str, str] = {
    "pick_place": "factory.tasks.pick_place.task:PickPlaceTask",
    "mobile_pick_place": "factory.tasks.mobile_pick_place.task:MobilePickPlaceTask",
    "open": "factory.tasks.open.task:OpenTask",
    "close": "factory.tasks.close.task:CloseTask",
    "place_inside": "factory.tasks.place_inside.task:PlaceInsideTask",
}
"""Task name (``task=<name>``, a scene's ``task.kind``) -> ``"module:Class"``."""

DEFAULT_TASK = "pick_place"
"""The task of a scene that names none and that no other task claims."""


def task_names() -> list[str]:
    """The registered task names, in registry order."""
    return list(TASKS)


@cache
def get_task(name: str) -> Task:
    """The task registered as ``name`` (one instance per process).

    Raises:
        ConfigError: no task has that name (lists the registered ones).
    """
    if name not in TASKS:
        raise ConfigError(f"unknown task {name!r}: choose one of {', '.join(TASKS)}")
    module, _, cls = TASKS[name].partition(":")
    task: Task = getattr(importlib.import_module(module), cls)()
    if task.name != name:
        raise ConfigError(f"task class {TASKS[name]} is named {task.name!r}, registered {name!r}")
    return task


def tasks() -> list[Task]:
    """Every registered task, in registry order."""
    return [get_task(n) for n in TASKS]


def task_for_scene(scene: Scene) -> Task:
    """The task a scene was made for: the first registered task that claims it
    (:meth:`Task.claims`: its ``task.kind``, or what its objects' roles say), else
    :data:`DEFAULT_TASK`."""
    for task in tasks():
        if task.claims(scene):
            return task
    return get_task(DEFAULT_TASK)


def task_of_scenes(asked: str, scenes: Sequence[Scene]) -> str:
    """The task a stage records in ``scenes``: ``asked`` (``task=``), except that the default
    task stands aside for the one other task that every scene claims (:func:`task_for_scene`:
    a run generated for "open the fridge door" records ``open`` with no ``task=``)."""
    if asked != DEFAULT_TASK or not scenes:
        return asked
    claimed = {task_for_scene(s).name for s in scenes}
    return claimed.pop() if len(claimed) == 1 else asked
