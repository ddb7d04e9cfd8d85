"""The fixed-base pick-and-place task: the Panda on its pedestal picks an object and puts it
in or on a target (:mod:`factory.tasks.pick_place.objects`: task objects, base spot, episode
poses, success; :mod:`factory.tasks.pick_place.plan`: grasp, IK, RRTConnect, ruckig)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

from factory.tasks.base import Task

__all__ = ["PickPlaceTask"]


class PickPlaceTask(Task):
    """``task=pick_place``."""

    name: ClassVar[str] = "pick_place"
    description: ClassVar[str] = "pick up an object and put it in or on a target"

    # -- scenes ---------------------------------------------------------------------------------

    example_request: ClassVar[str | None] = (
        "a kitchen where the robot picks up a mug and puts it in the bowl"
    )

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request the robot serves without travelling ("put the mug in the bowl", "pick
        up the mug from the table and put it in the bowl": an object to pick, ``travel``
        false)."""
        return bool(spec.get("pick")) and not spec.get("travel")

    def feasibility(self, scene: Any, assets_root: Any) -> dict[str, Any] | None:
        """A free base spot and room for the task objects within reach
        (:func:`factory.tasks.pick_place.feasibility.feasibility`)."""
        from factory.tasks.pick_place.feasibility import feasibility

        return feasibility(scene, assets_root)

    # -- demos ----------------------------------------------------------------------------------
    # set-up, planner and stored episode: factory.tasks.pick_place.demos (demo_scene)

    demo_execution: ClassVar[str] = "batch"

    # -- dataset and policy ---------------------------------------------------------------------
    # the features and card lines: factory.tasks.pick_place.dataset; the env's observations,
    # action bounds and rules: factory.tasks.pick_place.env

    robot_kind: ClassVar[str] = "fixed-base"

    def env_state_dim(self) -> int:
        """The pick object's and the target's poses: 14."""
        from factory.tasks.pick_place.env import ENV_STATE_DIM

        return ENV_STATE_DIM

    def env_cameras(self) -> tuple[str, ...]:
        """``left``, ``right``, ``wrist``."""
        from factory.tasks.pick_place.env import CAMERAS

        return CAMERAS

    def calibrated_cameras(self, cameras: Sequence[str]) -> tuple[str, ...]:
        """The left and right cameras among ``cameras``: fixed in the world, placed per scene
        (:data:`~factory.robots.panda.SCENE_CAMERAS`); the wrist camera's pose is forward
        kinematics."""
        from factory.robots.panda import SCENE_CAMERAS

        return tuple(c for c in cameras if c in SCENE_CAMERAS)

    def camera_calibration(
        self, setup: Any, cameras: Sequence[str]
    ) -> tuple[dict[str, list[float]], dict[str, float]]:
        """:func:`factory.tasks.pick_place.plan.camera_calibration` without a patch."""
        from factory.tasks.pick_place.plan import camera_calibration

        return camera_calibration(setup, self.calibrated_cameras(cameras))

    def env_scene(self, run_dir: Any, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """The demos' set-up and planner (
        :func:`factory.tasks.pick_place.demos.scene_planner`)."""
        from factory.tasks.pick_place.demos import scene_planner

        return scene_planner(run_dir, scene_id, dc)

    def env_instruction(self, setup: Any) -> str:
        """The scene's instruction, else "put the <pick> <in/on> the <target>"."""
        from factory.tasks.pick_place.demos import episode_instruction

        return episode_instruction(setup)

    def env_rules(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any:
        """:class:`~factory.tasks.pick_place.env.PickPlaceRules`."""
        from factory.tasks.pick_place.env import PickPlaceRules

        return PickPlaceRules(setup, planner, num_envs, spec.fps, interpolate)
