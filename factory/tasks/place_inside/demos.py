"""What ``stage=demos`` records of ``task=place_inside``: a scene of a run composed with the
Panda in front of the container part (:func:`scene_planner`, also the evaluation env's set-up)
and :class:`PlaceInsideScene`, the :class:`~factory.demos.record.scene.SimulatingScene` the
demos machinery plans, simulates and stores with (``demo_execution = "episode"``: an episode
at a time on one ``MjData``, :func:`~factory.tasks.place_inside.execute.execute_episode`).

Stored episodes fill :class:`~factory.schema.episode.EpisodeInfo` as the articulated tasks do,
with ``pick_id`` the object put away, ``target_id`` the part (``<object>:<joint>``),
``support_id`` the container, ``robot`` the base spot, ``frozen`` the objects compiled
static, ``grasp_width`` the object grasp's span, ``outcome`` the success check's numbers
(``joint``, ``fraction`` of the range, the object's position in the link's frame
``object_x/y/z``, ``lifted``, ``off_place``, ...). Arrays: the fixed task's (``time``,
``state``, ``joint_pos``, ``gripper``, ``ee_pose``, ``action`` (F, 8)) and ``env_state``
(F, 9): the part's joint position (rad or m) and share of its range, the object's position (m)
and quaternion (wxyz), world frame.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from factory.config import DemosConfig
from factory.demos.record.payload import episode_arrays, episode_meta
from factory.demos.record.scene import SimulatingScene
from factory.demos.record.slots import StageEnv
from factory.schema.episode import EpisodeInfo, RobotBase
from factory.tasks.articulated.demos import ArticulatedScene, ensure_assets
from factory.tasks.place_inside.plan import PlaceInsidePlan, PlaceInsidePlanner, PlaceInsideSetup

__all__ = ["PlaceInsideScene", "demo_scene", "scene_planner", "scene_setup"]

log = logging.getLogger(__name__)


def scene_setup(run_dir: str | Path, scene_id: str, dc: DemosConfig) -> PlaceInsideSetup:
    """A scene of a run composed with the robot in front of its container part as
    ``stage=demos`` records it (:func:`~factory.tasks.place_inside.plan.setup_scene`,
    deterministic per scene; objects beyond ``demos.freeze_beyond`` static). The search runs
    once per scene and run (:func:`~factory.tasks.articulated.setup_record.recorded_setup`).

    Raises:
        TaskError: no object to put away, or no container part the robot can work.
    """
    import mujoco

    from factory.store import RunStore
    from factory.tasks.articulated.setup_record import recorded_setup
    from factory.tasks.place_inside.plan import hint_of, setup_scene

    store = RunStore(run_dir)
    scene = ensure_assets(store.load_scene(scene_id), store.assets_dir)
    setup = recorded_setup(
        run_dir,
        scene_id,
        {"task": "place_inside", "freeze_beyond": dc.freeze_beyond},
        lambda hint: setup_scene(
            scene, store.assets_dir, freeze_beyond=dc.freeze_beyond, hint=hint
        ),
        hint_of,
    )
    if not dc.sleep:
        setup.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return setup


def scene_planner(
    run_dir: str | Path, scene_id: str, dc: DemosConfig
) -> tuple[PlaceInsideSetup, PlaceInsidePlanner]:
    """:func:`scene_setup` and its planner (free-motion speed and RRTConnect timeout from
    ``demos.*``).

    Raises:
        TaskError: no object to put away, no container part the robot can work, or an object
            the gripper cannot take from the container's top
            (:meth:`~factory.tasks.place_inside.plan.PlaceInsidePlanner.check_graspable`).
    """
    from factory.demos.plan.planner import PlannerConfig
    from factory.tasks.articulated.plan import ArticulatedMotion

    setup = scene_setup(run_dir, scene_id, dc)
    motion = ArticulatedMotion(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    planner = PlaceInsidePlanner(setup, motion, PlannerConfig(timeout=dc.plan_timeout))
    planner.check_graspable()
    return setup, planner


class PlaceInsideScene(ArticulatedScene):
    """A scene of ``task=place_inside`` set up for ``stage=demos`` (episodes simulated one at a
    time): the articulated tasks' scene (its planner, renderer, camera rig and recording
    settings) with this task's episode execution, summary and payload."""

    plan_type: ClassVar[type[Any]] = PlaceInsidePlan
    gpu_physics_by_default: ClassVar[bool] = False  # demos.episode_physics=warp takes it
    setup: PlaceInsideSetup  # type: ignore[assignment]  # the articulated set-up inside it

    def __init__(
        self, env: StageEnv, setup: PlaceInsideSetup, planner: PlaceInsidePlanner | None
    ) -> None:
        SimulatingScene.__init__(self, env, setup, planner)  # not the articulated instruction
        self.instruction = setup.instruction()

    def summary(self) -> dict[str, Any]:
        """The robot's base spot (x, y m, yaw rad), the objects taken out, the part
        (``<object>:<joint>``), the object put away and the instruction."""
        p = self.setup.art.placement
        return {
            "robot_base": [p.x, p.y, p.yaw],
            "cleared": list(self.setup.cleared),
            "part": self.setup.art.part.key,
            "object": self.setup.pick.id,
            "instruction": self.instruction,
        }

    def states_recorder(self) -> Any:
        """The episode from its GPU-simulated states
        (:class:`~factory.tasks.place_inside.from_states.PlaceInsideFromStates`)."""
        from factory.tasks.place_inside.from_states import PlaceInsideFromStates

        return PlaceInsideFromStates(self.setup)

    def execute(self, plan: Any, rec_cfg: Any, renderer: Any | None) -> Any:
        """:func:`~factory.tasks.place_inside.execute.execute_episode`."""
        from factory.tasks.place_inside.execute import execute_episode

        return execute_episode(self.setup, plan, rec_cfg, renderer)

    def payload(
        self, slot: int, seed: int, plan: Any, rec: Any, rec_cfg: Any, recorder: str = "cpu"
    ) -> tuple[EpisodeInfo, dict[str, np.ndarray]]:
        """The episode with its object, part, container, base spot, the calibration of its
        cameras fixed in the scene and ``env_state`` (F, 9)."""
        from factory.robots.panda import SCENE_CAMERAS
        from factory.tasks.articulated.plan import camera_calibration

        art = self.setup.art
        p = art.placement
        poses: dict[str, list[float]] = {}
        fovy: dict[str, float] = {}
        if rec_cfg.render:
            cams = tuple(c for c in rec_cfg.cameras if c in SCENE_CAMERAS)
            poses, fovy = camera_calibration(art, cams)
        meta = episode_meta(
            self.setup,
            slot,
            seed,
            plan,
            rec,
            task=self.env.task,
            instruction=self.instruction,
            rec_cfg=rec_cfg,
            recorder=recorder,
            pick_id=self.setup.pick.id,
            target_id=art.part.key,
            support_id=art.part.obj.id,
            robot=RobotBase(p.x, p.y, p.z, p.yaw),
            frozen=list(art.frozen),
            camera_poses=poses,
            camera_fovy=fovy,
        )
        return meta, episode_arrays(rec, env_state=rec.env_state.astype(np.float32))


def demo_scene(env: StageEnv, scene_id: str, plan: bool = True) -> PlaceInsideScene:
    """:meth:`factory.tasks.base.Task.demo_scene` of ``task=place_inside``; logs the set-up
    time, the part and the object. Without ``plan`` (the GPU pipeline's main process, which
    draws the recorded states with the scene's cameras) the scene is set up as the planner
    processes set it up (:func:`scene_setup`), without its planner; an object the gripper
    cannot take is then found by the planner processes, which report the scene unusable.

    Raises:
        TaskError: the scene cannot host the task.
    """
    t0 = time.perf_counter()
    if plan:
        setup, planner = scene_planner(env.run_dir, scene_id, env.demos)
    else:
        setup, planner = scene_setup(env.run_dir, scene_id, env.demos), None
    log.info(
        "scene %s: put %s in %s (%s), set up in %.1f s%s",
        scene_id,
        setup.pick.id,
        setup.art.part.key,
        setup.art.part.label,
        time.perf_counter() - t0,
        "" if plan else " (no planner: recording only)",
    )
    return PlaceInsideScene(env, setup, planner)
