"""``stage=warmup``: the GPU kernels of ``stage=demos`` compiled ahead into Warp's kernel cache.

The Warp test runs on Warp's CPU device with the scene and recording settings of
tests/demos/test_execute_warp.py's pipeline test (same group: its kernels are compiled once per
test process and kernel cache).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from robot_models import require_robot_models

from factory.config import DemosConfig, FactoryConfig
from factory.context import StageContext
from factory.errors import StoreError
from factory.store import RunStore, Shard

EXAMPLE_SCENE = (
    Path(__file__).resolve().parents[2] / "factory/data/examples/kitchen_pick_place/scene.json"
)

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")


def _ctx(run: Path, task: str = "pick_place", **demos: Any) -> StageContext:
    cfg = FactoryConfig(stage="warmup", run_dir=str(run), task=task, demos=DemosConfig(**demos))
    run.mkdir(parents=True, exist_ok=True)
    return StageContext(cfg, RunStore(run), Shard(0, 1))


@pytest.mark.slow
def test_warmup_compiles_a_scenes_kernels_once(
    make_kitchen, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """On Warp's CPU device: the scene's kernels are traced and loaded (compiled, or read from
    the kernel cache), a second warm-up loads and compiles none, the progress line names the
    counts and the cache, and ``warmup.json`` holds the summary."""
    import logging

    require_robot_models()
    pytest.importorskip("mujoco_warp")
    import factory.sim.backend as backend
    from factory.demos.warmup import run
    from factory.schema import scene_to_json

    monkeypatch.setattr(backend, "cuda_available", lambda: False)
    caplog.set_level(logging.INFO, logger="factory.demos.warmup")
    root = tmp_path / "run"
    scene = make_kitchen(root / "assets")
    (root / "scenes" / scene.id).mkdir(parents=True)
    (root / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    # test_gpu_pipeline_on_warp_cpu's settings: the same kernels
    ctx = _ctx(root, sleep=False, width=32, height=32, gpu_batch=2, gpu_tail=0.25)

    first = run(ctx)
    assert first["scenes_warmed"] == 1 and first["scenes_failed"] == 0, first
    assert first["device"] == "cpu"
    summary = json.loads((root / "warmup.json").read_text())
    assert summary["schema_version"] == 1 and summary["device"] == "cpu"
    assert summary["kernel_cache"] == first["kernel_cache"] and summary["kernel_cache"]
    (one,) = summary["scenes"]
    assert one["scene_id"] == scene.id and "trace_error" not in one, one
    assert one["modules"] > 20  # physics, renderer and the executor's own
    assert 0 <= one["compiled"] <= one["loaded"] <= one["modules"]
    assert summary["totals"]["warmed"] == 1 and summary["totals"]["modules"] == one["modules"]
    assert "no CUDA device: compiling for Warp's CPU device" in caplog.text
    line = f"warmup 1/1 {scene.id}: {one['compiled']} of {one['modules']} modules compiled in"
    assert line in caplog.text and f"(kernel cache {summary['kernel_cache']}" in caplog.text

    second = run(ctx)
    assert second["modules_compiled"] == 0
    (again,) = json.loads((root / "warmup.json").read_text())["scenes"]
    assert again["modules"] == one["modules"]
    assert again["loaded"] == 0 and again["compiled"] == 0, again


def test_a_task_without_gpu_kernels_compiles_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A task whose execution has no warm-up (``Execution.warm_up`` None; every registered
    execution has one now, so ``task=open``'s stands in without it): the stage says so in one
    line, compiles nothing (no scene set up, no Warp) and writes the summary with the reason."""
    import dataclasses

    import factory.demos.execution as execution
    from factory.demos.episode_execution import EPISODE
    from factory.demos.warmup import run

    monkeypatch.setattr(
        execution, "execution_of", lambda task: dataclasses.replace(EPISODE, warm_up=None)
    )
    root = tmp_path / "run"
    (root / "scenes" / "kitchen").mkdir(parents=True)
    shutil.copy(EXAMPLE_SCENE, root / "scenes" / "kitchen" / "scene.json")
    out = run(_ctx(root, task="open"))
    assert out["scenes_warmed"] == 0 and out["modules_compiled"] == 0 and out["device"] is None
    summary = json.loads((root / "warmup.json").read_text())
    assert summary["schema_version"] == 1 and summary["task"] == "open"
    assert summary["scenes"] == [] and summary["totals"]["compiled"] == 0
    reason = summary["nothing_to_warm"]
    assert "task=open compiles no GPU kernels ahead" in reason and "nothing compiled" in reason
    assert reason in caplog.text
    assert out["produced"][0]["detail"] == reason


def test_warmup_compiles_the_episode_renderers_kernels(tmp_path: Path) -> None:
    """``task=open`` (the ``episode`` execution: the GPU draws recorded states) on its bundled
    kitchen, on Warp's CPU device: the scene is set up without its planner and the kernels of
    the renderer's calls (kinematics, camera poses, BVH, ray tracing, pixel conversion) are
    traced and loaded; a second warm-up loads none."""
    require_robot_models()
    pytest.importorskip("ompl")
    pytest.importorskip("mujoco_warp")
    from factory.demos.warmup import run
    from factory.tasks import get_task

    src = get_task("open").example_scene_path()
    assert src is not None
    root = tmp_path / "run"
    (root / "scenes" / src.parent.name).mkdir(parents=True)
    shutil.copy(src, root / "scenes" / src.parent.name / "scene.json")
    ctx = _ctx(root, task="open", width=32, height=32, episode_physics="cpu")
    first = run(ctx)
    assert first["scenes_warmed"] == 1 and first["scenes_failed"] == 0, first
    (one,) = json.loads((root / "warmup.json").read_text())["scenes"]
    assert "trace_error" not in one and one["modules"] >= 5, one
    assert 0 <= one["compiled"] <= one["loaded"] <= one["modules"]
    run(ctx)
    (again,) = json.loads((root / "warmup.json").read_text())["scenes"]
    assert again["modules"] == one["modules"] and again["loaded"] == 0, again


def test_a_run_without_scenes_names_the_fix(tmp_path: Path, cli) -> None:
    from factory.demos.warmup import run

    with pytest.raises(StoreError, match=r"no scenes in .*run stage=generate or stage=ingest"):
        run(_ctx(tmp_path / "run"))
    out = cli("stage=warmup", f"run_dir={tmp_path / 'run'}")
    assert out.returncode != 0
    assert "no scenes in" in out.stderr and "stage=generate" in out.stderr
    assert "Traceback" not in out.stderr


def test_a_scene_that_cannot_host_the_task_is_listed_and_the_rest_go_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A scene whose set-up fails (a :class:`FactoryError`) is listed with its reason; the next
    scene is warmed up (the execution's hook stands in for Warp: no kernels compile here)."""
    import dataclasses
    import logging
    from types import SimpleNamespace

    import factory.demos.execution as execution
    import factory.sim.backend as backend
    from factory.demos.batch_execution import BATCH
    from factory.demos.warmup import run
    from factory.errors import TaskError
    from factory.sim.kernel_preload import PreloadReport
    from factory.tasks.pick_place.task import PickPlaceTask

    root = tmp_path / "run"
    for sid in ("bad", "good"):
        (root / "scenes" / sid).mkdir(parents=True)
        shutil.copy(EXAMPLE_SCENE, root / "scenes" / sid / "scene.json")

    def demo_scene(self, env, scene_id, plan=True):  # type: ignore[no-untyped-def]
        assert plan is False  # set up without its planner
        if scene_id == "bad":
            raise TaskError("no free base spot next to the table")
        return SimpleNamespace(scene_id=scene_id)

    warmed: list[tuple[str, str]] = []

    def warm_up(scene, env, device):  # type: ignore[no-untyped-def]
        warmed.append((scene.scene_id, device))
        return PreloadReport(modules=9, compiled=0, trace_s=0.1, load_s=0.0, workers=1)

    monkeypatch.setattr(PickPlaceTask, "demo_scene", demo_scene)
    monkeypatch.setattr(
        execution, "execution_of", lambda task: dataclasses.replace(BATCH, warm_up=warm_up)
    )
    monkeypatch.setattr(backend, "cuda_available", lambda: False)
    monkeypatch.setattr(backend, "init_warp", lambda: None)
    caplog.set_level(logging.INFO, logger="factory.demos.warmup")
    out = run(_ctx(root))
    assert warmed == [("good", "cpu")]
    assert out["scenes_warmed"] == 1 and out["scenes_failed"] == 1
    summary = json.loads((root / "warmup.json").read_text())
    bad, good = summary["scenes"]
    assert bad == {"scene_id": "bad", "error": "no free base spot next to the table"}
    assert good["modules"] == 9 and good["loaded"] == 0 and good["compiled"] == 0
    assert "warmup 1/2 bad: not warmed up: no free base spot" in caplog.text
    assert "warmup 2/2 good: 0 of 9 modules compiled in" in caplog.text
