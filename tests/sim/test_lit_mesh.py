"""Visual meshes refined for lighting (factory.sim.lit_mesh) and their use by the compiler."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from factory.errors import CompileError
from factory.sim.compile import CompileOptions
from factory.sim.lit_mesh import (
    LightingRefinement,
    lit_copy,
    obj_lines,
    read_obj,
    refine_for_lighting,
)


def _longest_edges(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    tri = v[f]
    return np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2).max(1)


@pytest.mark.parametrize("edge", [0.3, 0.1, 0.07])
def test_a_box_is_split_to_the_edge_and_stays_the_same_closed_surface(edge: float) -> None:
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.4))
    v, f, uv = refine_for_lighting(box.vertices, box.faces, None, LightingRefinement(edge, 0))
    assert uv is None
    assert _longest_edges(v, f).max() <= edge + 1e-9
    np.testing.assert_array_equal(v[: len(box.vertices)], box.vertices)  # old vertices kept
    out = trimesh.Trimesh(v, f, process=False)
    assert out.area == pytest.approx(box.area)
    assert out.volume == pytest.approx(box.volume)  # winding kept (signed volume)
    merged = trimesh.Trimesh(v, f)  # no cracks: every edge shared by exactly two faces
    assert merged.is_watertight and merged.is_winding_consistent
    # every new vertex lies on an old face's plane: the surface is unchanged
    assert np.abs(np.abs(v).max(0) - [0.5, 0.3, 0.2]).max() < 1e-12


def test_texture_coordinates_follow_the_surface() -> None:
    """A linear map from position to uv stays exact on every refined corner."""
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uv = quad[faces][..., :2] * [2.0, 3.0] + [0.1, 0.2]
    v, f, t = refine_for_lighting(quad, faces, uv, LightingRefinement(0.2, 0))
    assert t is not None and t.shape == (len(f), 3, 2)
    np.testing.assert_allclose(t, v[f][..., :2] * [2.0, 3.0] + [0.1, 0.2], atol=1e-12)


def test_only_long_edges_are_split() -> None:
    """A small flat mesh is left as it is; a long thin one is split along its length only."""
    small = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    v, f, _ = refine_for_lighting(small.vertices, small.faces, None, LightingRefinement(0.1, 0))
    assert len(f) == len(small.faces)
    rod = trimesh.creation.box(extents=(1.0, 0.02, 0.02))
    v, f, _ = refine_for_lighting(rod.vertices, rod.faces, None, LightingRefinement(0.1, 0))
    assert _longest_edges(v, f).max() <= 0.1 + 1e-9
    assert len(f) < 12 * 4**4 // 3  # far fewer than splitting every face four times over


def test_the_curvature_rule_ends_and_the_budget_holds() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=1, radius=0.3)
    spec = LightingRefinement(max_edge=0, max_normal_deg=5, min_edge=0.02)
    v, f, _ = refine_for_lighting(sphere.vertices, sphere.faces, None, spec)
    assert len(f) > len(sphere.faces)
    assert np.allclose(np.linalg.norm(v[: len(sphere.vertices)], axis=1), 0.3)
    budget = LightingRefinement(max_edge=0.01, max_normal_deg=0, max_faces=500)
    _, f2, _ = refine_for_lighting(sphere.vertices, sphere.faces, None, budget)
    assert len(sphere.faces) < len(f2) <= 500


@pytest.mark.parametrize(
    "kwargs", [{"max_edge": -1.0}, {"max_normal_deg": -2.0}, {"min_edge": -1.0}, {"max_faces": 0}]
)
def test_bad_rules_name_the_field(kwargs: dict[str, float]) -> None:
    with pytest.raises(CompileError, match=next(iter(kwargs))):
        LightingRefinement(**kwargs)  # type: ignore[arg-type]


def test_compile_option_must_not_be_negative() -> None:
    with pytest.raises(CompileError, match=r"compile.light_mesh_edge must be >= 0"):
        CompileOptions(light_mesh_edge=-0.1)


def test_lit_copy_is_written_once_beside_the_mesh(tmp_path: Path) -> None:
    box = trimesh.creation.box(extents=(0.8, 0.4, 0.3))
    uv = np.random.default_rng(0).random((len(box.faces), 3, 2))
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "visual_0.obj").write_text(obj_lines(box.vertices, box.faces, uv))
    name = lit_copy(tmp_path, "parts/visual_0.obj", 0.1)
    assert name == "parts/lit100mm-visual_0.obj"
    v, f, t = read_obj(tmp_path / name)
    assert t is not None and _longest_edges(v, f).max() <= 0.1 + 1e-6
    stamp = (tmp_path / name).stat().st_mtime_ns
    assert lit_copy(tmp_path, "parts/visual_0.obj", 0.1) == name
    assert (tmp_path / name).stat().st_mtime_ns == stamp  # reused, not rewritten
    # the edge is measured at the object's scale: half size, fewer splits
    half = lit_copy(tmp_path, "parts/visual_0.obj", 0.1, [0.5, 0.5, 0.5])
    assert half == name  # one copy per asset and edge (MuJoCo: one scale per mesh asset)
    assert lit_copy(tmp_path, "parts/visual_0.obj", 2.0) == "parts/visual_0.obj"  # no split
    assert not list(tmp_path.rglob(".*"))  # no temporary file left


def test_read_obj_rejects_broken_files(tmp_path: Path) -> None:
    with pytest.raises(CompileError, match="cannot read"):
        read_obj(tmp_path / "missing.obj")
    (tmp_path / "empty.obj").write_text("v 0 0 0\n")
    with pytest.raises(CompileError, match="no faces"):
        read_obj(tmp_path / "empty.obj")
    (tmp_path / "mixed.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n"
    )
    with pytest.raises(CompileError, match="some faces have texture"):
        read_obj(tmp_path / "mixed.obj")


def test_the_compiler_draws_refined_visual_meshes_and_keeps_the_physics(
    tmp_path: Path, make_kitchen: Any
) -> None:
    """A procedural kitchen compiled with ``light_mesh_edge=0.1`` draws refined copies of its
    long visual meshes; its collision meshes, masses and contacts are those of the unrefined
    one. The default (0) refines nothing."""
    import mujoco

    from factory.sim.compile import compile_scene

    assets = tmp_path / "assets"
    scene = make_kitchen(assets)
    plain = compile_scene(scene, assets, CompileOptions()).model
    assert not list(assets.rglob("lit*.obj"))
    lit = compile_scene(scene, assets, CompileOptions(light_mesh_edge=0.1)).model
    written = sorted(assets.rglob("lit100mm-*.obj"))
    assert written, "no visual mesh was refined"
    assert not any("collision" in p.name for p in written)

    def faces(model: mujoco.MjModel, kind: str) -> int:
        names = [model.mesh(i).name for i in range(model.nmesh)]
        return sum(int(model.mesh_facenum[i]) for i, n in enumerate(names) if kind in n)

    assert faces(lit, "visual") > faces(plain, "visual")
    assert faces(lit, "collision") == faces(plain, "collision")
    np.testing.assert_allclose(lit.body_mass, plain.body_mass)
    np.testing.assert_allclose(lit.body_inertia, plain.body_inertia, rtol=1e-6, atol=1e-12)
    for model in (plain, lit):
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
    # the refined meshes' extents are the original ones
    plain_mesh = {plain.mesh(i).name: i for i in range(plain.nmesh)}
    for i in range(lit.nmesh):
        j = plain_mesh[lit.mesh(i).name]
        va = lit.mesh_vert[lit.mesh_vertadr[i] : lit.mesh_vertadr[i] + lit.mesh_vertnum[i]]
        vb = plain.mesh_vert[plain.mesh_vertadr[j] : plain.mesh_vertadr[j] + plain.mesh_vertnum[j]]
        np.testing.assert_allclose(va.min(0), vb.min(0), atol=1e-5)
        np.testing.assert_allclose(va.max(0), vb.max(0), atol=1e-5)
