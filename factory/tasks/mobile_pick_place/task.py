"""The mobile pick-and-place task: the Panda on the Omron base drives to an object, picks it,
carries it to another support and places it (:mod:`factory.tasks.mobile_pick_place`: scene,
planning, execution)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from factory.tasks.base import Task

if TYPE_CHECKING:
    from factory.schema import Scene

__all__ = ["MobilePickPlaceTask"]


class MobilePickPlaceTask(Task):
    """``task=mobile_pick_place``."""

    name: ClassVar[str] = "mobile_pick_place"
    description: ClassVar[str] = (
        "drive to an object, pick it, carry it to another support, place it"
    )

    # -- scenes ---------------------------------------------------------------------------------

    drives_base: ClassVar[bool] = True

    def claims(self, scene: Scene) -> bool:
        """Its ``task.kind`` names the task, or an object is its place support."""
        return super().claims(scene) or any(o.task_role == "place_support" for o in scene.objects)

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """ "Move X from A to B": a request with a source support."""
        return bool(spec.get("source"))

    # -- demos ----------------------------------------------------------------------------------

    # -- dataset --------------------------------------------------------------------------------

    # -- policy ---------------------------------------------------------------------------------
