"""What ``stage=demos`` records of the articulated tasks (``task=open``, ``task=close``): a scene
of a run composed with the Panda in front of the part (:func:`scene_planner`, also the
evaluation env's set-up) and :class:`ArticulatedScene`, the
:class:`~factory.demos.record.scene.SimulatingScene` the demos machinery plans, simulates and
stores with (``demo_execution = "episode"``: an episode at a time on one ``MjData``,
:func:`~factory.tasks.articulated.execute.execute_episode`).

Stored episodes fill :class:`~factory.schema.episode.EpisodeInfo` as the fixed task does, with
``pick_id`` the articulated object, ``target_id`` its joint (the asset's joint name),
``support_id`` the handle, ``robot`` the base spot, ``frozen`` the objects compiled static,
``grasp_width`` the handle's thickness, ``outcome`` the success check's numbers (``joint``,
``fraction`` of the range, ``opened`` share of the span, ``range``, ``span``, ...). Arrays: the
fixed task's (``time``, ``state``, ``joint_pos``, ``gripper``, ``ee_pose``, ``action`` (F, 8))
and ``env_state`` (F, 11): the part's joint and its handle seen from the robot
(:func:`~factory.tasks.articulated.execute.env_state`).
``demos.randomize`` does not apply (each seed draws its start and goal), nor do
``demos.appearance`` and ``demos.max_grasps`` (two handle grasps).
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
from factory.schema import Scene
from factory.schema.episode import EpisodeInfo, RobotBase
from factory.tasks.articulated.plan import ArticulatedPlan, ArticulatedPlanner, ArticulatedSetup

__all__ = [
    "ArticulatedScene",
    "demo_scene",
    "ensure_assets",
    "episode_instruction",
    "record_config",
    "scene_planner",
    "scene_setup",
]

log = logging.getLogger(__name__)


def ensure_assets(scene: Scene, assets_dir: Path) -> Scene:
    """Builds the procedural articulated assets a scene names but the run lacks (a bundled
    example scene copied into a run): an object whose ``extras["asset_request"]`` holds its
    asset's request (``meta.json``'s ``request``) and whose asset folder is missing is built
    by the procedural library, articulated. Returns ``scene`` with the built assets' ids (the
    same ids when the library builds what the request names)."""
    from dataclasses import replace

    from factory.assets.cache import cached

    out = []
    changed = False
    for obj in scene.objects:
        req = obj.extras.get("asset_request")
        if obj.asset is None or not req or cached(assets_dir, obj.asset.asset_id) is not None:
            out.append(obj)
            continue
        from factory.assets.library import AssetLibrary
        from factory.assets.procedural import AssetSpec

        spec = AssetSpec(
            category=str(req["category"]),
            dims=None if req.get("dims") is None else tuple(req["dims"]),
            materials=None if req.get("materials") is None else tuple(req["materials"]),
            colors=None if req.get("colors") is None else tuple(tuple(c) for c in req["colors"]),  # type: ignore[arg-type]
            style=str(req.get("style", "")),
            seed=int(req.get("seed", 0)),
        )
        lib = AssetLibrary(assets_dir, real_meshes=False, articulated=True)
        meta = lib.get(spec)
        log.info("scene %s: built asset %s for %s", scene.id, meta.asset_id, obj.id)
        if meta.asset_id != obj.asset.asset_id:
            obj = replace(obj, asset=replace(obj.asset, asset_id=meta.asset_id))
            changed = True
        out.append(obj)
    return replace(scene, objects=out) if changed else scene


def scene_setup(
    run_dir: str | Path, scene_id: str, dc: DemosConfig, direction: str
) -> ArticulatedSetup:
    """A scene of a run composed with the robot in front of its part as ``stage=demos``
    records it (:func:`~factory.tasks.articulated.plan.setup_scene`, deterministic per scene;
    objects beyond ``demos.freeze_beyond`` static). The search runs once per scene and run:
    the other processes compose its recorded choices
    (:func:`~factory.tasks.articulated.setup_record.recorded_setup`).

    Raises:
        TaskError: the scene has no usable part (none, the named one missing, out of reach).
    """
    import mujoco

    from factory.store import RunStore
    from factory.tasks.articulated.plan import SetupHint, setup_scene
    from factory.tasks.articulated.setup_record import recorded_setup

    store = RunStore(run_dir)
    scene = ensure_assets(store.load_scene(scene_id), store.assets_dir)
    key = {"task": direction, "freeze_beyond": dc.freeze_beyond}
    setup = recorded_setup(
        run_dir,
        scene_id,
        key,
        lambda hint: setup_scene(
            scene,
            store.assets_dir,
            direction,
            freeze_beyond=dc.freeze_beyond,
            hint=None if hint is None else SetupHint.from_json(hint),
        ),
        lambda found: SetupHint.of(found).to_json(),
    )
    if not dc.sleep:
        setup.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return setup


def scene_planner(
    run_dir: str | Path, scene_id: str, dc: DemosConfig, direction: str
) -> tuple[ArticulatedSetup, ArticulatedPlanner]:
    """:func:`scene_setup` and its planner (free-motion speed and RRTConnect timeout from
    ``demos.*``).

    Raises:
        TaskError: the scene has no usable part.
    """
    from factory.demos.plan.planner import PlannerConfig
    from factory.tasks.articulated.plan import ArticulatedMotion

    setup = scene_setup(run_dir, scene_id, dc, direction)
    motion = ArticulatedMotion(speed=dc.speed, accel=0.6 * dc.speed, jerk=0.4 * dc.speed)
    planner = ArticulatedPlanner(setup, motion, PlannerConfig(timeout=dc.plan_timeout))
    return setup, planner


def episode_instruction(setup: ArticulatedSetup) -> str:
    """The scene's instruction when the scene was made for this task, else "<open|close>
    <the part's label>" ("open the drawer of the base cabinet")."""
    task = setup.scene.task
    if task is not None and task.kind == setup.direction and task.instruction:
        return str(task.instruction)
    return f"{setup.direction} {setup.part.label}"


def record_config(dc: DemosConfig, render: bool | None = None) -> Any:
    """The recording settings of ``demos.*`` (``render``: overrides ``demos.render``)."""
    from factory.tasks.articulated.record import RecordConfig

    return RecordConfig(
        fps=dc.fps,
        width=dc.width,
        height=dc.height,
        cameras=tuple(dc.cameras),
        depth=dc.depth,
        render=dc.render if render is None else render,
        shadows=dc.shadows,
    )


class ArticulatedScene(SimulatingScene):
    """A scene of an articulated task set up for ``stage=demos`` (episodes simulated one at a
    time)."""

    plan_type: ClassVar[type[Any]] = ArticulatedPlan
    setup: ArticulatedSetup

    def __init__(
        self, env: StageEnv, setup: ArticulatedSetup, planner: ArticulatedPlanner | None
    ) -> None:
        super().__init__(env, setup, planner)
        self.instruction = episode_instruction(setup)

    def summary(self) -> dict[str, Any]:
        """The robot's base spot (x, y m, yaw rad), the objects taken out of the part's way
        and the part (``<object>:<joint>``)."""
        p = self.setup.placement
        return {
            "robot_base": [p.x, p.y, p.yaw],
            "cleared": list(self.setup.cleared),
            "part": self.setup.part.key,
            "instruction": self.instruction,
        }

    def plan(self, seed: int) -> Any:
        """:meth:`~factory.tasks.articulated.plan.ArticulatedPlanner.plan_episode`."""
        assert self.planner is not None, "a scene set up without its planner"
        return self.planner.plan_episode(seed)

    def record_config(self, render: bool | None = None) -> Any:
        return record_config(self.env.demos, render)

    def renderer(self, rec_cfg: Any) -> Any:
        from factory.tasks.articulated.record import ArticulatedRenderer

        return ArticulatedRenderer(self.setup.model, rec_cfg)

    def camera_rig(self, rec_cfg: Any) -> CameraRig:
        """The fixed-base Panda's cameras :meth:`renderer` draws
        (:func:`~factory.tasks.articulated.record.camera_rig`)."""
        from factory.tasks.articulated.record import camera_rig

        return camera_rig(rec_cfg)

    def simulate(self, plan: Any, rec_cfg: Any, renderer: Any | None = None) -> Any:
        """:meth:`execute` (images only with a renderer)."""
        if renderer is None:
            from dataclasses import replace

            rec_cfg = replace(rec_cfg, render=False)
        return self.execute(plan, rec_cfg, renderer)

    def states_recorder(self) -> Any:
        """The episode from its GPU-simulated states
        (:class:`~factory.tasks.articulated.from_states.ArticulatedFromStates`)."""
        from factory.tasks.articulated.from_states import ArticulatedFromStates

        return ArticulatedFromStates(self.setup)

    def execute(self, plan: Any, rec_cfg: Any, renderer: Any | None) -> Any:
        """Runs and records one planned episode:
        :func:`~factory.tasks.articulated.execute.execute_episode` (a task sharing this class
        gives its own)."""
        from factory.tasks.articulated.execute import execute_episode

        return execute_episode(self.setup, plan, rec_cfg, renderer)

    def payload(
        self, slot: int, seed: int, plan: Any, rec: Any, rec_cfg: Any, recorder: str = "cpu"
    ) -> tuple[EpisodeInfo, dict[str, np.ndarray]]:
        """The episode with its part, base spot, the calibration of its cameras fixed in the
        scene (``camera_poses``, ``camera_fovy``) and the part's joint (``env_state``)."""
        from factory.robots.panda import SCENE_CAMERAS
        from factory.tasks.articulated.plan import camera_calibration

        setup = self.setup
        p = setup.placement
        poses: dict[str, list[float]] = {}
        fovy: dict[str, float] = {}
        if rec_cfg.render:
            cams = tuple(c for c in rec_cfg.cameras if c in SCENE_CAMERAS)
            poses, fovy = camera_calibration(setup, cams)
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
            pick_id=setup.part.obj.id,
            target_id=setup.part.joint.name,
            support_id=setup.part.handle.name,
            robot=RobotBase(p.x, p.y, p.z, p.yaw),
            frozen=list(setup.frozen),
            camera_poses=poses,
            camera_fovy=fovy,
        )
        return meta, episode_arrays(rec, env_state=rec.env_state.astype(np.float32))


def demo_scene(env: StageEnv, scene_id: str, plan: bool = True) -> ArticulatedScene:
    """:meth:`factory.tasks.base.Task.demo_scene` of the articulated tasks (the direction is
    the task's, ``env.task``); logs the set-up time and the part. Without ``plan`` (the GPU
    pipeline's main process, which draws the recorded states with the scene's cameras) the
    scene is set up as the planner processes set it up (:func:`scene_setup`: the same model,
    base spot and part), without its planner.

    Raises:
        TaskError: the scene has no usable part.
    """
    from factory.tasks import get_task

    direction = str(getattr(get_task(env.task), "direction"))  # noqa: B009
    t0 = time.perf_counter()
    if plan:
        setup, planner = scene_planner(env.run_dir, scene_id, env.demos, direction)
    else:
        setup, planner = scene_setup(env.run_dir, scene_id, env.demos, direction), None
    log.info(
        "scene %s: %s %s (%s), set up in %.1f s%s",
        scene_id,
        direction,
        setup.part.key,
        setup.part.label,
        time.perf_counter() - t0,
        "" if plan else " (no planner: recording only)",
    )
    return ArticulatedScene(env, setup, planner)
