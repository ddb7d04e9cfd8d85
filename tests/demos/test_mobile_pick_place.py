"""Mobile pick-and-place: a can from a coffee table onto a desk across a hand-built living room."""

from __future__ import annotations

import os

import numpy as np
import pytest
from robot_models import require_robot_models

if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
    require_robot_models()
pytest.importorskip("ruckig")
pytest.importorskip("ompl")
pytest.importorskip("mink")

from living_room import can, desk, living_room

from factory.demos.plan.grasps import Grasp
from factory.schema import Physics, Scene, SceneObject, Size3, Vec3
from factory.tasks.mobile_pick_place import (
    ALL_CAMERAS,
    PLAN_TIMEOUT,
    SUBTASKS,
    MobileEpisodePlan,
    MobileMotionConfig,
    MobilePlanFailure,
    MobilePlanner,
    MobileRecordConfig,
    MobileTaskError,
    carry_order,
    execute_mobile,
    mobile_setup,
    mobile_task_objects,
    replay,
)

ROOM_W, ROOM_L = 6.0, 5.0
TABLE = (1.6, 2.5)
DESK = (4.6, 1.2)
DOOR = (2.0, 3.0)
"""The doorway of the partition of ``_living_room(stool_in_door=True)`` (y from, y to; m)."""


def _living_room(enclose_desk: bool = False, stool_in_door: bool = False) -> Scene:
    """A 6 x 5 m living room: a coffee table with a can on it and a desk 3.3 m away; with
    ``enclose_desk`` static panels close the desk in; with ``stool_in_door`` a static
    partition at x = 3 m splits the room, its 1 m doorway blocked by a light stool."""
    objects = [
        SceneObject(
            id="coffee_table",
            room_id="living",
            category="coffee_table",
            position=Vec3(*TABLE, 0.0),
            dimensions=Size3(1.0, 0.6, 0.45),
            physics=Physics(mass=15.0),
        ),
        can(Vec3(TABLE[0], TABLE[1] - 0.1, 0.45), "coffee_table"),
        desk(*DESK, "place_target"),
    ]
    if enclose_desk:  # a closed pen of static panels 0.9 m around the desk
        x, y = DESK
        hx, hy, t = 0.6 + 0.9, 0.3 + 0.9, 0.06
        for k, (cx, cy, w, ln) in enumerate(
            (
                (x, y - hy - t / 2, 2 * hx + 2 * t, t),
                (x, y + hy + t / 2, 2 * hx + 2 * t, t),
                (x - hx - t / 2, y, t, 2 * hy),
                (x + hx + t / 2, y, t, 2 * hy),
            )
        ):
            objects.append(
                SceneObject(
                    id=f"panel{k}",
                    room_id="living",
                    category="partition",
                    position=Vec3(cx, cy, 0.0),
                    dimensions=Size3(w, ln, 1.2),
                    physics=Physics(mass=20.0, static=True),
                )
            )
    if stool_in_door:
        for k, (y0, y1) in enumerate(((0.0, DOOR[0]), (DOOR[1], ROOM_L))):
            objects.append(
                SceneObject(
                    id=f"partition{k}",
                    room_id="living",
                    category="partition",
                    position=Vec3(3.0, (y0 + y1) / 2, 0.0),
                    dimensions=Size3(0.06, y1 - y0, 1.2),
                    physics=Physics(mass=20.0, static=True),
                )
            )
        objects.append(
            SceneObject(
                id="stool",
                room_id="living",
                category="stool",
                position=Vec3(3.0, (DOOR[0] + DOOR[1]) / 2, 0.0),
                dimensions=Size3(0.45, 0.45, 0.5),
                physics=Physics(mass=4.0),
            )
        )
    return Scene(
        id="living", rooms=[living_room(ROOM_W, ROOM_L)], objects=objects, source="example"
    )


def _near_box(xy: np.ndarray, centre: tuple[float, float], half: tuple[float, float]) -> float:
    """Distance (m) from a point to an axis-aligned box's footprint."""
    d = np.maximum(np.abs(xy - np.asarray(centre)) - np.asarray(half), 0.0)
    return float(np.linalg.norm(d))


def test_task_objects_from_roles() -> None:
    objs = mobile_task_objects(_living_room())
    assert (objs.pick.id, objs.pick_support.id, objs.place_support.id) == (
        "can",
        "coffee_table",
        "desk",
    )
    with pytest.raises(MobileTaskError) as e:
        mobile_task_objects(_living_room(), place_support="coffee_table")
    assert e.value.reason == "no_place_support"


@pytest.mark.slow
def test_full_episode_succeeds_and_replays() -> None:
    setup = mobile_setup(_living_room())
    plan = MobilePlanner(setup).plan_episode(0)
    assert isinstance(plan, MobileEpisodePlan), plan
    cfg = MobileRecordConfig(fps=5.0, width=64, height=64)
    rec = execute_mobile(setup, plan, cfg)
    assert rec.outcome is not None and rec.outcome.success, rec.outcome
    n = len(rec.time)
    # sub-tasks in order, each ending once, on its own last frame
    firsts = [int(np.flatnonzero(rec.subtask == k)[0]) for k in range(len(SUBTASKS))]
    assert firsts == sorted(firsts) and firsts[0] == 0
    assert (np.diff(rec.subtask) >= 0).all()
    done = np.flatnonzero(rec.subtask_done)
    assert len(done) == len(SUBTASKS)
    assert list(rec.subtask[done]) == list(range(len(SUBTASKS)))
    assert list(done[:-1] + 1) == firsts[1:] and done[-1] == n - 1
    # the base drives from near the coffee table to near the desk
    arrive_pick = rec.base_pose[firsts[1]]
    assert _near_box(arrive_pick[:2], TABLE, (0.5, 0.3)) < 0.8
    assert np.linalg.norm(arrive_pick[:2] - plan.pick_base[:2]) < 0.05
    end = rec.base_pose[-1]
    assert _near_box(end[:2], DESK, (0.6, 0.3)) < 0.8
    assert np.linalg.norm(end[:2] - plan.place_base[:2]) < 0.05
    assert np.linalg.norm(end[:2] - arrive_pick[:2]) > 1.0
    # signals and images
    assert rec.action.shape == (n, 11) and rec.joint_pos.shape == (n, 7)
    assert set(rec.rgb) == set(ALL_CAMERAS) == set(rec.depth)
    for c in ALL_CAMERAS:
        assert rec.rgb[c].shape == (n, 64, 64, 3) and rec.rgb[c].dtype == np.uint8
        assert rec.depth[c].shape == (n, 64, 64) and rec.depth[c].dtype == np.uint16
        assert rec.rgb[c].any() and rec.depth[c].any()
    # replaying the recorded controls reproduces the states and the images
    again = replay(setup, rec, cfg)
    assert np.array_equal(again.state, rec.state)
    for c in ALL_CAMERAS:
        assert np.array_equal(again.rgb[c], rec.rgb[c]), c
        assert np.array_equal(again.depth[c], rec.depth[c]), c


def test_demo_drives_to_the_poses_the_route_check_verified() -> None:
    """The route check (generation, validation) and the demos judge a scene on the same grid
    with the same footprint and work poses: the demo's drives end at poses the check
    verified, and the episode records which."""
    from factory.nav.route import check_route

    scene = _living_room()
    verdict = check_route(scene)
    assert verdict.ok and verdict.route is not None, verdict
    route = verdict.route
    setup = mobile_setup(scene)
    assert setup.route is not None and setup.route.ok and setup.cleared == ()
    # one grid: the scene compiled alone (the check) and with the robot (the demos)
    assert setup.grid.resolution == route.grid.resolution
    assert np.allclose(setup.grid.origin, route.grid.origin)
    assert np.array_equal(setup.grid.occupied, route.grid.occupied)
    assert setup.route.footprint == route.footprint and setup.route.carry == route.carry
    planner = MobilePlanner(setup)
    assert planner.carry_footprint == route.carry
    assert verdict.route_pick_poses == len(route.route_picks()) > 0
    for seed in (0, 1):
        plan = planner.plan_episode(seed)
        assert isinstance(plan, MobileEpisodePlan), plan
        picks = route.route_picks()
        i = route.pick_index(plan.pick_base)
        assert i >= 0 and route.pick_poses[i] in picks  # a verified pick pose, to 1 um
        goal = route.pick_poses[i]
        assert np.allclose(plan.pick_base[:2], goal.xy, atol=1e-6)
        assert goal in route.picks_from(plan.spawn)  # the lattice connects the spawn to it
        j = route.place_index(plan.place_base)
        assert j >= 0 and route.place_poses[j] in route.route_places(goal)
        assert np.allclose(plan.place_base[:2], route.place_poses[j].xy, atol=1e-6)
        # the plan names them (the episode's metadata ``route``)
        assert (plan.route["pick_index"], plan.route["place_index"]) == (i, j)
        assert np.allclose(plan.route["pick_pose"], goal.as_array(), atol=1e-6)
        assert plan.route["resolution"] == route.grid.resolution
        assert plan.route["route_pick_poses"] == len(picks)


def test_enclosed_place_support_fails_with_nav_failed() -> None:
    setup = mobile_setup(_living_room(enclose_desk=True))
    result = MobilePlanner(setup).plan_episode(0)
    assert isinstance(result, MobilePlanFailure)
    assert result.reason == "nav_failed", result
    assert "desk" in result.detail  # the pick was planned; the route to the desk is closed


@pytest.mark.slow
def test_mobile_stage_cli(cli, tmp_path) -> None:
    """``stage=demos task=mobile_pick_place`` stores a mobile episode in the episode store."""
    from factory.demos.record.episodes import EpisodeStore
    from factory.schema import scene_to_json

    scene = _living_room()
    run = tmp_path / "run"
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    out = cli(
        "stage=demos",
        f"run_dir={run}",
        "task=mobile_pick_place",
        "demos.episodes_per_scene=1",
        "demos.width=32",
        "demos.height=32",
        "demos.fps=5",
        "demos.workers=1",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    info = store.info(eid)
    assert info.task == "mobile_pick_place" and info.success
    assert (info.pick_id, info.support_id, info.target_id) == ("can", "coffee_table", "desk")
    assert info.route["pick_index"] >= 0 and info.route["place_index"] >= 0
    assert len(info.route["pick_pose"]) == 3 and info.route["resolution"] == 0.05
    g = store.arrays(eid)
    n = info.n_frames
    assert g["action"].shape == (n, 11) and g["base_pose"].shape == (n, 3)
    assert list(np.unique(g["subtask"][:])) == [0, 1, 2, 3] and int(g["subtask_done"][:].sum()) == 4
    for cam in ALL_CAMERAS:
        assert g[f"rgb/{cam}"].shape == (n, 32, 32, 3)


def test_light_furniture_in_the_way_is_taken_out() -> None:
    """A stool in the only doorway closes the route for the base: the set-up takes it out
    (and says so), and an episode plans through the doorway."""
    blocked = mobile_setup(_living_room(stool_in_door=True), clear=False)
    assert "route" in blocked.reachable and blocked.cleared == ()
    assert isinstance(MobilePlanner(blocked).plan_episode(0), MobilePlanFailure)
    setup = mobile_setup(_living_room(stool_in_door=True))
    assert setup.cleared == ("stool",) and setup.reachable == ""
    assert "stool" not in {o.id for o in setup.scene.objects}
    plan = MobilePlanner(setup).plan_episode(0)
    assert isinstance(plan, MobileEpisodePlan), plan
    assert plan.pick_base[0] < 3.0 < plan.place_base[0]  # it drove through the doorway


def test_plan_budget_bounds_an_episode() -> None:
    setup = mobile_setup(_living_room())
    result = MobilePlanner(setup, MobileMotionConfig(plan_budget=0.0)).plan_episode(0)
    assert isinstance(result, MobilePlanFailure) and result.reason == PLAN_TIMEOUT
    assert "budget" in result.detail


def _grasp(z: float, contact: float, score: float) -> Grasp:
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])  # straight down
    pose[2, 3] = z
    pts = np.array([[-0.033, 0.0, z], [0.033, 0.0, z]])
    return Grasp(pose, 0.066, 1.0, contact, score, pts)


def test_carry_order_prefers_a_hold_near_the_centre_of_mass() -> None:
    """A can 12 cm tall (centre of mass 6 cm up): a grasp on its rim, 3 mm below the top,
    ranks below one 2.5 cm lower with the pads fully on the can, although the geometric score
    prefers the rim; with hold_weight 0 the order stays."""
    rim, body = _grasp(0.117, 0.67, 1.30), _grasp(0.095, 1.0, 1.28)
    obj = np.eye(4)
    com = np.array([0.0, 0.0, 0.06])
    ranked = carry_order([rim, body], obj, com, 0.12, np.array([-0.6, 0.0]), 1.0, 1.0)
    assert ranked == [body, rim]
    assert carry_order([rim, body], obj, com, 0.12, np.array([-0.6, 0.0]), 1.0, 0.0) == [
        rim,
        body,
    ]
