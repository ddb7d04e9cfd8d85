"""Procedural textures: every material renders textured on the CPU renderer, the cache is
deterministic and content-addressed, condition words change the images, and the UV mappings
of every category stay within the stated stretch bound."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec, generate, resolve
from factory.assets.physics import MATERIALS
from factory.assets.uv import STRETCH_BOUND, planar_uv, stretch, uv_of
from factory.schema import (
    AssetRef,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
    Wall,
)
from factory.sim.compile import CompileOptions, compile_scene
from factory.sim.materials import SURFACES
from factory.textures.appearance import appearance
from factory.textures.cache import TextureSpec, read_record, texture_file
from factory.textures.conditions import kinds_in
from factory.textures.looks import LOOKS, look_for
from factory.textures.noise import luma
from factory.textures.registry import GENERATORS, TextureError

BLOCK = 0.3
"""Edge (m) of the test blocks."""


def _blocks_scene(materials: list[str], assets: Path) -> tuple[Scene, list[str]]:
    """One 0.3 m block of each material (in its own colour, opaque) in a row on a concrete
    floor."""
    lib = AssetLibrary(assets)
    room = Room(
        id="room",
        room_type="test",
        position=Vec3(0, 0, 0),
        dimensions=Size3(len(materials) * 0.6 + 1, 2, 2.5),
        floor_material="concrete",
    )
    objects = []
    for i, m in enumerate(materials):
        rgba = (*MATERIALS[m].rgba[:3], 1.0)  # opaque: glass would show the floor behind
        spec = AssetSpec("toy_block", (BLOCK,) * 3, (m, m), (rgba, rgba), seed=i)
        meta = lib.get(spec)
        objects.append(
            SceneObject(
                id=f"block_{i}",
                room_id="room",
                category="toy_block",
                position=Vec3(0.5 + 0.6 * i, 1.0, 0.0),
                dimensions=Size3(BLOCK, BLOCK, BLOCK),
                placement=Placement(kind="floor", support_id="room"),
                asset=AssetRef(backend="procedural", asset_id=meta.asset_id),
                physics=Physics(mass=1.0, static=True),
            )
        )
    return Scene(id="blocks", rooms=[room], objects=objects, seed=0), [o.id for o in objects]


def _top_views(model: mujoco.MjModel, centres: list[tuple[float, float]]) -> list[np.ndarray]:
    """A 48 px close-up looking straight down at each block's top (its middle 0.2 m), in
    uniform ambient light (no shading: a pixel is the material colour times the texture)."""
    model.light_diffuse[:] = 0.0
    model.light_specular[:] = 0.0
    model.light_ambient[:] = 0.0
    model.vis.headlight.ambient[:] = 1.0
    model.vis.headlight.diffuse[:] = 0.0
    model.vis.headlight.specular[:] = 0.0
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.elevation, cam.azimuth, cam.distance = -90.0, 90.0, 0.45
    out = []
    with mujoco.Renderer(model, 48, 48) as r:
        for x, y in centres:
            cam.lookat[:] = [x, y, BLOCK]
            r.update_scene(data, camera=cam)
            out.append(r.render()[8:-8, 8:-8].astype(np.float32))
    return out


def test_every_asset_material_renders_textured(tmp_path: Path) -> None:
    """Every material of the asset library, through the real path (asset build, OBJ with
    UVs, compile, CPU renderer): the block's top shows a texture (pixels vary far more than
    with textures off)."""
    materials = sorted(MATERIALS)
    scene, ids = _blocks_scene(materials, tmp_path)
    textured = compile_scene(scene, tmp_path).model
    flat = compile_scene(scene, tmp_path, CompileOptions(textures=False)).model
    assert textured.ntex > len({look_for(m)[0] for m in materials}) - 1
    for k in range(len(ids)):  # every visual part mesh carries texture coordinates
        geom = textured.geom(f"block_{k}/visual_0")
        assert textured.mesh_texcoordnum[geom.dataid[0]] > 0
        assert textured.mat_texid[geom.matid[0], mujoco.mjtTextureRole.mjTEXROLE_RGB] >= 0
    centres = [(o.position.x, o.position.y) for o in scene.objects]
    for m, im_t, im_f in zip(materials, _top_views(textured, centres), _top_views(flat, centres)):
        s_t = float(im_t.reshape(-1, 3).std(axis=0).max())  # 0..255, the most varied channel
        s_f = float(im_f.reshape(-1, 3).std(axis=0).max())
        mean = float(im_t.mean())
        msg = f"{m}: textured std {s_t:.2f}, flat {s_f:.2f} (mean {mean:.0f})"
        assert s_t > 0.01 * mean and s_t > 2.0 * s_f + 0.3, msg


def test_every_look_makes_a_varied_image(tmp_path: Path) -> None:
    """Every look of the table (architecture too) gives a non-constant image, and every
    asset material and every named surface has a look of its own."""
    for name in MATERIALS:
        assert look_for(name)[0] == name
    for name in SURFACES:
        assert look_for(name, default="nothing-here")[0] != "nothing-here" or name == "glass"
    for key, look in LOOKS.items():
        assert look.generator in GENERATORS
        app = appearance(key, (0.6, 0.5, 0.4, 1.0), tmp_path, size=64)
        from PIL import Image

        im = np.asarray(Image.open(app.texture.path), np.float32)
        assert im.shape == (64, 64, 3)
        assert im.std() > 1.0, f"{key}: flat texture"
        assert np.all(np.asarray(app.rgba) <= 1.0)


def test_floors_and_walls_are_textured(tmp_path: Path) -> None:
    room = Room(
        id="r",
        room_type="test",
        position=Vec3(0, 0, 0),
        dimensions=Size3(3, 3, 2.5),
        walls=[Wall(id="w", start=Vec3(0, 0, 0), end=Vec3(3, 0, 0), height=2.5, material="brick")],
        floor_material="oak",
    )
    scene = Scene(id="s", rooms=[room], seed=1)
    model = compile_scene(scene, tmp_path, CompileOptions(ceiling=True)).model
    for geom in ("r/floor", "r/w/0", "r/ceiling"):
        mat = model.geom(geom).matid[0]
        assert model.mat_texid[mat, mujoco.mjtTextureRole.mjTEXROLE_RGB] >= 0, geom
        assert model.mat_texuniform[mat]
    # MuJoCo repeats a texuniform texture on an upright box face by the box's thickness: the
    # wall piece's material scales the vertical repeat by height over thickness
    wall = model.geom("r/w/0")
    rep = model.mat_texrepeat[wall.matid[0]]
    assert rep[1] / rep[0] == pytest.approx(wall.size[2] / wall.size[1], rel=1e-3)
    floor_rep = model.mat_texrepeat[model.geom("r/floor").matid[0]]
    assert floor_rep[0] == floor_rep[1] == pytest.approx(2.0 / LOOKS["hardwood"].tile)
    names = sorted(p.name for p in (tmp_path / "textures").iterdir())
    assert any(n.startswith("planks-") for n in names) and any(
        n.startswith("brick-") for n in names
    )
    plain = compile_scene(scene, tmp_path, CompileOptions(textures=False)).model
    assert plain.ntex < model.ntex


def test_texture_cache_is_deterministic_and_content_addressed(tmp_path: Path) -> None:
    spec = TextureSpec("planks", (("rows", 6), ("species", "oak")), seed=2, size=128)
    a = texture_file(spec, tmp_path / "a")
    b = texture_file(spec, tmp_path / "b")
    assert a.key == b.key == spec.key() and a.path.name == f"{spec.key()}.png"
    assert a.path.read_bytes() == b.path.read_bytes()  # same key -> identical bytes
    mtime = a.path.stat().st_mtime_ns
    again = texture_file(spec, tmp_path / "a")  # cached: not made again
    assert again.path.stat().st_mtime_ns == mtime and again.gain == a.gain
    record = read_record(a.path)
    assert record["schema_version"] == 1 and record["key"] == a.key
    other = texture_file(TextureSpec(spec.generator, spec.params, seed=3, size=128), tmp_path)
    assert other.key != a.key
    from PIL import Image

    ia = np.asarray(Image.open(a.path), np.float32)
    io = np.asarray(Image.open(other.path), np.float32)
    assert np.abs(ia - io).mean() > 5.0  # a different seed is a different image
    # a damaged file is made again
    a.path.write_bytes(b"not a png")
    from factory.textures import cache

    cache._GAINS.clear()
    fixed = texture_file(spec, tmp_path / "a")
    assert fixed.path.read_bytes() == b.path.read_bytes()
    with pytest.raises(TextureError, match="unknown texture generator"):
        texture_file(TextureSpec("nope"), tmp_path)
    with pytest.raises(TextureError, match="not one of"):
        texture_file(TextureSpec("wood", size=300), tmp_path)


def _rendered(app) -> np.ndarray:  # type: ignore[no-untyped-def]
    """What MuJoCo shows: the texture times the material colour (0..1)."""
    from PIL import Image

    im = np.asarray(Image.open(app.texture.path), np.float32) / 255.0
    return im * np.asarray(app.rgba[:3], np.float32)


def test_condition_words_change_the_texture_statistics(tmp_path: Path) -> None:
    steel = MATERIALS["steel"].rgba
    clean = _rendered(appearance("steel", steel, tmp_path, seed=0))
    rusty = _rendered(appearance("steel", steel, tmp_path, seed=0, kinds=("rust",)))
    # rust turns grey steel orange-brown: red over blue goes up by at least 0.1, and the
    # surface becomes patchy (luminance spread at least doubles)
    red = (clean[..., 0] - clean[..., 2]).mean(), (rusty[..., 0] - rusty[..., 2]).mean()
    assert red[1] - red[0] > 0.1, red
    assert luma(rusty).std() > 2 * luma(clean).std()
    walnut = MATERIALS["walnut"].rgba
    dark = _rendered(appearance("walnut", walnut, tmp_path))
    dusty = _rendered(appearance("dusty walnut", walnut, tmp_path))
    assert luma(dusty).mean() > luma(dark).mean() + 0.1  # dust settles light on dark wood
    assert appearance("metal", steel, tmp_path, kinds=("gold",)).look == "gold"
    assert appearance("fabric", (0.5, 0.1, 0.2, 1), tmp_path, kinds=("luxury",)).look == "velvet"
    polished = appearance("marble", (0.9, 0.9, 0.9, 1), tmp_path, kinds=("polished",))
    assert polished.finish.shininess > LOOKS["marble"].finish.shininess


def test_condition_words_reach_assets_and_rooms(tmp_path: Path) -> None:
    assert kinds_in("a dusty, rusty old shelf") == ("dust", "rust", "wear")
    assert kinds_in("a 5 year old's room") == ()
    res = resolve("a muddy wooden chair")
    assert res.spec.finish == ("mud",)
    lib = AssetLibrary(tmp_path)
    meta, _ = lib.from_text("a wooden chair", seed=1, finish=("mud",))
    clean, _ = lib.from_text("a wooden chair", seed=1)
    assert meta.asset_id != clean.asset_id
    assert all(p["weathering"] == ["mud"] for p in meta.visual_parts)
    assert all(p["weathering"] == [] for p in clean.visual_parts)
    from factory.scenes.floorplan import init_scene

    scene, _ = init_scene("a dusty old garage", seed=0)
    room = scene.rooms[0]
    assert room.floor_material.startswith("dusty old ")
    assert all(w.material.startswith("dusty old ") for w in room.walls)
    clean_scene, _ = init_scene("a garage", seed=0)
    assert clean_scene.rooms[0].floor_material == room.floor_material.removeprefix("dusty old ")


def _extruded() -> trimesh.Trimesh:
    """An L-shaped profile (0.4 x 0.3 m) extruded 0.05 m: two caps and six side strips."""
    pts = np.array([(0, 0), (0.4, 0), (0.4, 0.1), (0.1, 0.1), (0.1, 0.3), (0, 0.3)], float)
    tris = np.array([(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)])
    return trimesh.creation.extrude_triangulation(pts, tris, 0.05)


@pytest.mark.parametrize("category", sorted(CATEGORIES))
def test_uv_stretch_is_bounded(category: str) -> None:
    """Every face's UV area / 3-D area stays within STRETCH_BOUND of its part's median and no
    face with area has a degenerate UV triangle."""
    gen = generate(AssetSpec(category, seed=0))
    for part in gen.shape.parts:
        uv = uv_of(part.visual, part.mapping, part.labels)
        ratio = stretch(part.visual, uv)
        ok = np.isfinite(ratio)
        assert ok.any()
        med = float(np.median(ratio[ok]))
        assert med > 0.5, f"{category}/{part.name}: median UV scale {med:.3f}"
        worst = max(float(ratio[ok].max() / med), float(med / ratio[ok].min()))
        assert worst <= STRETCH_BOUND, f"{category}/{part.name} ({part.mapping}): {worst:.2f}"


def test_extruded_prisms_map_without_stretch() -> None:
    mesh = _extruded()
    ratio = stretch(mesh, planar_uv(mesh))
    assert np.allclose(ratio[np.isfinite(ratio)], 1.0, atol=1e-6)
