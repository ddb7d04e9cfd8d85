"""What ``stage=demos`` records of the fixed-base task: a scene of a run composed with the
Panda at its base spot and the scene's planner (:func:`scene_planner`, also the evaluation
env's set-up), and :class:`PickPlaceScene`, the :class:`~factory.demos.record.scene.DemoScene`
the demos machinery plans and stores with (its plans run together on a batch of worlds:
``demo_execution = "batch"``).

Stored episodes fill :class:`~factory.schema.episode.EpisodeInfo`'s ``pick_id``,
``target_id``, ``support_id``, ``robot`` (the base spot), ``frozen``, ``appearance`` and the
left and right cameras' calibration (``camera_poses``, ``camera_fovy``), and
add the ``env_state`` array (F, 14): the pick object's and the target's poses.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from factory.config import DemosConfig
from factory.demos.record.payload import episode_arrays, episode_meta
from factory.demos.record.scene import DemoScene
from factory.demos.record.slots import StageEnv
from factory.schema.episode import EpisodeInfo, RobotBase
from factory.tasks.pick_place.plan import EpisodePlan, EpisodePlanner, SceneSetup

__all__ = ["PickPlaceScene", "demo_scene", "episode_instruction", "scene_planner", "scene_setup"]


def scene_setup(run_dir: str | Path, scene_id: str, dc: DemosConfig) -> SceneSetup:
    """A scene of a run composed with the robot as ``stage=demos`` records it: the base spot,
    cleared objects and cameras of :func:`~factory.tasks.pick_place.plan.setup_scene`
    (deterministic per scene), objects beyond ``demos.freeze_beyond`` static, island sleeping
    as ``demos.sleep`` says.

    Raises:
        TaskError: the scene cannot host the task (objects missing, no base spot).
    """
    import mujoco

    from factory.store import RunStore
    from factory.tasks.pick_place.plan import LOOKALIKE_RADIUS, setup_scene

    store = RunStore(run_dir)
    scene = store.load_scene(scene_id)
    setup = setup_scene(
        scene,
        store.assets_dir,
        freeze_beyond=dc.freeze_beyond,
        lookalike_radius=getattr(dc, "lookalike_radius", LOOKALIKE_RADIUS),
    )
    if not dc.sleep:
        setup.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return setup


def scene_planner(
    run_dir: str | Path, scene_id: str, dc: DemosConfig
) -> tuple[SceneSetup, EpisodePlanner]:
    """:func:`scene_setup` and its planner, whose timing, timeout and grasp count follow
    ``demos.*``: what ``stage=demos`` plans in and the evaluation env simulates.

    Raises:
        TaskError: the scene cannot host the task (objects missing, no base spot).
    """
    from factory.demos.plan.planner import PlannerConfig
    from factory.tasks.pick_place.plan import MotionConfig

    setup = scene_setup(run_dir, scene_id, dc)
    motion = MotionConfig(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    planner = EpisodePlanner(
        setup,
        planner_cfg=PlannerConfig(timeout=dc.plan_timeout),
        motion=motion,
        max_grasps=dc.max_grasps,
        grasp_facing=dc.grasp_facing,
    )
    return setup, planner


def episode_instruction(setup: SceneSetup) -> str:
    """The scene's task instruction, else one made from the task objects."""
    scene, objects = setup.scene, setup.objects
    if scene.task and scene.task.instruction:
        return str(scene.task.instruction)
    return (
        f"put the {objects.pick.category.replace('_', ' ')} {objects.relation} the "
        f"{objects.target.category.replace('_', ' ')}"
    )


class PickPlaceScene(DemoScene):
    """A scene of the fixed-base task set up for ``stage=demos`` (its plans run together on
    a batch of worlds)."""

    plan_type: ClassVar[type[Any]] = EpisodePlan
    setup: SceneSetup

    def __init__(self, env: StageEnv, setup: SceneSetup, planner: EpisodePlanner | None) -> None:
        super().__init__(env, setup, planner)
        self.instruction = episode_instruction(setup)

    def summary(self) -> dict[str, Any]:
        """The robot's base spot (x, y m, yaw rad) and the objects taken out for it."""
        p = self.setup.placement
        return {"robot_base": [p.x, p.y, p.yaw], "cleared": list(self.setup.cleared)}

    def plan(self, seed: int) -> Any:
        """:meth:`~factory.tasks.pick_place.plan.EpisodePlanner.plan_episode` with new object
        poses when ``demos.randomize``."""
        assert self.planner is not None, "a scene set up without its planner"
        return self.planner.plan_episode(seed, self.env.demos.randomize)

    def payload(
        self, slot: int, seed: int, plan: Any, rec: Any, rec_cfg: Any, recorder: str = "cpu"
    ) -> tuple[EpisodeInfo, dict[str, np.ndarray]]:
        """The episode with its task objects, base spot, frozen objects, appearance, the
        calibration of its cameras fixed in the scene (``camera_poses``, ``camera_fovy``) and
        the objects' poses (``env_state``)."""
        setup = self.setup
        objects = setup.objects
        placement = setup.placement
        meta = episode_meta(
            setup,
            slot,
            seed,
            plan,
            rec,
            task=self.env.task,
            instruction=self.instruction,
            rec_cfg=rec_cfg,
            recorder=recorder,
            pick_id=objects.pick.id,
            target_id=objects.target.id,
            support_id=objects.support.id,
            robot=RobotBase(placement.x, placement.y, placement.z, placement.yaw),
            frozen=list(getattr(setup, "frozen", ())),
            appearance=getattr(rec, "appearance", None),
            camera_poses=dict(getattr(rec, "camera_poses", {})),
            camera_fovy=dict(getattr(rec, "camera_fovy", {})),
        )
        return meta, episode_arrays(rec, env_state=rec.env_state.astype(np.float32))


def demo_scene(env: StageEnv, scene_id: str, plan: bool = True) -> PickPlaceScene:
    """:meth:`factory.tasks.pick_place.task.PickPlaceTask.demo_scene`.

    Raises:
        TaskError: the scene cannot host the task.
    """
    if plan:
        setup, planner = scene_planner(env.run_dir, scene_id, env.demos)
        return PickPlaceScene(env, setup, planner)
    return PickPlaceScene(env, scene_setup(env.run_dir, scene_id, env.demos), None)
