"""What ``stage=demos`` records of the mobile task: a scene of a run composed with the mobile
robot and its planner (:func:`mobile_scene_planner`, also the evaluation env's set-up), and
:class:`MobilePickPlaceScene`, the :class:`~factory.demos.record.scene.SimulatingScene` the
demos machinery plans, simulates and stores with (``demo_execution = "episode"``: an episode
at a time on one ``MjData``, :func:`~factory.tasks.mobile_pick_place.execute.execute_mobile`).

The cameras are ``demos.cameras`` (pinhole, on the robot) plus both fisheye cameras;
``demos.randomize`` does not apply. Stored episodes keep the fixed task's
:class:`~factory.schema.episode.EpisodeInfo` fields and fill ``route`` (the route check's pick and
place poses the drives ended at, their indices in the route's lists, its pose counts, grid cell and
footprint; :meth:`~factory.tasks.mobile_pick_place.plan.MobilePlanner.route_record`): ``pick_id`` is
the object, ``support_id`` the pick support, ``target_id`` the place support, ``robot`` the spawn
pose (z = 0), ``phases`` the first frame of each phase (sub-tasks included), ``cameras`` the pinhole
cameras then ``fisheye_front`` / ``fisheye_back``. Arrays: as the fixed task's (``time``, ``state``,
``joint_pos``, ``gripper``, ``ee_pose``, ``rgb/<camera>``, ``depth/<camera>``), with ``action`` of
11 columns (arm 7, gripper, base x, y, yaw) instead of 8, and in addition ``base_pose`` (F, 3),
``subtask`` (F,) int8 (index into ``SUBTASKS``), ``subtask_done`` (F,) bool and, as the fixed
task's, ``env_state`` (F, 14): the pick object's and the place support's world poses (stores
recorded before it have none: the export reads the poses of free bodies from ``state``).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from factory.config import DemosConfig
from factory.demos.record.payload import episode_arrays, episode_meta
from factory.demos.record.rig import CameraRig
from factory.demos.record.scene import SimulatingScene
from factory.demos.record.slots import StageEnv
from factory.errors import TaskError
from factory.schema.episode import EpisodeInfo, RobotBase
from factory.tasks.mobile_pick_place.execute import (
    MobileRecordConfig,
    MobileRecording,
    MobileRenderer,
    camera_rig,
    execute_mobile,
)
from factory.tasks.mobile_pick_place.plan import MobileEpisodePlan, MobilePlanner
from factory.tasks.mobile_pick_place.scene import FISHEYE_CAMERAS, MobileSetup, mobile_setup

__all__ = ["MobilePickPlaceScene", "demo_scene", "mobile_scene_planner", "record_config"]

log = logging.getLogger(__name__)


def mobile_scene_planner(
    run_dir: str | Path, scene_id: str, dc: DemosConfig
) -> tuple[MobileSetup, MobilePlanner]:
    """A scene of a run composed with the mobile robot, and its planner with the demos
    settings ``dc`` (``demos.*``): what ``stage=demos`` plans in and what the closed-loop env
    (:mod:`factory.tasks.mobile_pick_place.env`) simulates.

    Raises:
        FactoryError: the scene cannot be loaded or cannot host the task.
    """
    from factory.demos.plan.planner import PlannerConfig
    from factory.store import RunStore
    from factory.tasks.mobile_pick_place.plan import MobileMotionConfig
    from factory.tasks.pick_place.plan import MotionConfig

    run_store = RunStore(run_dir)
    setup = mobile_setup(run_store.load_scene(scene_id), run_store.assets_dir)
    motion = MobileMotionConfig(
        arm=MotionConfig(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    )
    planner = MobilePlanner(
        setup,
        motion,
        planner_cfg=PlannerConfig(timeout=dc.plan_timeout),
        max_grasps=dc.max_grasps,
        grasp_facing=dc.grasp_facing,
    )
    return setup, planner


def record_config(dc: DemosConfig, render: bool | None = None) -> MobileRecordConfig:
    """The mobile recording settings of ``demos.*``: the pinhole ``demos.cameras`` plus both
    fisheye cameras (``render``: overrides ``demos.render``)."""
    return MobileRecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=(*dc.cameras, *FISHEYE_CAMERAS),
        depth=dc.depth,
        render=dc.render if render is None else render,
    )


class MobilePickPlaceScene(SimulatingScene):
    """A scene of the mobile task set up for ``stage=demos`` (its episodes simulated one at a
    time)."""

    plan_type: ClassVar[type[Any]] = MobileEpisodePlan
    setup: MobileSetup

    def plan(self, seed: int) -> Any:
        """:meth:`~factory.tasks.mobile_pick_place.plan.MobilePlanner.plan_episode`."""
        assert self.planner is not None, "a scene set up without its planner"
        return self.planner.plan_episode(seed)

    def record_config(self, render: bool | None = None) -> MobileRecordConfig:
        return record_config(self.env.demos, render)

    def renderer(self, rec_cfg: MobileRecordConfig) -> MobileRenderer:
        return MobileRenderer(self.setup.model, rec_cfg)

    def camera_rig(self, rec_cfg: MobileRecordConfig) -> CameraRig:
        """The robot's cameras :meth:`renderer` draws, three pinhole and two fisheye
        (:func:`~factory.tasks.mobile_pick_place.execute.camera_rig`)."""
        return camera_rig(rec_cfg)

    def simulate(self, plan: Any, rec_cfg: Any, renderer: Any | None = None) -> MobileRecording:
        """:func:`~factory.tasks.mobile_pick_place.execute.execute_mobile`."""
        return execute_mobile(self.setup, plan, rec_cfg, renderer)

    def payload(
        self, slot: int, seed: int, plan: Any, rec: Any, rec_cfg: Any, recorder: str = "cpu"
    ) -> tuple[EpisodeInfo, dict[str, np.ndarray]]:
        """The episode with its objects and supports, spawn pose, route, base poses and
        sub-task labels."""
        setup = self.setup
        objs = setup.objects
        scene = setup.scene
        instruction = (
            scene.task.instruction
            if scene.task is not None and scene.task.instruction
            else f"pick up the {objs.pick.category} and put it on the {objs.place_support.category}"
        )
        assert rec.outcome is not None
        meta = episode_meta(
            setup,
            slot,
            seed,
            plan,
            rec,
            task=self.env.task,
            instruction=instruction,
            rec_cfg=rec_cfg,
            recorder=recorder,
            pick_id=objs.pick.id,
            target_id=objs.place_support.id,
            support_id=objs.pick_support.id,
            robot=RobotBase(float(plan.spawn[0]), float(plan.spawn[1]), 0.0, float(plan.spawn[2])),
            route=dict(plan.route),
        )
        arrays = episode_arrays(
            rec,
            base_pose=rec.base_pose.astype(np.float32),
            subtask=rec.subtask.astype(np.int8),
            subtask_done=rec.subtask_done.astype(bool),
            env_state=rec.env_state.astype(np.float32),
        )
        return meta, arrays


def demo_scene(env: StageEnv, scene_id: str, plan: bool = True) -> MobilePickPlaceScene:
    """:meth:`factory.tasks.mobile_pick_place.task.MobilePickPlaceTask.demo_scene`; with its
    planner, logs the set-up time and the objects taken out for the base.

    Raises:
        FactoryError: the scene cannot be loaded or cannot host the task (also: the base
            cannot work at both supports).
    """
    if not plan:
        from factory.store import RunStore

        store = RunStore(env.run_dir)
        setup = mobile_setup(store.load_scene(scene_id), store.assets_dir)
        return MobilePickPlaceScene(env, setup, None)
    t0 = time.perf_counter()
    setup, planner = mobile_scene_planner(env.run_dir, scene_id, env.demos)
    if planner.unusable:
        raise TaskError(f"the robot's base cannot work there: {planner.unusable}")
    log.info(
        "scene %s: set up in %.1f s%s",
        scene_id,
        time.perf_counter() - t0,
        f", took out {', '.join(setup.cleared)} for the base" if setup.cleared else "",
    )
    return MobilePickPlaceScene(env, setup, planner)
