"""Base paths for the base's footprint in SE(2), work poses and spawn poses, in a hand-built
room: the footprint passes a doorway too narrow for the disc around it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_rooms import OBSTACLE, build_room

pytest.importorskip("ompl")

from factory.nav import (
    NAV_FAILED,
    Footprint,
    NavError,
    OccupancyGrid,
    plan_se2_path,
    random_footprint_pose,
    time_base_path,
    work_poses,
)

RES = 0.05
FP = Footprint(rear=0.35, front=0.40, half_width=0.25, margin=0.04)
NARROW = (1.7, 2.4)
"""A doorway 0.7 m wide: the footprint (0.58 m wide) passes lengthwise, a 0.45 m disc not."""


def _raw(**kw) -> OccupancyGrid:
    model, data = build_room(**kw)
    return OccupancyGrid.from_model(model, data, resolution=RES)


@pytest.fixture(scope="module")
def room() -> OccupancyGrid:
    return _raw()


@pytest.fixture(scope="module")
def narrow() -> OccupancyGrid:
    return _raw(obstacle=False, divider="open", door=NARROW)


def _corners(pose: np.ndarray, fp: Footprint) -> np.ndarray:
    """Points (k, 2) on the footprint's rectangle (without the margin), world frame."""
    xs = np.linspace(-fp.rear, fp.front, 9)
    ys = np.linspace(-fp.half_width, fp.half_width, 5)
    local = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return pose[:2] + local @ np.array([[c, s], [-s, c]])


def _dense(path: np.ndarray, fp: Footprint) -> np.ndarray:
    return np.concatenate(
        [fp.motion(path[i], path[i + 1], RES / 5) for i in range(len(path) - 1)] or [path]
    )


def test_discs_cover_the_rectangle() -> None:
    pts = _corners(np.zeros(3), FP)
    centres = np.stack([FP.centres, np.zeros(FP.discs)], axis=1)
    d = np.linalg.norm(pts[:, None] - centres[None], axis=2).min(axis=1)
    assert (d <= FP.radius - FP.margin + 1e-9).all()
    assert FP.radius < 0.45  # narrower than the disc around the base
    with pytest.raises(NavError):
        Footprint(half_width=0.0)


def test_pose_free_lengthwise_not_across(narrow: OccupancyGrid) -> None:
    mid = (NARROW[0] + NARROW[1]) / 2
    assert FP.free(narrow, np.array([3.0, mid, 0.0]))  # through the doorway, lengthwise
    assert not FP.free(narrow, np.array([3.0, mid, math.pi / 2]))  # across it
    assert not narrow.inflate(0.45).free(np.array([3.0, mid]))  # the disc does not fit


def test_path_through_a_narrow_doorway(narrow: OccupancyGrid) -> None:
    start, goal = np.array([1.2, 1.0, math.pi / 2]), np.array([4.8, 3.0, -math.pi])
    disc = narrow.inflate(0.45)  # a disc around the base: the two halves are not connected
    assert disc.component(start[:2]) != disc.component(goal[:2])
    res = plan_se2_path(narrow, FP, start, goal, seed=1)
    assert res.ok, res.detail
    path = res.path
    assert path.shape[1] == 3 and np.allclose(path[0], start)
    assert np.allclose(path[-1, :2], goal[:2])
    assert math.isclose(math.remainder(path[-1, 2] - goal[2], 2 * math.pi), 0.0, abs_tol=1e-9)
    assert (np.abs(np.diff(path[:, 2])) <= math.pi + 1e-9).all()  # yaws unwrapped
    dense = _dense(path, FP)
    assert FP.free(narrow, dense).all()
    for pose in dense[:: max(1, len(dense) // 200)]:  # the rectangle itself is in free cells
        assert narrow.free(_corners(pose, FP)).all()
    crossing = dense[np.argmin(np.abs(dense[:, 0] - 3.0))]
    assert NARROW[0] < crossing[1] < NARROW[1]
    # the timed trajectory follows the checked motions and ends at rest at the goal
    traj = time_base_path(path, dt=0.02)
    assert np.allclose(traj.q[-1], path[-1]) and np.allclose(traj.qd[-1], 0.0)
    assert FP.free(narrow, traj.q).all()


def test_se2_failures(room: OccupancyGrid, narrow: OccupancyGrid) -> None:
    inside = np.array([OBSTACLE[0], OBSTACLE[1], 0.0])
    res = plan_se2_path(room, FP, np.array([1.0, 2.0, 0.0]), inside)
    assert not res.ok and res.reason == NAV_FAILED and "goal" in res.detail
    shut = _raw(obstacle=False, divider="blocked")
    res = plan_se2_path(shut, FP, np.array([1.2, 1.0, 0.0]), np.array([4.8, 3.0, 0.0]))
    assert not res.ok and "not connected" in res.detail
    straight = plan_se2_path(room, FP, np.array([1.0, 0.8, 0.0]), np.array([5.0, 0.8, 0.5]))
    assert straight.ok and len(straight.path) == 2


def test_same_seed_same_path_whatever_ran_before(room: OccupancyGrid) -> None:
    """OMPL is seeded per query: a query gives the same path in a process that ran other
    queries with other seeds first (as a worker does, episode after episode)."""
    start, goal = np.array([1.0, 2.0, 0.0]), np.array([5.0, 2.0, math.pi / 2])
    first = plan_se2_path(room, FP, start, goal, seed=11)
    plan_se2_path(room, FP, start, goal, seed=12)
    plan_se2_path(room, FP, np.array([1.0, 0.8, 0.0]), goal, seed=13)
    again = plan_se2_path(room, FP, start, goal, seed=11)
    assert first.ok and again.ok
    assert np.array_equal(first.path, again.path)


def test_work_poses_reach_the_target(room: OccupancyGrid) -> None:
    """The obstacle as a table with an object near its -x end."""
    cx, cy, hx, hy = OBSTACLE
    box = (cx - hx, cy - hy, cx + hx, cy + hy)
    target = np.array([[cx - 0.25, cy + 0.4]])
    arm_x = 0.2
    poses = work_poses(room, FP, box, arm_x, target, (0.3, 0.75), start_xy=np.array([1.0, 1.0]))
    assert poses and {p.side for p in poses} >= {"-x", "radial"}
    inscribed = FP.inscribed_grid(room)
    for p in poses:
        assert FP.free(room, p.as_array())
        assert inscribed.component(p.xy) == inscribed.component(np.array([1.0, 1.0]))
        arm = p.xy + arm_x * np.array([math.cos(p.yaw), math.sin(p.yaw)])
        assert 0.3 - 1e-9 <= np.linalg.norm(arm - target[0]) <= 0.75 + 1e-9
        assert p.offset == pytest.approx(np.linalg.norm(arm - target[0]))
        if p.side == "radial":  # facing the target
            to = target[0] - p.xy
            assert math.isclose(
                math.remainder(math.atan2(to[1], to[0]) - p.yaw, 2 * math.pi), 0.0, abs_tol=1e-6
            )
    best = poses[0]
    assert abs(best.offset - 0.55) < 0.1
    assert work_poses(room, FP, box, arm_x, target, start_xy=np.array([-0.5, 2.0])) == []
    with pytest.raises(NavError):
        work_poses(room, FP, (1.0, 1.0, 0.5, 2.0), arm_x, target)


def test_random_footprint_pose(room: OccupancyGrid) -> None:
    inscribed = FP.inscribed_grid(room)
    inside = inscribed.component(np.array([1.0, 1.0]))
    for k in range(10):
        p = random_footprint_pose(room, FP, np.random.default_rng(k))
        assert FP.free(room, p.as_array()) and inscribed.component(p.xy) == inside
    a = random_footprint_pose(room, FP, np.random.default_rng(5), near_xy=np.array([5.0, 3.0]))
    b = random_footprint_pose(room, FP, np.random.default_rng(5), near_xy=np.array([5.0, 3.0]))
    assert a == b
    with pytest.raises(NavError):
        random_footprint_pose(room, FP, np.random.default_rng(0), near_xy=np.array([-9.0, 0.0]))
