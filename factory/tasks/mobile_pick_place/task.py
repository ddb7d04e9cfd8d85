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
    example_scene: ClassVar[str | None] = "tasks/mobile_pick_place/living_can_to_desk"

    def claims(self, scene: Scene) -> bool:
        """Its ``task.kind`` names the task, or an object is its place support."""
        return super().claims(scene) or any(o.task_role == "place_support" for o in scene.objects)

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request where the robot must travel ("move X from A to B", "bring X to the
        kitchen": ``travel``, :mod:`factory.scenes.task_read`)."""
        return bool(spec.get("travel"))

    def feasibility(self, scene: Scene, assets_root: Any) -> dict[str, Any] | None:
        """The route check (:func:`factory.nav.route.check_route`: both supports reachable
        for the base, a free route between them) with the supports' nearest edges at least
        :data:`~factory.nav.support_gap.MIN_SUPPORT_GAP` apart, so that the robot must drive.
        A scene whose only fault is a smaller gap can still host the task: its verdict is
        ``soft`` (``stage=generate`` tries other seeds and keeps the widest gap if none
        reaches the minimum). ``stage=validate`` reports the route itself
        (``validate.checks.route``)."""
        from factory.nav.route import PLACE_SUPPORT_TOO_CLOSE, check_route
        from factory.nav.support_gap import MIN_SUPPORT_GAP
        from factory.sim.compile import compile_scene

        model = compile_scene(scene, assets_root).model
        verdict = check_route(scene, model=model, min_gap=MIN_SUPPORT_GAP)
        if verdict.reason == PLACE_SUPPORT_TOO_CLOSE:
            route = check_route(scene, model=model)  # the centres' distance and the rest
            if route.ok:
                return {
                    **route.as_dict(),
                    "reason": verdict.reason,
                    "detail": verdict.detail,
                    "soft": True,
                }
        return verdict.as_dict()

    # -- demos ----------------------------------------------------------------------------------
    # set-up, planner, simulation and stored episode: factory.tasks.mobile_pick_place.demos
    # (demo_scene)

    demo_execution: ClassVar[str] = "episode"

    # -- dataset --------------------------------------------------------------------------------
    # the features and card lines: factory.tasks.mobile_pick_place.dataset

    def dataset_meta(self) -> dict[str, Any]:
        """``layout``, the sub-task names, the state's and action's column names."""
        from factory.tasks.mobile_pick_place.dataset import meta

        return meta()

    def card_tags(self) -> tuple[str, ...]:
        """``mobile-manipulation``."""
        from factory.tasks.mobile_pick_place.dataset import TAGS

        return TAGS

    # -- policy ---------------------------------------------------------------------------------

    # the env's observations, action bounds and simulation: factory.tasks.mobile_pick_place.env

    env_max_steps: ClassVar[int] = 1500
    robot_kind: ClassVar[str] = "mobile"

    def env_state_dim(self) -> int:
        """The pick object's and the place support's world poses: 14 (the fixed task's
        layout)."""
        from factory.tasks.pick_place.env import ENV_STATE_DIM

        return ENV_STATE_DIM

    def fisheye_cameras(self) -> tuple[str, ...]:
        """``fisheye_front``, ``fisheye_back``."""
        from factory.tasks.mobile_pick_place.scene import FISHEYE_CAMERAS

        return tuple(FISHEYE_CAMERAS)

    def env_cameras(self) -> tuple[str, ...]:
        """``left``, ``right``, ``wrist``, then the fisheye cameras."""
        from factory.tasks.mobile_pick_place.scene import ALL_CAMERAS

        return ALL_CAMERAS

    def env_scene(self, run_dir: Any, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """The demos' set-up and planner (
        :func:`factory.tasks.mobile_pick_place.demos.mobile_scene_planner`); a scene where the base
        cannot reach both supports raises TaskError."""
        from factory.errors import TaskError
        from factory.tasks.mobile_pick_place.demos import mobile_scene_planner

        setup, planner = mobile_scene_planner(run_dir, scene_id, dc)
        if planner.unusable:
            raise TaskError(f"the robot's base cannot work in {scene_id!r}: {planner.unusable}")
        return setup, planner

    def env_instruction(self, setup: Any) -> str:
        """The scene's instruction, else "pick up the <pick> and put it on the <support>"."""
        from factory.tasks.mobile_pick_place.env import instruction

        return instruction(setup)

    def env_sim(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any | None:
        """:class:`~factory.tasks.mobile_pick_place.env.MobileSim` (episodes stepped one
        physics step at a time, as the demos simulate them)."""
        from factory.tasks.mobile_pick_place.env import MobileSim

        return MobileSim(setup, planner, num_envs, spec, interpolate)

    def claims_features(self, features: Any) -> bool:
        """A policy that reads ``subtask_index``."""
        from factory.tasks.mobile_pick_place.env import SUBTASK_KEY

        return SUBTASK_KEY in features

    def subtasks(self) -> tuple[str, ...]:
        """``navigate_to_pick``, ``pick``, ``navigate_to_place``, ``place``."""
        from factory.tasks.mobile_pick_place.scene import SUBTASKS

        return SUBTASKS

    def eval_identity(self) -> dict[str, Any]:
        """The task's name."""
        return {"task": self.name}

    def eval_notes(self) -> dict[str, Any]:
        """The task's name and how the env ends sub-tasks."""
        from factory.tasks.mobile_pick_place.env import SUBTASK_RULE

        return {"task": self.name, "subtask_rule": SUBTASK_RULE}
