"""Base paths with OMPL RRTConnect on the room's inflated grid; goals beside a support."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from nav_rooms import OBSTACLE, build_room

pytest.importorskip("ompl")

from factory.nav import (
    NAV_FAILED,
    NavError,
    OccupancyGrid,
    base_pose_beside,
    plan_base_path,
    random_free_pose,
)
from factory.nav.rrt import path_free

RES = 0.05
RADIUS = 0.45


def _grid(**kw) -> tuple[OccupancyGrid, OccupancyGrid]:
    model, data = build_room(**kw)
    raw = OccupancyGrid.from_model(model, data, resolution=RES)
    return raw, raw.inflate(RADIUS)


@pytest.fixture(scope="module")
def grids() -> tuple[OccupancyGrid, OccupancyGrid]:
    return _grid()


def _dense(path: np.ndarray, step: float) -> np.ndarray:
    pts = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, math.ceil(np.linalg.norm(b - a) / step))
        pts.append(a + np.outer(np.linspace(0, 1, n + 1)[1:], b - a))
    return np.concatenate(pts)


def test_path_around_the_obstacle(grids) -> None:
    raw, inflated = grids
    start, goal = np.array([1.0, 2.0]), np.array([5.0, 2.0])
    res = plan_base_path(inflated, start, goal, seed=3)
    assert res.ok, res.detail
    assert res.reason == ""
    assert np.allclose(res.path[0], start) and np.allclose(res.path[-1], goal)
    assert len(res.path) >= 3  # the straight line is blocked
    dense = _dense(res.path, RES / 10)
    assert inflated.free(dense).all()
    # the base keeps its radius from the real obstacle, to within a cell
    assert raw.clearance(dense).min() >= RADIUS - RES
    cx, cy, hx, hy = OBSTACLE
    assert not ((np.abs(dense[:, 0] - cx) < hx) & (np.abs(dense[:, 1] - cy) < hy)).any()
    assert res.length >= 4.0
    assert path_free(inflated, res.path, RES / 10)


def test_straight_line_when_free(grids) -> None:
    _, inflated = grids
    res = plan_base_path(inflated, np.array([1.0, 0.8]), np.array([5.0, 0.8]))
    assert res.ok and len(res.path) == 2


def test_blocked_start_or_goal(grids) -> None:
    _, inflated = grids
    inside = np.array([OBSTACLE[0], OBSTACLE[1]])
    res = plan_base_path(inflated, np.array([1.0, 2.0]), inside)
    assert not res.ok and res.reason == NAV_FAILED and "goal" in res.detail
    assert res.path.shape == (0, 2)
    res = plan_base_path(inflated, np.array([0.2, 2.0]), np.array([5.0, 2.0]))  # too near a wall
    assert not res.ok and res.reason == NAV_FAILED and "start" in res.detail
    res = plan_base_path(inflated, np.array([-9.0, 2.0]), np.array([5.0, 2.0]))
    assert not res.ok and "off the grid" in res.detail


def test_doorway_open_and_blocked() -> None:
    start, goal = np.array([1.0, 1.0]), np.array([5.0, 3.0])
    _, open_grid = _grid(obstacle=False, divider="open")
    res = plan_base_path(open_grid, start, goal, seed=1)
    assert res.ok, res.detail
    dense = _dense(res.path, RES / 10)
    assert open_grid.free(dense).all()
    crossing = dense[np.argmin(np.abs(dense[:, 0] - 3.0))]
    assert 1.4 + RADIUS - RES <= crossing[1] <= 2.6 - RADIUS + RES  # through the doorway
    _, shut = _grid(obstacle=False, divider="blocked")
    res = plan_base_path(shut, start, goal, seed=1)
    assert not res.ok
    assert res.reason == NAV_FAILED
    assert "not connected" in res.detail


def test_poses_beside_a_support(grids) -> None:
    """The obstacle as a table: poses face it from outside at the reach distance."""
    _, inflated = grids
    cx, cy, hx, hy = OBSTACLE
    box = (cx - hx, cy - hy, cx + hx, cy + hy)
    start = np.array([1.0, 1.0])
    poses = base_pose_beside(inflated, box, start_xy=start, target_xy=np.array([cx - 0.3, cy]))
    assert poses
    for p in poses:
        assert inflated.free(p.xy)
        assert inflated.component(p.xy) == inflated.component(start)
        assert 0.55 - 1e-9 <= p.offset <= 0.75 + 1e-9
        facing = np.array([math.cos(p.yaw), math.sin(p.yaw)])
        to_box = np.array([cx, cy]) - p.xy
        # the support's middle is ahead, its near edge at the offset along the heading
        assert facing @ to_box > 0
        gap = {"-x": box[0] - p.x, "+x": p.x - box[2], "-y": box[1] - p.y, "+y": p.y - box[3]}
        assert gap[p.side] == pytest.approx(p.offset)
    assert poses[0].side == "-x"  # nearest to the target on the -x half
    # a start outside the room reaches none of them
    assert base_pose_beside(inflated, box, start_xy=np.array([-0.2, 2.0])) == []
    with pytest.raises(NavError):
        base_pose_beside(inflated, (1.0, 1.0, 0.5, 2.0))


def test_random_free_pose(grids) -> None:
    _, inflated = grids
    rng = np.random.default_rng(0)
    inside = inflated.component(np.array([1.0, 1.0]))
    for _ in range(20):
        p = random_free_pose(inflated, rng)
        assert inflated.free(p.xy) and inflated.component(p.xy) == inside  # the room's inside
        assert -math.pi <= p.yaw < math.pi
    q = random_free_pose(inflated, np.random.default_rng(1), near_xy=np.array([5.0, 3.0]))
    assert inflated.component(q.xy) == inside
    a = random_free_pose(inflated, np.random.default_rng(7), min_clearance=0.3)
    b = random_free_pose(inflated, np.random.default_rng(7), min_clearance=0.3)
    assert a == b
    with pytest.raises(NavError):
        random_free_pose(inflated, rng, near_xy=np.array([OBSTACLE[0], OBSTACLE[1]]))
