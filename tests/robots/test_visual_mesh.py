"""Simplified visual meshes for the robot cache (``factory.robots.visual_mesh``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from factory.robots.visual_mesh import (
    cluster,
    face_budget,
    simplify_arrays,
    simplify_visual_mesh,
    weld,
)

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("fast_simplification")


def _soup(mesh) -> tuple[np.ndarray, np.ndarray]:
    """A mesh as an OBJ export stores it with normals: every face its own three corners."""
    v = np.asarray(mesh.vertices)[np.asarray(mesh.faces)].reshape(-1, 3)
    return v, np.arange(len(v)).reshape(-1, 3)


def test_weld_joins_repeated_corners() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=2)
    v, f = _soup(sphere)
    wv, wf = weld(v, f)
    assert len(wv) == len(sphere.vertices) and len(wf) == len(sphere.faces)
    edges = np.sort(np.concatenate([wf[:, [0, 1]], wf[:, [1, 2]], wf[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert (count == 2).all()  # closed again: every edge between two faces


def test_cluster_keeps_both_sides_of_a_thin_wall() -> None:
    """Two opposite-facing sheets 1 mm apart collapse onto one another at a 5 mm cell: both
    windings stay, so the wall is seen from either side."""
    top = trimesh.creation.box(extents=(0.1, 0.1, 0.001))
    v, f = cluster(top.vertices, top.faces, 0.005)
    assert len(f) > 0
    normals = trimesh.Trimesh(v, f, process=False).face_normals
    assert (normals[:, 2] > 0.9).any() and (normals[:, 2] < -0.9).any()


def test_simplified_sphere_keeps_its_shape() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.1)  # 20,480 faces
    v, f, cell = simplify_arrays(*_soup(sphere), 1000)
    assert 500 <= len(f) <= 1000 and cell > 0
    radius = np.linalg.norm(v, axis=1)
    assert np.abs(radius - 0.1).max() < 0.003  # vertices stay on the sphere (3 mm)
    simple = trimesh.Trimesh(v, f, process=False)
    assert simple.area == pytest.approx(sphere.area, rel=0.03)
    assert simple.is_watertight


def test_many_small_pieces_reach_the_budget() -> None:
    """A plate with 300 separate bolts of 8 faces each (2,412 faces): edge collapse alone
    cannot merge separate pieces; clustering brings the mesh within the budget."""
    parts = [trimesh.creation.box(extents=(0.6, 0.4, 0.01))]
    rng = np.random.default_rng(0)
    for x, y in rng.uniform([-0.28, -0.18], [0.28, 0.18], size=(300, 2)):
        bolt = trimesh.creation.cylinder(radius=0.003, height=0.004, sections=4)
        bolt.apply_translation((x, y, 0.007))
        parts.append(bolt)
    plate = trimesh.util.concatenate(parts)
    v, f, cell = simplify_arrays(*_soup(plate), 600)
    assert len(f) <= 600 and cell > 0
    lo, hi = v.min(axis=0), v.max(axis=0)
    assert np.allclose(hi[:2] - lo[:2], (0.6, 0.4), atol=0.02)  # the plate's outline stays


def test_budget_grows_with_the_size_of_the_mesh() -> None:
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    assert face_budget(box.vertices, 1000) == 1000
    big = trimesh.creation.box(extents=(0.6, 0.4, 0.5))  # 0.88 m across
    assert face_budget(big.vertices, 1000) == round(1000 * np.sqrt(0.77) / 0.4)


@pytest.mark.parametrize("suffix", [".obj", ".stl"])
def test_simplify_visual_mesh_writes_a_mesh_mujoco_reads(tmp_path: Path, suffix: str) -> None:
    import mujoco

    src = tmp_path / f"src{suffix}"
    trimesh.creation.icosphere(subdivisions=4, radius=0.05).export(src)
    dst = tmp_path / f"out{suffix}"
    done = simplify_visual_mesh(src, dst, 400)
    assert done.faces_in == 5120 and done.faces_out <= 400
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(dst))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    model = spec.compile()
    assert model.mesh_facenum[0] == done.faces_out
    radius = np.linalg.norm(model.mesh_vert, axis=1)
    assert radius.max() == pytest.approx(0.05, abs=0.002)
    assert radius.min() > 0.045
