"""The last step of ``stage=generate`` (:mod:`factory.scenes.finish`): the strict whole-scene
check with repair, and the task's feasibility critic with another attempt when it fails."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import pytest

from factory.config import FactoryConfig
from factory.context import StageContext
from factory.errors import StageFailed
from factory.schema import Placement, Task, Vec3
from factory.store import RunStore, Shard

pytest.importorskip("ompl")

REQUEST = "a kitchen where the robot picks up a mug and puts it in the bowl"


def test_final_check_leaves_what_validate_finds_valid(tmp_path: Path, make_kitchen) -> None:
    """A second bowl inside the bowl and a mug hanging in the air: the final check removes
    one of the colliding pair and settles or removes the mug; ``stage=validate``'s protocol
    then measures 0 % colliding and 100 % stable."""
    from factory.scenes.finish import strict_check
    from factory.sim.validate import make_backend, validate_scene

    scene = make_kitchen(tmp_path / "assets")
    bowl, mug = (next(o for o in scene.objects if o.id.startswith(k)) for k in ("bowl", "mug"))
    twin = replace(bowl, id="bowl_9", task_role=None)
    twin.position = Vec3(bowl.position.x + 0.03, bowl.position.y, bowl.position.z)
    floating = replace(
        mug,
        id="mug_9",
        task_role=None,
        position=Vec3(mug.position.x, mug.position.y - 0.25, mug.position.z + 0.4),
        placement=Placement(kind="on_top", support_id=mug.placement.support_id),
    )
    scene.objects += [twin, floating]
    cfg = FactoryConfig()
    _, before = validate_scene(
        replace(scene, objects=list(scene.objects)), tmp_path / "assets", cfg, make_backend(cfg.sim)
    )
    assert before["metrics"]["collision"]["ratio"] > 0
    assert before["metrics"]["stability"]["ratio"] < 1
    scene, out = strict_check(scene, tmp_path / "assets", cfg)
    acted = {c["object"]: c["action"] for c in out["changes"]}
    assert "bowl_9" in acted or bowl.id in acted, out
    assert "mug_9" in acted, out
    assert out["collision_ratio"] == 0.0 and out["stability_ratio"] == 1.0, out
    _, report = validate_scene(scene, tmp_path / "assets", cfg, make_backend(cfg.sim))
    metrics = report["metrics"]
    assert metrics["collision"]["ratio"] == 0.0 and metrics["stability"]["ratio"] == 1.0


def test_pick_place_feasibility_reasons(tmp_path: Path, make_kitchen) -> None:
    """The fixed task's critic: a kitchen with its mug and bowl on a table can host it; one
    without its pick object cannot (``no_task_objects``); the share of placements asked for
    decides ``no_room``."""
    from factory.tasks.pick_place.feasibility import NO_ROOM, NO_TASK_OBJECTS, feasibility

    assets = tmp_path / "assets"
    scene = make_kitchen(assets)
    ok = feasibility(scene, assets)
    assert ok["reason"] == "" and ok["placed"] >= 5, ok
    strict = feasibility(scene, assets, seeds=4, share=1.5)  # more than every seed: never
    assert strict["reason"] == NO_ROOM and strict["seeds"] == 4, strict
    no_mug = replace(scene, objects=[o for o in scene.objects if o.task_role != "pick"])
    assert feasibility(no_mug, assets)["reason"] == NO_TASK_OBJECTS


def _generate(run: Path, **generate: object) -> dict:
    from factory.scenes.generate import run as generate_stage

    cfg = FactoryConfig()
    cfg.run_dir = str(run)
    cfg.generate = replace(
        cfg.generate, prompts=[REQUEST], render=False, physics_critic=False, **generate
    )
    return generate_stage(StageContext(cfg, RunStore(run), Shard(0, 1)))


def test_generate_tries_another_seed_when_the_task_does_not_fit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, make_kitchen
) -> None:
    """A first attempt that the task's critic refuses is generated again with the next seed,
    and the report keeps why; when every attempt is refused the scene is not written, the
    stage fails naming the reason, and ``report.json`` lists the attempts. (The agent is
    replaced by a fixed kitchen: the stage's loop is what is tested.)"""
    import factory.scenes.generate as generate

    def agent(gcfg, prompt, library, seed, agent_cfg, scene_id):
        scene = make_kitchen(library.assets_dir, scene_id=scene_id)
        scene.task = Task(kind="pick_place", instruction="put the mug in the bowl")
        return scene, {"request": prompt, "seed": seed, "objects": len(scene.objects)}

    monkeypatch.setattr(generate, "_generate_with", agent)
    from factory.tasks.pick_place.task import PickPlaceTask

    calls: list[int] = []

    def refuse_first(self, scene, assets_root):
        calls.append(len(scene.objects))
        if len(calls) == 1:
            return {"reason": "no_room", "detail": "refused by the test"}
        return {"reason": "", "detail": "accepted"}

    monkeypatch.setattr(PickPlaceTask, "feasibility", refuse_first)
    _generate(tmp_path / "a")
    (report_path,) = (tmp_path / "a" / "scenes").glob("*/report.json")
    report = json.loads(report_path.read_text())["generate"]
    assert len(calls) == 2 and report["seed"] == 7919, report["seed"]
    assert report["rejected_attempts"] == [
        {"seed": 0, "reason": "no_room", "detail": "refused by the test"}
    ]
    assert report["task_check"]["reason"] == "" and report["final_check"]["objects"] == 4
    assert (report_path.parent / "scene.json").is_file()

    monkeypatch.setattr(
        PickPlaceTask, "feasibility", lambda self, s, a: {"reason": "no_base_spot", "detail": "x"}
    )
    with pytest.raises(StageFailed, match=r"none of 2 attempts can host its task \(no_base_spot"):
        _generate(tmp_path / "b", task_attempts=2)
    (report_path,) = (tmp_path / "b" / "scenes").glob("*/report.json")
    rejected = json.loads(report_path.read_text())["generate"]["rejected"]
    assert [r["seed"] for r in rejected] == [0, 7919]
    assert not (report_path.parent / "scene.json").exists()


def test_mobile_feasibility_asks_the_base_to_drive(tmp_path: Path) -> None:
    """The mobile task's critic is its route check with the supports' nearest edges at least
    MIN_SUPPORT_GAP apart: the bundled living room passes; with the desk moved beside the
    coffee table (one base pose would serve both) it fails as ``place_support_too_close``."""
    from factory.nav.support_gap import MIN_SUPPORT_GAP
    from factory.schema import load_scene
    from factory.tasks import get_task

    task = get_task("mobile_pick_place")
    path = task.example_scene_path()
    assert path is not None
    scene = load_scene(path)
    ok = task.feasibility(scene, None)
    assert ok is not None and ok["reason"] == "" and ok["gap"] >= MIN_SUPPORT_GAP, ok
    can = next(o for o in scene.objects if o.task_role == "pick")
    pick = scene.object(can.placement.support_id or "")
    place = next(o for o in scene.objects if o.task_role == "place_target")
    side = math.copysign(1.0, place.position.x - pick.position.x)
    x = pick.position.x + side * (pick.dimensions.width / 2 + place.dimensions.width / 2 + 0.5)
    dx, dy = x - place.position.x, pick.position.y - place.position.y
    for o in [place, *(o for o in scene.objects if o.placement.support_id == place.id)]:
        o.position = Vec3(o.position.x + dx, o.position.y + dy, o.position.z)
    near = task.feasibility(scene, None)
    assert near is not None and near["reason"] == "place_support_too_close", near


def test_generate_keeps_the_closest_soft_attempt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, make_kitchen
) -> None:
    """When every attempt could host the task but none meets the critic's preference (a soft
    verdict, as the mobile task's supports closer than it asks), the attempt closest to it
    (the widest gap) is written, and the report says so."""
    import factory.scenes.generate as generate
    from factory.tasks.pick_place.task import PickPlaceTask

    def agent(gcfg, prompt, library, seed, agent_cfg, scene_id):
        scene = make_kitchen(library.assets_dir, scene_id=scene_id)
        scene.task = Task(kind="pick_place", instruction="put the mug in the bowl")
        return scene, {"request": prompt, "seed": seed, "objects": len(scene.objects)}

    gaps = iter([0.9, 1.2, 0.4])
    monkeypatch.setattr(generate, "_generate_with", agent)
    monkeypatch.setattr(
        PickPlaceTask,
        "feasibility",
        lambda self, s, a: {"reason": "too_close", "detail": "x", "soft": True, "gap": next(gaps)},
    )
    _generate(tmp_path / "a", task_attempts=3)
    (report_path,) = (tmp_path / "a" / "scenes").glob("*/report.json")
    report = json.loads(report_path.read_text())["generate"]
    assert report["seed"] == 7919 and "kept the one closest" in report["task_check_kept"]
    assert len(report["rejected_attempts"]) == 3
    assert (report_path.parent / "scene.json").is_file()


def test_final_check_removes_an_object_in_a_wall(tmp_path: Path, make_kitchen) -> None:
    """An object standing 4 cm into a wall (which stage=validate's object pairs do not count)
    is removed by the final check, with the depth and the wall in its reason."""
    from factory.scenes.finish import strict_check

    scene = make_kitchen(tmp_path / "assets")
    mug = next(o for o in scene.objects if o.id.startswith("mug"))
    room = scene.rooms[0]
    wall = min(room.walls, key=lambda w: min(w.start.x, w.end.x))  # the west wall, x = x0
    x0 = min(wall.start.x, wall.end.x)
    inside = replace(
        mug,
        id="mug_8",
        task_role=None,
        position=Vec3(x0 + wall.thickness / 2 + mug.dimensions.width / 2 - 0.04, 1.0, 0.0),
        placement=Placement(kind="floor"),
    )
    scene.objects.append(inside)
    scene, out = strict_check(scene, tmp_path / "assets", FactoryConfig())
    removed = {c["object"]: c["reason"] for c in out["changes"] if c["action"] == "remove"}
    assert "mug_8" in removed and "cm into" in removed["mug_8"], out["changes"]
    assert all(o.id != "mug_8" for o in scene.objects)
