"""The tasks that simulate their episodes themselves (``demo_execution = "episode"``: the mobile
task, ``open``, ``close``, ``place_inside``) record on both executors: the GPU pipeline's main
process sets each scene up without its planner (``demo_scene(..., plan=False)``) as the planner
processes set it up, and draws the recorded states with the scene's own cameras
(``SimulatingScene.camera_rig``), the ones its CPU renderer draws."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import pytest
from robot_models import require_robot_models

from factory.tasks import TASKS, get_task

require_robot_models()
pytest.importorskip("ompl")

EPISODE_TASKS = [name for name in TASKS if get_task(name).demo_execution == "episode"]


def test_the_articulated_and_mobile_tasks_simulate_their_episodes() -> None:
    assert {"mobile_pick_place", "open", "close", "place_inside"} <= set(EPISODE_TASKS)


@pytest.mark.parametrize("name", EPISODE_TASKS)
def test_scene_without_its_planner_matches_the_planners(name: str, tmp_path: Path) -> None:
    """``demo_scene(env, scene, plan=False)`` on the task's bundled example: no planner, the
    same model as the planner processes' scene (so its recorded states draw right), and a
    camera rig of the recording's cameras, in order, each a camera of that model with the
    recording's image size (fisheyes square) and depth format."""
    from factory.config import DemosConfig
    from factory.demos.record.scene import SimulatingScene
    from factory.demos.record.slots import StageEnv

    task = get_task(name)
    src = task.example_scene_path()
    assert src is not None, f"task {name} has no bundled example scene"
    sid = json.loads(src.read_text())["id"]
    (tmp_path / "scenes" / sid).mkdir(parents=True)
    (tmp_path / "scenes" / sid / "scene.json").write_text(src.read_text())
    dc = DemosConfig(width=48, height=32, depth="float32")
    env = StageEnv(str(tmp_path), str(tmp_path / "episodes" / "shard-0.zarr"), dc, name, 0, 1)
    gpu = task.demo_scene(env, sid, False)
    cpu = task.demo_scene(env, sid)
    assert isinstance(gpu, SimulatingScene) and type(gpu) is type(cpu)
    assert gpu.planner is None and cpu.planner is not None
    a, b = gpu.setup.model, cpu.setup.model
    for size in ("nq", "nv", "nbody", "ngeom", "ncam", "nmocap"):
        assert getattr(a, size) == getattr(b, size), size
    assert (a.qpos0 == b.qpos0).all() and (a.cam_pos == b.cam_pos).all()
    assert gpu.summary() == cpu.summary()
    cfg = gpu.record_config()
    rig = gpu.camera_rig(cfg)
    assert rig.keys == tuple(cfg.cameras) and rig.depth == "float32"
    for cam in rig.cameras:
        assert mujoco.mj_name2id(a, mujoco.mjtObj.mjOBJ_CAMERA, cam.camera) >= 0, cam
        side = (48, 48) if cam.fisheye is not None else (48, 32)
        assert (cam.width, cam.height) == side, cam
