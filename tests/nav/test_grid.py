"""The occupancy grid of a hand-built room: footprints, band, exclusions, inflation, lookups."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_rooms import OBSTACLE, WALL_T, build_room

from factory.nav import NavError, OccupancyGrid
from factory.nav.grid import convex_hull_2d

RES = 0.05


@pytest.fixture(scope="module")
def room():
    return build_room()


@pytest.fixture(scope="module")
def grid(room) -> OccupancyGrid:
    model, data = room
    return OccupancyGrid.from_model(model, data, resolution=RES)


@pytest.fixture(scope="module")
def extras() -> OccupancyGrid:
    model, data = build_room(obstacle=False, extras=True)
    return OccupancyGrid.from_model(model, data, resolution=RES, bounds=(-0.5, -0.5, 6.5, 4.5))


def _cells_in(grid: OccupancyGrid, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Centres (k, 2) of the cells whose centre lies inside the rectangle."""
    ny, nx = grid.shape
    ij = np.stack(np.meshgrid(np.arange(nx), np.arange(ny)), axis=-1).reshape(-1, 2)
    c = grid.cell_to_world(ij)
    keep = (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1)
    return c[keep]


def test_bounds_cover_the_walls(grid: OccupancyGrid) -> None:
    xmin, ymin, xmax, ymax = grid.bounds
    assert xmin == pytest.approx(-WALL_T / 2 - 0.2) and ymin == pytest.approx(-WALL_T / 2 - 0.2)
    assert xmax >= 6 + WALL_T / 2 + 0.2 - 1e-9 and ymax >= 4 + WALL_T / 2 + 0.2 - 1e-9
    assert grid.inflation == 0.0


def test_obstacle_cells_occupied_and_free_space_free(grid: OccupancyGrid) -> None:
    cx, cy, hx, hy = OBSTACLE
    inside = _cells_in(grid, cx - hx, cy - hy, cx + hx, cy + hy)
    assert len(inside) > 100 and not grid.free(inside).any()
    # a ring one cell beyond the box is free (thin boundary cells may be occupied)
    ring = _cells_in(
        grid, cx - hx - 2 * RES, cy - hy - 2 * RES, cx + hx + 2 * RES, cy + hy + 2 * RES
    )
    ring = ring[(np.abs(ring[:, 0] - cx) > hx + RES) | (np.abs(ring[:, 1] - cy) > hy + RES)]
    assert grid.free(ring).all()
    room_free = _cells_in(grid, 0.2, 0.2, 2.4, 3.8)
    assert grid.free(room_free).all()
    # walls occupied, outside the room free, off the grid not free
    assert not grid.free(np.array([[0.0, 2.0], [6.0, 2.0], [3.0, 0.0], [3.0, 4.0]])).any()
    assert grid.free(np.array([-0.2, 2.0]))
    assert not grid.free(np.array([-5.0, 2.0]))


def test_occupied_area_matches_the_box(grid: OccupancyGrid) -> None:
    """Cells overlapping the box: its area rounded out to whole cells."""
    cx, cy, hx, hy = OBSTACLE
    sub = grid.world_to_cell(np.array([[cx - 0.6, cy - 0.8], [cx + 0.6, cy + 0.8]]))
    block = grid.occupied[sub[0, 1] : sub[1, 1], sub[0, 0] : sub[1, 0]]
    cells = block.sum()
    exact = (2 * hx / RES) * (2 * hy / RES)
    assert exact <= cells <= (2 * hx / RES + 2) * (2 * hy / RES + 2)


def test_inflation_grows_by_the_radius(grid: OccupancyGrid) -> None:
    radius = 0.45
    inflated = grid.inflate(radius)
    assert inflated.inflation == radius
    assert inflated.occupied.sum() > grid.occupied.sum()
    assert (inflated.occupied | ~grid.occupied).all()  # a superset
    cx, cy, hx, _ = OBSTACLE
    # along the row through the obstacle's centre, the occupied run spans the box + radius
    xs = np.arange(1.0, 5.0, RES / 5)
    occ = ~inflated.free(np.stack([xs, np.full_like(xs, cy)], axis=1))
    left, right = xs[occ].min(), xs[occ].max()
    assert left == pytest.approx(cx - hx - radius, abs=RES + 1e-9)
    assert right == pytest.approx(cx + hx + radius, abs=RES + 1e-9)
    # and so does the clearance of the raw grid
    assert grid.clearance(np.array([cx + hx + 1.0, cy])) == pytest.approx(1.0, abs=RES)
    assert grid.clearance(np.array([cx, cy])) == 0.0
    with pytest.raises(NavError):
        grid.inflate(-0.1)


def test_world_cell_round_trip(grid: OccupancyGrid) -> None:
    pts = np.array([[0.123, 3.21], [5.5, 0.05], [2.0, 2.0]])
    centres = grid.cell_to_world(grid.world_to_cell(pts))
    assert np.abs(centres - pts).max() <= RES / 2 + 1e-9
    assert (grid.world_to_cell(centres) == grid.world_to_cell(pts)).all()
    assert grid.inside(pts).all() and not grid.inside(np.array([100.0, 0.0]))


def test_band_planes_and_exclusions(extras: OccupancyGrid) -> None:
    g = extras
    assert g.free(np.array([3.0, 2.0]))  # the floor slab and the ground plane are no obstacles
    assert g.free(np.array([1.0, 3.0]))  # the shelf is above the band
    assert g.free(np.array([2.0, 3.3]))  # visual-only geoms do not collide
    assert g.free(np.array([4.2, 0.7]))  # the robot's own bodies are left out
    assert not g.free(np.array([1.0, 2.0]))  # a free (movable) object on the floor counts


def test_footprint_shapes(extras: OccupancyGrid) -> None:
    g = extras
    # a box turned 45 degrees: a diamond; its axis-aligned box's corner region stays free
    r = 0.3 * math.sqrt(2)
    assert not g.free(np.array([[1.0 + r - 0.06, 1.0], [1.0, 1.0 + r - 0.06]])).any()
    assert g.free(np.array([1.0 + 0.25, 1.0 + 0.25]))
    # an upright cylinder: a disc
    assert not g.free(np.array([[5.0 + 0.25, 1.0], [5.0, 1.0 - 0.25]])).any()
    assert g.free(np.array([5.0 + 0.25, 1.0 + 0.25]))
    # a mesh prism: the triangle (4.5, 3), (5.1, 3), (4.5, 3.6)
    assert not g.free(np.array([[4.6, 3.1], [5.0, 3.05], [4.55, 3.5]])).any()
    assert g.free(np.array([5.0, 3.5]))


def test_components(room) -> None:
    model, data = room
    g = OccupancyGrid.from_model(model, data, resolution=RES).inflate(0.45)
    inside, outside = np.array([1.0, 1.0]), np.array([-0.2, 2.0])
    assert g.component(inside) > 0
    assert g.component(inside) == g.component(np.array([5.0, 3.0]))  # around the obstacle
    assert g.component(outside) != g.component(inside)
    assert g.component(np.array([3.0, 2.0])) == 0


def test_convex_hull_and_errors() -> None:
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [1, 0.5]], float)
    hull = convex_hull_2d(square)
    assert len(hull) == 4
    area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    assert area == pytest.approx(1.0)  # counter-clockwise
    with pytest.raises(NavError):
        OccupancyGrid(0.0, (0.0, 0.0), np.zeros((2, 2), bool))
    with pytest.raises(NavError):
        OccupancyGrid(0.1, (0.0, 0.0), np.zeros((0, 2), bool))
