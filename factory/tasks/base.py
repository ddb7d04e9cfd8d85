"""The :class:`Task` protocol: the hooks that the task-agnostic machinery calls.

The machinery is written once and takes a task: scene generation, augmentation and validation
ask it what a scene must hold (:meth:`Task.claims`, :meth:`Task.scene_check`); ``stage=demos``
(one stage, one CPU item loop, one GPU pipeline) asks it to plan and record episodes; the
LeRobot export takes its features; the evaluation env its set-up, observations, actions and
success check. Hooks are grouped by the floor that calls them; a hook's heavy imports happen
inside it, so that the lower floors can hold a task without loading its planner.

A task class sets :attr:`Task.name` (its registry key, :data:`factory.tasks.TASKS`) and
:attr:`Task.description`, and fills the hooks; like ManiSkill's ``_load_scene`` /
``_initialize_episode`` / ``evaluate``, each hook is one question about the task.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:
    from factory.schema import Scene

__all__ = ["Task"]


class Task:
    """A robot task (subclass per task; one instance per process, :func:`~factory.tasks.
    get_task`)."""

    name: ClassVar[str]
    """Registry key: ``task=<name>`` on the command line, ``task.kind`` in ``scene.json``."""

    description: ClassVar[str]
    """One line: what the robot does (``stage=list`` and the run report show it)."""

    # -- scenes: generation, augmentation, validation (floors 4-5) -----------------------------

    def claims(self, scene: Scene) -> bool:
        """Whether ``scene`` was made for this task (by default: its ``task.kind`` names it)."""
        return scene.task is not None and scene.task.kind == self.name

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """Whether a parsed request's task (the ``TaskSpec`` fields of
        :mod:`factory.scenes.request`: ``pick``, ``place``, ``source``, ...) asks for this
        task; the scene agent writes the matching task's name as the scene's ``task.kind``."""
        return False

    drives_base: ClassVar[bool] = False
    """The robot drives between supports: a scene made for the task needs a route for its base
    (:mod:`factory.nav.route`: checked by the generation critic, ``stage=validate`` and the
    configuration variants)."""

    # -- demos: stage=demos, one CPU item loop and one GPU pipeline (floor 7) ------------------

    # -- dataset: the LeRobot export (floor 8) --------------------------------------------------

    # -- policy: the evaluation env, training inputs, lerobot plugin (floor 9) ------------------
