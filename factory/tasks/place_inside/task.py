"""``task=place_inside``: the Panda on its pedestal puts a small object away in a drawer or
behind a door: it opens the drawer (door) by its handle, picks the object from the top above,
places it on the drawer's floor (the shelf or floor behind the door), lets go, and closes the
drawer (door).

The package reuses the articulated tasks' machinery (:mod:`factory.tasks.articulated`: the
part, the base spot, the handle motions, recording) and the pick-and-place task's (grasps,
free motions, the controller): :mod:`~factory.tasks.place_inside.plan` (which part and object,
the episode's plan), :mod:`~factory.tasks.place_inside.execute` (an episode on one ``MjData``,
the success check), :mod:`~factory.tasks.place_inside.demos`,
:mod:`~factory.tasks.place_inside.dataset` and :mod:`~factory.tasks.place_inside.env`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

from factory.tasks.base import Task

__all__ = ["PlaceInsideTask"]


class PlaceInsideTask(Task):
    """``task=place_inside``."""

    name: ClassVar[str] = "place_inside"
    description: ClassVar[str] = (
        "put a small object in a drawer or behind a door (microwave, fridge, cabinet): open it, "
        "place the object inside, close it"
    )
    example_scene: ClassVar[str | None] = "tasks/place_inside/kitchen_cabinet_can_drawer"
    demo_execution: ClassVar[str] = "episode"
    robot_kind: ClassVar[str] = "fixed-base"

    articulated_assets: ClassVar[bool] = True

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request to put an object away in a drawer or behind a door ("put the mug in the
        drawer of the base cabinet", "put the mug in the microwave": the ``PartSpec`` fields
        of :mod:`factory.scenes.part_read` with an ``item`` and the role ``drawer`` or
        ``door``); a place target that is neither ("puts it in the bowl") is
        pick-and-place's."""
        return bool(spec.get("item_named")) and spec.get("role") in ("drawer", "door")

    def dataset_meta(self) -> dict[str, Any]:
        """``layout`` (a dataset without it is the default task's)."""
        return {"layout": self.dataset_layout()}

    def card_tags(self) -> tuple[str, ...]:
        """``articulated``, ``pick-and-place``."""
        return ("articulated", "pick-and-place")

    def env_state_dim(self) -> int:
        """The part's joint and share of range, the object's position and quaternion: 9."""
        return 9

    def env_cameras(self) -> tuple[str, ...]:
        """``left``, ``right``, ``wrist``."""
        from factory.tasks.place_inside.env import CAMERAS

        return CAMERAS

    def calibrated_cameras(self, cameras: Sequence[str]) -> tuple[str, ...]:
        """The left and right cameras among ``cameras`` (fixed in the world)."""
        from factory.robots.panda import SCENE_CAMERAS

        return tuple(c for c in cameras if c in SCENE_CAMERAS)

    def camera_calibration(
        self, setup: Any, cameras: Sequence[str]
    ) -> tuple[dict[str, list[float]], dict[str, float]]:
        """:func:`factory.tasks.articulated.plan.camera_calibration` of the set-up's rig."""
        from factory.tasks.articulated.plan import camera_calibration

        return camera_calibration(setup.art, self.calibrated_cameras(cameras))

    def env_scene(self, run_dir: Any, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """The demos' set-up and planner (:func:`factory.tasks.place_inside.demos.
        scene_planner`)."""
        from factory.tasks.place_inside.demos import scene_planner

        return scene_planner(run_dir, scene_id, dc)

    def env_instruction(self, setup: Any) -> str:
        """The scene's instruction, else "put the <object> in <the part>"."""
        return str(setup.instruction())

    def env_rules(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any:
        """:class:`~factory.tasks.place_inside.env.PlaceInsideRules`."""
        from factory.tasks.place_inside.env import PlaceInsideRules

        return PlaceInsideRules(setup, planner, num_envs, spec.fps, interpolate)
