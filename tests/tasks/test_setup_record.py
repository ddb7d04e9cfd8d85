"""One set-up search per scene and run (factory/tasks/articulated/setup_record.py): the first
process searches and records its choices, the others compose the same set-up from the record;
an unusable scene is recorded with its reason."""

from __future__ import annotations

import json
import multiprocessing as mp
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from robot_models import require_robot_models

from factory.config import DemosConfig
from factory.errors import TaskError
from factory.tasks import get_task

require_robot_models()
pytest.importorskip("ompl")


def _example_run(run: Path, instruction: str | None = None) -> str:
    """The bundled ``open`` example scene copied into ``run`` (its instruction replaced)."""
    src = get_task("open").example_scene_path()
    assert src is not None
    data = json.loads(src.read_text())
    if instruction is not None:
        data["task"] = {"kind": "open", "instruction": instruction}
        for o in data["objects"]:
            o.pop("task_joint", None)
    (run / "scenes" / data["id"]).mkdir(parents=True)
    (run / "scenes" / data["id"] / "scene.json").write_text(json.dumps(data))
    return str(data["id"])


def test_a_hint_composes_the_searched_set_up(tmp_path: Path) -> None:
    from factory.store import RunStore
    from factory.tasks.articulated.demos import ensure_assets
    from factory.tasks.articulated.plan import SetupHint, setup_scene

    sid = _example_run(tmp_path)
    store = RunStore(tmp_path)
    scene = ensure_assets(store.load_scene(sid), store.assets_dir)
    searched = setup_scene(scene, store.assets_dir, "open")
    hint = SetupHint.from_json(json.loads(json.dumps(SetupHint.of(searched).to_json())))
    assert hint == SetupHint.of(searched)
    composed = setup_scene(scene, store.assets_dir, "open", hint=hint)
    assert composed.part.key == searched.part.key and composed.placement == searched.placement
    assert composed.rig == searched.rig and composed.cleared == searched.cleared
    assert composed.frozen == searched.frozen
    assert (composed.joint, composed.qadr, composed.lo, composed.hi) == (
        searched.joint,
        searched.qadr,
        searched.lo,
        searched.hi,
    )
    a, b = composed.model, searched.model
    for name in ("nq", "nv", "nbody", "ngeom", "ncam"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("qpos0", "body_pos", "body_quat", "geom_pos", "cam_pos", "cam_quat"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    with pytest.raises(TaskError, match="names part 'nothing:here'"):
        setup_scene(scene, store.assets_dir, "open", hint=replace(hint, part="nothing:here"))


def test_the_record_is_searched_once_and_read_after(tmp_path: Path) -> None:
    from factory.tasks.articulated.demos import scene_setup
    from factory.tasks.articulated.setup_record import record_path

    sid = _example_run(tmp_path)
    dc = DemosConfig()
    first = scene_setup(tmp_path, sid, dc, "open")
    path = record_path(tmp_path, sid, {"task": "open", "freeze_beyond": dc.freeze_beyond})
    record = json.loads(path.read_text())
    assert record["schema_version"] == 1 and record["hint"]["part"] == first.part.key
    t0 = time.perf_counter()
    again = scene_setup(tmp_path, sid, dc, "open")
    assert again.placement == first.placement and again.rig == first.rig
    assert time.perf_counter() - t0 < 30  # composed, not searched (a generous bound)
    # another setting or direction is another record
    scene_setup(tmp_path, sid, replace(dc, freeze_beyond=0.5), "open")
    assert len(list(path.parent.glob(f"{sid}-*.json"))) == 2


def test_an_unusable_scene_is_recorded_with_its_reason(tmp_path: Path) -> None:
    from factory.tasks.articulated.demos import scene_setup
    from factory.tasks.articulated.setup_record import recorded_setup

    sid = _example_run(tmp_path, instruction="open the garage door")
    with pytest.raises(TaskError, match="names no part of the scene") as e:
        scene_setup(tmp_path, sid, DemosConfig(), "open")

    def must_not_search(hint: object) -> object:
        raise AssertionError("searched again")

    key = {"task": "open", "freeze_beyond": DemosConfig().freeze_beyond}
    with pytest.raises(TaskError) as again:
        recorded_setup(tmp_path, sid, key, must_not_search, lambda s: {})
    assert str(again.value) == str(e.value)


def _search_in_a_process(run: str, sid: str, marks: str) -> str:
    """A process's set-up through the record; appends 's' to ``marks`` when it searches."""
    from factory.tasks.articulated.plan import SetupHint, setup_scene
    from factory.tasks.articulated.setup_record import recorded_setup

    def search(hint):  # type: ignore[no-untyped-def]
        if hint is None:
            with open(marks, "a") as f:
                f.write("s")
            time.sleep(1.0)  # the others arrive while this one searches
        from factory.store import RunStore
        from factory.tasks.articulated.demos import ensure_assets

        store = RunStore(run)
        scene = ensure_assets(store.load_scene(sid), store.assets_dir)
        given = None if hint is None else SetupHint.from_json(hint)
        return setup_scene(scene, store.assets_dir, "open", hint=given)

    hint_of = lambda s: SetupHint.of(s).to_json()  # noqa: E731
    return recorded_setup(run, sid, {"task": "open"}, search, hint_of).part.key


def test_processes_that_start_together_search_once(tmp_path: Path) -> None:
    from factory.store import RunStore
    from factory.tasks.articulated.demos import ensure_assets

    sid = _example_run(tmp_path)
    store = RunStore(tmp_path)
    ensure_assets(store.load_scene(sid), store.assets_dir)  # the asset built once, beforehand
    marks = tmp_path / "marks"
    with mp.get_context("spawn").Pool(3) as pool:
        keys = pool.starmap(_search_in_a_process, [(str(tmp_path), sid, str(marks))] * 3)
    assert len(set(keys)) == 1
    assert marks.read_text() == "s"


@pytest.mark.parametrize("example", ["place_inside", "place_inside/kitchen_microwave_can_door"])
def test_place_inside_hint_composes_the_searched_set_up(example: str, tmp_path: Path) -> None:
    """``place_inside`` records its container (part and interior level) beside the articulated
    choices: from the record, a drawer's and a door's set-up come out the same."""
    from factory.store import RunStore
    from factory.tasks.articulated.demos import ensure_assets
    from factory.tasks.place_inside.plan import hint_of, setup_scene

    if "/" in example:
        src = Path(__file__).resolve().parents[2] / "factory" / "data" / "tasks" / example
        src = src / "scene.json"
    else:
        found = get_task(example).example_scene_path()
        assert found is not None
        src = found
    data = json.loads(src.read_text())
    (tmp_path / "scenes" / data["id"]).mkdir(parents=True)
    (tmp_path / "scenes" / data["id"] / "scene.json").write_text(src.read_text())
    store = RunStore(tmp_path)
    scene = ensure_assets(store.load_scene(data["id"]), store.assets_dir)
    searched = setup_scene(scene, store.assets_dir)
    hint = json.loads(json.dumps(hint_of(searched)))
    composed = setup_scene(scene, store.assets_dir, hint=hint)
    assert json.loads(json.dumps(hint_of(composed))) == hint
    assert composed.cleared == searched.cleared and composed.top_z == searched.top_z
    assert (composed.pick_body, composed.pick_adr) == (searched.pick_body, searched.pick_adr)
    assert np.array_equal(composed.art.model.qpos0, searched.art.model.qpos0)
    assert np.array_equal(composed.art.model.body_pos, searched.art.model.body_pos)
    with pytest.raises(TaskError, match="delete the run's cache/setups folder"):
        setup_scene(scene, store.assets_dir, hint={**hint, "support": "no_such_level"})
