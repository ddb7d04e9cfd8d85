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

    example_request: ClassVar[str | None] = (
        "a kitchen where the robot picks up a mug and puts it in the bowl"
    )

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """A request without a source support ("put the mug in the bowl")."""
        return not spec.get("source")

    # -- demos ----------------------------------------------------------------------------------
    # set-up, planner and stored episode: factory.tasks.pick_place.demos

    demo_execution: ClassVar[str] = "batch"

    def demo_scene(self, env: Any, scene_id: str, plan: bool = True) -> Any:
        """The scene with the Panda at its base spot (:class:`~factory.tasks.pick_place.demos.
        PickPlaceScene`)."""
        from factory.tasks.pick_place.demos import demo_scene

        return demo_scene(env, scene_id, plan)

    # -- dataset --------------------------------------------------------------------------------
    # the features and card lines: factory.tasks.pick_place.dataset

    def dataset_layout(self) -> str:
        """``fixed`` (its datasets hold no ``layout``: written before there were two)."""
        from factory.tasks.pick_place.dataset import LAYOUT

        return LAYOUT

    def robot_type(self) -> str:
        """``franka_panda``."""
        from factory.tasks.pick_place.dataset import ROBOT_TYPE

        return ROBOT_TYPE

    def dataset_features(self) -> dict[str, dict[str, Any]]:
        """The arm's state, tool pose, the objects' poses, the arm's action."""
        from factory.tasks.pick_place.dataset import features

        return features()

    def episode_arrays(self, n_frames: int) -> dict[str, tuple[int, ...]]:
        """The arm's arrays (``env_state``, absent from older stores, is checked when read)."""
        from factory.tasks.pick_place.dataset import arrays_of

        return arrays_of(n_frames)

    def episode_columns(self, info: Any, arrays: Any, scene_json: bytes) -> dict[str, Any]:
        """The arrays, and the objects' poses from the MuJoCo states of older stores."""
        from factory.tasks.pick_place.dataset import columns

        return columns(info, arrays, scene_json)

    def dataset_card(
        self, meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]
    ) -> tuple[str, list[str]]:
        """Franka Panda demonstrations; the features and extras."""
        from factory.tasks.pick_place.dataset import card

        return card(meta, cameras, rgb)

    # -- policy ---------------------------------------------------------------------------------

    # the env's rules and observations: factory.tasks.pick_place.env

    robot_kind: ClassVar[str] = "fixed-base"

    def env_state_dim(self) -> int:
        """The pick object's and the target's poses: 14."""
        from factory.tasks.pick_place.env import ENV_STATE_DIM

        return ENV_STATE_DIM

    def env_cameras(self) -> tuple[str, ...]:
        """``left``, ``right``, ``wrist``."""
        from factory.tasks.pick_place.env import CAMERAS

        return CAMERAS

    def env_observations(self) -> dict[str, tuple[tuple[int, ...], str]]:
        """The arm's state (8) and the tool pose (7)."""
        from factory.tasks.pick_place.env import OBSERVATIONS

        return dict(OBSERVATIONS)

    def env_action_bounds(self) -> tuple[Any, Any]:
        """Arm joint targets within the Panda's limits (rad), the gripper command from
        squeezing shut to open (m)."""
        from factory.tasks.pick_place.env import action_bounds

        return action_bounds()

    def env_scene(self, run_dir: Any, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """The demos' set-up and planner (:func:`factory.tasks.pick_place.demos.
        scene_planner`)."""
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
