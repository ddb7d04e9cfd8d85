"""The articulated tasks' shared class: the Panda on its pedestal opens or closes a named part
of an articulated object (a drawer, a cabinet or fridge door) by its handle.

``task=open`` (:class:`~factory.tasks.open.task.OpenTask`) and ``task=close``
(:class:`~factory.tasks.close.task.CloseTask`) are two registered tasks, each its own package
with its class; both read their hooks' data from this package (:meth:`ArticulatedTask.part`):
:mod:`~factory.tasks.articulated.parts` (which part a scene's episodes act on),
:mod:`~factory.tasks.articulated.plan` (base spot, handle grasp, IK along the joint, ruckig),
:mod:`~factory.tasks.articulated.execute` (an episode on one ``MjData``, the success check),
:mod:`~factory.tasks.articulated.demos`, :mod:`~factory.tasks.articulated.dataset` and
:mod:`~factory.tasks.articulated.env`. This package is no task: it is not in the registry.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from factory.tasks.base import Task

if TYPE_CHECKING:
    from types import ModuleType

__all__ = ["ArticulatedTask"]


class ArticulatedTask(Task):
    """``task=open`` / ``task=close`` (subclass per direction)."""

    direction: ClassVar[str]
    """``open`` or ``close``: where the part starts and where the robot moves it."""

    layout: ClassVar[str]
    """The layout of the task's datasets (``meta/factory.json``'s ``layout``)."""

    def part(self, module: str) -> ModuleType:
        """The shared package's module ``module`` (:mod:`factory.tasks.articulated`)."""
        return importlib.import_module(f"factory.tasks.articulated.{module}")

    # -- scenes ---------------------------------------------------------------------------------

    articulated_assets: ClassVar[bool] = True

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request to move a part the task's way ("open the fridge door", "close the top
        drawer of the nightstand": the ``PartSpec`` fields of
        :mod:`factory.scenes.part_read`, its ``verb`` one of :attr:`request_verbs`)."""
        return spec.get("verb") in self.request_verbs and bool(spec.get("role"))

    def feasibility(self, scene: Any, assets_root: Any) -> dict[str, Any] | None:
        """The demos' set-up (:func:`factory.tasks.articulated.plan.setup_scene`, at the
        default ``demos.freeze_beyond``): a part the scene's instruction names that the robot
        can work from a free base spot, with the whole motion planned from its hardest start;
        its failure's message is the verdict's ``detail``."""
        from factory.config import DemosConfig
        from factory.errors import TaskError
        from factory.tasks.articulated.plan import setup_scene

        try:
            setup = setup_scene(
                scene, assets_root, self.direction, freeze_beyond=DemosConfig().freeze_beyond
            )
        except TaskError as e:
            return {"reason": "no_workable_part", "detail": str(e)}
        return {"reason": "", "detail": f"{setup.part.key} ({setup.part.label})"}

    # -- demos ----------------------------------------------------------------------------------

    demo_execution: ClassVar[str] = "episode"

    # -- dataset and policy ---------------------------------------------------------------------

    robot_kind: ClassVar[str] = "fixed-base"

    def dataset_layout(self) -> str:
        """:attr:`layout`."""
        return self.layout

    def dataset_meta(self) -> dict[str, Any]:
        """``layout`` (a dataset without it is the default task's)."""
        return {"layout": self.layout}

    def card_tags(self) -> tuple[str, ...]:
        """``articulated`` and the direction."""
        return ("articulated", self.direction)

    def env_state_dim(self) -> int:
        """The part's joint and its handle seen from the robot:
        :data:`~factory.tasks.articulated.execute.ENV_STATE_DIM` (11)."""
        from factory.tasks.articulated.execute import ENV_STATE_DIM

        return ENV_STATE_DIM

    def env_cameras(self) -> tuple[str, ...]:
        """``left``, ``right``, ``wrist``."""
        from factory.tasks.articulated.env import CAMERAS

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

        return camera_calibration(setup, self.calibrated_cameras(cameras))

    def env_scene(self, run_dir: Any, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """The demos' set-up and planner (:func:`factory.tasks.articulated.demos.
        scene_planner`)."""
        from factory.tasks.articulated.demos import scene_planner

        return scene_planner(run_dir, scene_id, dc, self.direction)

    def env_instruction(self, setup: Any) -> str:
        """The scene's instruction, else "<open|close> <the part>"."""
        from factory.tasks.articulated.demos import episode_instruction

        return episode_instruction(setup)

    def env_rules(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any:
        """:class:`~factory.tasks.articulated.env.ArticulatedRules` (the env steps the worlds
        together on one batch, as the fixed task's)."""
        from factory.tasks.articulated.env import ArticulatedRules

        return ArticulatedRules(setup, planner, num_envs, spec.fps, interpolate)

    def claims_features(self, features: Any) -> bool:
        """Never by features alone: the two tasks' policies read the same features (the
        dataset's layout tells them apart)."""
        return False
