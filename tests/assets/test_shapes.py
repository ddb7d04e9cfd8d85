"""Shaped parts (rounded boxes, cushions, solids and rings of revolution, pleats) and the
templates built from them: exact sizes, clean meshes, convex collision of <= 64 vertices,
unstretched UVs, and supports (and rest heights in MuJoCo) where the plain boxes had them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec, generate
from factory.assets.geometry import MAX_HULL_VERTICES, Part
from factory.assets.primitives import moved, pleated, revolved, ring, rounded_box
from factory.assets.uv import STRETCH_BOUND, stretch, uv_of
from factory.schema import AssetRef, Physics, Placement, Room, Scene, SceneObject, Size3, Vec3
from factory.sim.compile import compile_scene
from factory.sim.stability import FreeBodies, StabilityProtocol, check_stability

WHITE = (1.0, 1.0, 1.0, 1.0)
RESHAPED = (
    "toilet",
    "clock",
    "table_lamp",
    "floor_lamp",
    "potted_plant",
    "small_plant",
    "curtain",
    "sofa",
    "armchair",
    "loveseat",
    "bed",
    "crib",
    "cushion",
    "dining_table",
    "desk",
    "dresser",
    "wardrobe",
    "bookshelf",
    "refrigerator",
    "oven",
    "microwave",
    "dishwasher",
    "washing_machine",
)


def _stretch_worst(part: Part) -> tuple[float, float]:
    ratio = stretch(part.visual, uv_of(part.visual, part.mapping, part.labels))
    ok = np.isfinite(ratio)
    med = float(np.median(ratio[ok]))
    return med, max(float(ratio[ok].max() / med), float(med / ratio[ok].min()))


def _clean(part: Part) -> None:
    mesh = part.visual
    assert mesh.is_watertight and mesh.is_volume, part.name
    assert float(mesh.area_faces.min()) > 1e-10, f"{part.name}: degenerate triangle"
    for hull in part.collision:
        assert hull.is_convex and 4 <= len(hull.vertices) <= MAX_HULL_VERTICES
        assert hull.volume > 0


@pytest.mark.parametrize(
    ("extents", "radius", "segments", "bulge"),
    [
        ((1.6, 0.9, 0.04), 0.015, 2, 0.0),
        ((0.02, 0.3, 1.8), 0.006, 1, 0.0),
        ((0.6, 0.6, 0.15), 0.05, 2, 0.02),
        ((0.05, 0.05, 0.05), 0.5, 3, 0.0),  # radius capped
    ],
)
def test_rounded_box_is_the_requested_box(
    extents: tuple[float, float, float], radius: float, segments: int, bulge: float
) -> None:
    center = (0.1, -0.2, 0.5)
    part = rounded_box(extents, center, "oak", WHITE, radius, segments=segments, bulge=bulge)
    _clean(part)
    lo, hi = part.visual.bounds
    assert np.allclose(hi - lo, extents, atol=1e-3) and np.allclose(
        (lo + hi) / 2, center, atol=1e-3
    )
    (box,) = part.collision  # the collision is the box itself: rest heights do not change
    assert np.allclose(box.bounds, part.visual.bounds, atol=1e-9) and len(box.vertices) == 8
    med, worst = _stretch_worst(part)
    assert 0.95 < med < 1.05 and worst < 1.3, (med, worst)
    # rounded: the corners are cut away (less volume than the box), flat faces stay flat
    assert part.visual.volume < box.volume
    if bulge:
        top = part.visual.vertices[:, 2].max()
        rim = part.visual.vertices[np.abs(part.visual.vertices[:, 0] - center[0]) > 0.29, 2].max()
        assert top - rim > 0.5 * bulge  # a crowned cushion, not a box


def test_rounded_box_maps_the_same_when_turned() -> None:
    a = rounded_box((0.5, 0.3, 0.2), (0, 0, 0.1), "oak", WHITE, 0.04)
    b = rounded_box((0.5, 0.3, 0.2), (0, 0, 0.1), "oak", WHITE, 0.04)
    tf = trimesh.transformations.rotation_matrix(0.7, [0, 0, 1])
    tf[:3, 3] = [1.0, 2.0, 0.0]
    moved(b, tf)
    ra = stretch(a.visual, uv_of(a.visual, a.mapping, a.labels))
    rb = stretch(b.visual, uv_of(b.visual, b.mapping, b.labels))
    assert np.allclose(ra, rb, atol=1e-9)
    assert np.allclose(b.collision[0].volume, 0.5 * 0.3 * 0.2)


def test_solids_and_rings_of_revolution() -> None:
    body = revolved(
        [(0.1, 0), (0.12, 0.02), (0.05, 0.1), (0.08, 0.3), (0.02, 0.35)], "ceramic", WHITE
    )
    _clean(body)
    # the bands' frusta are the faceted solid: their volumes add up to the visual's
    assert sum(h.volume for h in body.collision) == pytest.approx(body.visual.volume, rel=0.03)
    shade = revolved([(0.2, 0), (0.14, 0.25)], "fabric", WHITE, collision="hull")
    _clean(shade)
    assert len(shade.collision) == 1
    seat = ring([(0.1, 0), (0.16, 0), (0.16, 0.02), (0.1, 0.02)], "plastic", WHITE)
    _clean(seat)
    assert sum(h.volume for h in seat.collision) == pytest.approx(seat.visual.volume, rel=0.05)
    for part in (body, shade, seat):
        _med, worst = _stretch_worst(part)
        assert worst < 1.1, (part.name, worst)
    folds = pleated(0.7, 0.08, 2.2, 0.01, 7, (0, 0, 1.1), "fabric", WHITE, gather=0.9)
    _clean(folds)
    assert _stretch_worst(folds)[1] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("category", RESHAPED)
def test_reshaped_templates_are_clean(category: str) -> None:
    """Several seeds: exact extents (within 1 mm), watertight parts without degenerate
    triangles, convex collision of <= 64 vertices, UVs within the stretch bound."""
    cat = CATEGORIES[category]
    for seed in range(4):
        gen = generate(AssetSpec(category, seed=seed))
        assert np.abs(gen.visual.extents - np.array(gen.dims)).max() < 1e-3
        for part in gen.shape.parts:
            _clean(part)
            med, worst = _stretch_worst(part)
            assert med > 0.5 and worst <= STRETCH_BOUND, (category, part.name, worst)
        assert cat.mass[0] <= gen.mass <= cat.mass[1]


def _support(category: str, name: str, seed: int = 0) -> tuple[float, np.ndarray]:
    gen = generate(AssetSpec(category, seed=seed))
    sup = next(s for s in gen.shape.supports if s.name == name)
    return sup.z, np.array(gen.dims)


@pytest.mark.parametrize(
    ("category", "support", "height"),
    [
        ("dining_table", "top", lambda d: d[2]),
        ("desk", "top", lambda d: d[2]),
        ("sofa", "seat", lambda d: 0.45 * d[2]),
        ("armchair", "seat", lambda d: 0.45 * d[2]),
        ("bed", "mattress", lambda d: 0.47 * d[2]),
        ("dresser", "case_top", lambda d: d[2]),
        ("kitchen_cabinet", "case_top", lambda d: d[2]),
        ("refrigerator", "top", lambda d: d[2]),
        ("oven", "top", lambda d: d[2]),
        ("microwave", "top", lambda d: d[2]),
        ("dishwasher", "top", lambda d: d[2]),
        ("washing_machine", "top", lambda d: d[2]),
        ("cushion", "top", lambda d: d[2]),
    ],
)
def test_support_heights_are_those_of_the_boxes(category: str, support: str, height) -> None:
    for seed in range(3):
        z, dims = _support(category, support, seed)
        assert z == pytest.approx(height(dims), abs=1e-6), (category, seed)


def test_bookshelf_boards_unchanged() -> None:
    gen = generate(AssetSpec("bookshelf", seed=1))
    boards = sorted(s.z for s in gen.shape.supports if "board" in s.name)
    w, _ln, h = gen.dims
    t = float(np.clip(0.02 * max(w, h), 0.012, 0.03))
    n = len(boards)
    expect = [t + (h - t - t) * (b + 1) / (n + 1) + t / 2 for b in range(n)]
    assert np.allclose(boards, expect, atol=1e-6)


def test_clock_faces_the_room_and_toilet_has_its_parts() -> None:
    clock = generate(AssetSpec("clock", seed=2))
    parts = {p.name: p for p in clock.shape.parts}
    assert parts["minute_hand"].visual.bounds[0, 1] < parts["dial"].visual.bounds[0, 1]
    assert parts["body"].visual.bounds[1, 1] == pytest.approx(clock.dims[1] / 2, abs=1e-6)
    toilet = generate(AssetSpec("toilet", seed=0))
    names = {p.name for p in toilet.shape.parts}
    assert {"bowl", "seat", "lid", "cistern", "pedestal"} <= names
    bowl = next(p for p in toilet.shape.parts if p.name == "bowl")
    assert len(bowl.collision) > 8  # a hollow bowl of convex wall pieces


def test_new_shapes_are_written_textured(tmp_path: Path) -> None:
    lib = AssetLibrary(tmp_path)
    for category in ("sofa", "washing_machine", "curtain", "potted_plant"):
        meta = lib.get(AssetSpec(category, seed=0))
        for entry in meta.visual_parts:
            text = (tmp_path / meta.asset_id / entry["file"]).read_text()
            assert "\nvt " in text and entry["texture"], (category, entry["name"])


def _scene(lib: AssetLibrary, items: list[tuple]) -> Scene:
    room = Room(id="r", room_type="living room", position=Vec3(0, 0, 0), dimensions=Size3(6, 6, 3))
    objs = []
    for oid, category, pos, support, static in items:
        meta = lib.get(AssetSpec(category, seed=0))
        objs.append(
            SceneObject(
                id=oid,
                room_id="r",
                category=category,
                position=Vec3(*pos),
                dimensions=Size3(*meta.extents),
                placement=Placement("on_top", support) if support else Placement(),
                asset=AssetRef("procedural", meta.asset_id),
                physics=Physics(
                    mass=meta.mass or 1.0, friction=meta.friction or 0.6, static=static
                ),
            )
        )
    return Scene(id="shapes", rooms=[room], objects=objs, source="example")


def test_objects_rest_on_the_new_shapes_where_they_did(tmp_path: Path) -> None:
    """A cushion on the sofa's seat, a mug on the oven's top and a book on the bed: each
    settles at the support's height, and the furniture stays where it stood."""
    lib = AssetLibrary(tmp_path)
    z = {
        c: next(s for s in lib.get(AssetSpec(c, seed=0)).supports if s["name"] == n)["z"]
        for c, n in (("sofa", "seat"), ("oven", "top"), ("bed", "mattress"))
    }
    scene = _scene(
        lib,
        [
            ("sofa", "sofa", (1.5, 1.5, 0.0), None, False),
            ("oven", "oven", (4.0, 1.5, 0.0), None, False),
            ("bed", "bed", (2.5, 4.0, 0.0), None, False),
            ("cushion", "cushion", (1.5, 1.4, z["sofa"] + 0.01), "sofa", False),
            ("mug", "mug", (4.0, 1.45, z["oven"] + 0.005), "oven", False),
            ("book", "book", (2.5, 3.6, z["bed"] + 0.005), "bed", False),
        ],
    )
    model = compile_scene(scene, tmp_path).model
    result = check_stability(model, protocol=StabilityProtocol(resettle=False))
    free = FreeBodies.of(model)
    q = result.settled_qpos[0]

    def pos(name: str) -> np.ndarray:
        a = free.qposadr[free.index(name)]
        return q[a : a + 3]

    assert pos("sofa")[2] == pytest.approx(0.0, abs=0.005)
    assert pos("oven")[2] == pytest.approx(0.0, abs=0.005)
    assert pos("cushion")[2] == pytest.approx(z["sofa"], abs=0.01)
    assert pos("mug")[2] == pytest.approx(z["oven"], abs=0.005)
    assert pos("book")[2] == pytest.approx(z["bed"], abs=0.01)
    assert result.stable[0], result.candidate(0)
    assert math.isfinite(float(q.sum()))
