"""``task=place_inside`` on the bundled one-cabinet kitchen: the success rule (the object on the
drawer's floor, the drawer closed, the hand away), one planned and executed episode, a drawer
with something stored in it taken after the empty ones (what is stored taken out), scenes
whose drawer is too small for the object or whose object no gripper can take reported with
their reasons while the run goes on; and a bedroom generated from a request whose nightstand
drawer gets the object."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

from factory.tasks import get_task

require_robot_models()
pytest.importorskip("ompl")


@pytest.fixture(scope="module")
def setup_planner(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Any]:
    """The example scene set up (its cabinet built into a temporary run) and its planner."""
    from factory.store import RunStore
    from factory.tasks.articulated.demos import ensure_assets
    from factory.tasks.place_inside.plan import PlaceInsidePlanner, setup_scene

    src = get_task("place_inside").example_scene_path()
    assert src is not None
    run = tmp_path_factory.mktemp("place_inside")
    shutil.copytree(src.parent, run / "scenes" / src.parent.name)
    store = RunStore(run)
    scene = ensure_assets(store.load_scene(src.parent.name), store.assets_dir)
    setup = setup_scene(scene, store.assets_dir)
    return setup, PlaceInsidePlanner(setup)


def _state(setup: Any, q_joint: float, obj_in_link: np.ndarray | None) -> mujoco.MjData:
    """The scene with the drawer at ``q_joint`` and the object at ``obj_in_link`` (3, the
    drawer link's frame; None: where the scene has it), the arm at its start posture."""
    from factory.tasks.articulated.plan import initial_state

    m = setup.model
    data = mujoco.MjData(m)
    data.qpos[:] = initial_state(setup.art, q_joint)
    mujoco.mj_kinematics(m, data)
    if obj_in_link is not None:
        b = setup.art.body
        p = data.xmat[b].reshape(3, 3) @ obj_in_link + data.xpos[b]
        data.qpos[setup.pick_adr : setup.pick_adr + 3] = p
        mujoco.mj_kinematics(m, data)
    return data


def test_the_success_rule(setup_planner: tuple[Any, Any]) -> None:
    from factory.tasks.articulated.plan import grasps_in_link
    from factory.tasks.place_inside.execute import Watch, check_outcome

    setup, _ = setup_planner
    grasp = grasps_in_link(setup.art.part)[0]
    inner = setup.interior
    mid = np.array([0.5 * (inner.lo[0] + inner.hi[0]), -0.08, inner.floor_z])
    hi = setup.art.hi

    def outcome(q: float, p: np.ndarray | None, **watch: float) -> Any:
        return check_outcome(setup, _state(setup, q, p), Watch(**watch), grasp)

    ok = outcome(0.0, mid)
    assert ok.success and ok.reason == "", ok
    assert ok.details["object_z"] == pytest.approx(inner.floor_z, abs=1e-6)
    assert outcome(0.04 * hi, mid).success  # closed: <= 5 % of the range
    assert outcome(0.5 * hi, mid).reason == "not_closed"
    assert outcome(0.0, None).reason == "not_inside"  # still on the top
    assert outcome(0.0, mid + np.array([0.0, 0.0, 0.08])).reason == "not_inside"  # not on the floor
    assert outcome(0.0, None, lifted=0.0).reason == "slip"
    assert outcome(0.0, None, off_place=0.2).reason == "dropped"
    assert outcome(0.0, mid, worst=0.05).reason == "collision"


def test_one_episode_plans_and_succeeds(setup_planner: tuple[Any, Any]) -> None:
    from factory.tasks.articulated.record import RecordConfig
    from factory.tasks.place_inside.execute import execute_episode
    from factory.tasks.place_inside.plan import PlaceInsidePlan

    setup, planner = setup_planner
    plan = planner.plan_episode(1)
    assert isinstance(plan, PlaceInsidePlan), plan
    order = ["open_pull", "pick_lift", "transport", "place_release", "close_push", "end"]
    assert [plan.phases[p] for p in order] == sorted(plan.phases[p] for p in order)
    assert plan.ctrl.shape[0] == plan.targets.shape[0] == plan.phases["end"]
    # the plan leaves the model as it found it (the object's start is written per episode)
    a = setup.pick_adr
    assert np.allclose(setup.model.qpos0[a : a + 7], planner.home_pose)
    rec = execute_episode(setup, plan, RecordConfig(fps=10, render=False))
    assert rec.outcome.success, rec.outcome
    env = rec.env_state
    assert env.shape == (len(rec.time), 9)
    assert env[0, 1] == pytest.approx(0.0, abs=1e-3) and env[:, 1].max() >= 0.9
    assert env[-1, 1] <= 0.05
    assert np.allclose(env[0, 2:5], plan.qpos0[a : a + 3], atol=1e-3)
    # the seed decides the object's start (the free motions' OMPL paths may differ)
    again = planner.plan_episode(1)
    assert np.array_equal(again.qpos0, plan.qpos0)


def test_a_drawer_too_small_is_reported(tmp_path: Path, cli: Any) -> None:
    src = get_task("place_inside").example_scene_path()
    assert src is not None
    # the can: too tall for the drawer; 12 cm across, wider than the open gripper; as bundled
    for sid, size in (("too_tall", (0.06, 0.25)), ("too_wide", (0.12, 0.1)), ("ok", (0.06, 0.1))):
        data = json.loads(src.read_text())
        data["id"] = sid
        dims = data["objects"][1]["dimensions"]
        dims["width"] = dims["length"] = size[0]
        dims["height"] = size[1]
        (tmp_path / "scenes" / sid).mkdir(parents=True)
        (tmp_path / "scenes" / sid / "scene.json").write_text(json.dumps(data))
    out = cli(
        "stage=demos",
        f"run_dir={tmp_path}",
        "task=place_inside",
        "demos.render=false",
        "demos.workers=1",
        "demos.fps=10",
        "demos.episodes_per_scene=1",
        env={"OMP_NUM_THREADS": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((tmp_path / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["new_successes"] == 1, summary
    error = summary["scenes"]["too_tall"]["error"]
    assert "no container part for 'can_0'" in error and "'too_small': 1" in error, error
    error = summary["scenes"]["too_wide"]["error"]
    assert "no collision-free grasp on 'can_0'" in error and "ask for an object" in error, error


def test_a_drawer_with_something_stored_is_taken_after_the_empty_ones(tmp_path: Path) -> None:
    """A can stored on the example drawer's floor: the drawer is offered after the empty ones
    (there are none) with the can in :attr:`Container.stored`, and the set-up takes the can
    out of the scene (``cleared``)."""
    from collections import Counter
    from dataclasses import replace

    from factory.schema import SceneObject
    from factory.store import RunStore
    from factory.tasks.articulated.demos import ensure_assets
    from factory.tasks.place_inside.containers import _interiors, container_parts, pick_object
    from factory.tasks.place_inside.plan import setup_scene

    src = get_task("place_inside").example_scene_path()
    assert src is not None
    shutil.copytree(src.parent, tmp_path / "scenes" / src.parent.name)
    store = RunStore(tmp_path)
    scene = ensure_assets(store.load_scene(src.parent.name), store.assets_dir)
    pick = pick_object(scene)
    (box,) = container_parts(scene, store.assets_dir, pick, Counter())
    assert box.stored == ()
    cabinet = box.part.obj
    (floor,) = _interiors(box.part, store.assets_dir)
    stored: SceneObject = replace(
        pick,
        id="can_1",
        task_role=None,
        position=replace(cabinet.position, z=cabinet.position.z + floor.floor_z),
        placement=replace(pick.placement, support_id=cabinet.id, location="inside"),
    )
    scene = replace(scene, objects=[*scene.objects, stored])
    why: Counter[str] = Counter()
    (box,) = container_parts(scene, store.assets_dir, pick, why)
    assert box.stored == ("can_1",) and why["occupied"] == 1
    setup = setup_scene(scene, store.assets_dir)
    assert "can_1" in setup.cleared and "can_1" not in {o.id for o in setup.scene.objects}


def test_a_bedroom_request_puts_the_object_in_the_nightstand_drawer(
    tmp_path: Path, cli: Any
) -> None:
    """ "put the pill bottle in the drawer of the nightstand": one bedroom generated (its
    furniture articulated, the scene made for ``place_inside``, the pill bottle its ``pick``),
    one episode stored that puts it in a bedside cabinet's drawer (about 30 s on 2 cores)."""
    request = "put the pill bottle in the drawer of the nightstand"
    common = (f"run_dir={tmp_path}", "sim.backend=cpu")
    out = cli(
        "stage=generate",
        *common,
        f"generate.prompts=[{request}]",
        "generate.scenes_per_prompt=1",
        env={"OMP_NUM_THREADS": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    (path,) = tmp_path.glob("scenes/*/scene.json")
    data = json.loads(path.read_text())
    assert data["id"].startswith("bedroom")
    assert data["task"] == {"kind": "place_inside", "instruction": request}
    assert any(
        o.get("task_role") == "pick" and o["category"] == "pill_bottle" for o in data["objects"]
    )
    out = cli(
        "stage=demos",
        *common,
        "demos.executor=cpu",
        "demos.render=false",
        "demos.fps=10",
        "demos.episodes_per_scene=1",
        env={"OMP_NUM_THREADS": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((tmp_path / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["new_successes"] == 1, summary
    log = (tmp_path / "logs" / "demos-0-of-1.log").read_text()
    assert re.search(r"put pill_bottle_\d+ in bedside_cabinet_\d+:drawer", log), log[-3000:]


def test_the_object_is_stood_up_on_the_top() -> None:
    """An object the generated scene left lying on its side (fallen off its support) stands
    upright on the container's top, its yaw kept."""
    from dataclasses import replace

    from factory.schema import load_scene
    from factory.tasks.place_inside.containers import on_top, pick_object

    src = get_task("place_inside").example_scene_path()
    assert src is not None
    scene = load_scene(src)
    pick = pick_object(scene)
    fallen = replace(pick, rotation=replace(pick.rotation, x=90.0, y=9.0, z=-90.5))
    scene = replace(scene, objects=[fallen if o.id == pick.id else o for o in scene.objects])
    cabinet = next(o for o in scene.objects if o.id == "base_cabinet_0")
    moved = next(o for o in on_top(scene, cabinet, 0.87, fallen).objects if o.id == pick.id)
    assert (moved.rotation.x, moved.rotation.y, moved.rotation.z) == (0.0, 0.0, -90.5)
    assert moved.position.z == pytest.approx(cabinet.position.z + 0.87)
