"""The fixed-base pick-and-place task: the Panda on its pedestal picks an object and puts it
in or on a target (:mod:`factory.tasks.pick_place.objects`: task objects, base spot, episode
poses, success; :mod:`factory.tasks.pick_place.plan`: grasp, IK, RRTConnect, ruckig)."""

from __future__ import annotations

from typing import Any, ClassVar

from factory.tasks.base import Task

__all__ = ["PickPlaceTask"]


class PickPlaceTask(Task):
    """``task=pick_place``."""

    name: ClassVar[str] = "pick_place"
    description: ClassVar[str] = "pick up an object and put it in or on a target"

    # -- scenes ---------------------------------------------------------------------------------

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request without a source support ("put the mug in the bowl")."""
        return not spec.get("source")

    # -- demos ----------------------------------------------------------------------------------

    # -- dataset --------------------------------------------------------------------------------

    # -- policy ---------------------------------------------------------------------------------
