"""The textured real meshes (robosuite's, through the asset library) above the procedural
assets of the same requests, rendered by MuJoCo's OpenGL renderer and, with ``--warp``, a row
by MuJoCo Warp's renderer (``use_textures=True``), with statistics as JSON; optionally a crop
of a generated scene's render below.

    python scripts/render_real_meshes.py --out docs/images/real_meshes.png \
        [--scene-image run/scenes/<id>/renders/<view>.png --scene-crop x0 y0 x1 y1] \
        [--scene-json run/scenes/<id>/scene.json] \
        [--warp cpu] [--json stats.json]

Each object gets a camera of its own (side view, uniform headlight). Statistics per object:
the pixel spread (std, 0..255) of the textured and untextured renders of each renderer
inside the object, and the correlation of Warp's textured image with OpenGL's.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger("render_real_meshes")

REQUESTS = (
    "a coke can",
    "a water bottle",
    "milk",
    "a box of cereal",
    "a slice of bread",
    "a lemon",
)
SIZE = 160
"""Pixels (square) of each object's image."""


def _scene(assets: Path) -> tuple[Any, list[tuple[str, str]]]:
    """Two rows on a concrete floor: the real meshes (y = 0.5) and the procedural assets of
    the same requests (y = 1.5); returns the scene and (object id, label) pairs."""
    from factory.assets import AssetLibrary
    from factory.schema import (
        AssetRef,
        Physics,
        Placement,
        Room,
        Scene,
        SceneObject,
        Size3,
        Vec3,
    )

    libs = {"real": AssetLibrary(assets), "proc": AssetLibrary(assets, real_meshes=False)}
    objs, labels = [], []
    for row, (kind, lib) in enumerate(libs.items()):
        for i, text in enumerate(REQUESTS):
            meta, res = lib.from_text(text, seed=0)
            oid = f"{kind}_{i}"
            objs.append(
                SceneObject(
                    id=oid,
                    room_id="room",
                    category=res.spec.category,
                    position=Vec3(0.5 + 0.6 * i, 0.5 + 2.5 * row, 0.0),
                    dimensions=Size3(*meta.extents),
                    placement=Placement(kind="floor", support_id="room"),
                    asset=AssetRef(backend=meta.backend, asset_id=meta.asset_id),
                    physics=Physics(mass=float(meta.mass or 0.1), static=True),
                    license=meta.license,
                )
            )
            labels.append((oid, f"{text} ({meta.backend})"))
    room = Room(
        id="room",
        room_type="test",
        position=Vec3(0, 0, 0),
        dimensions=Size3(0.6 * len(REQUESTS) + 0.4, 3.5, 2.0),
        floor_material="concrete",
    )
    return Scene(id="real_meshes", rooms=[room], objects=objs, seed=0), labels


def _model(scene: Any, assets: Path, textures: bool) -> Any:
    """The compiled scene with a camera ``cam/<id>`` looking at each object from the front
    and a little above, at a distance that frames it; uniform light (headlight ambient)."""
    from factory.sim.compile import CompileOptions, build_spec

    spec, _ = build_spec(scene, assets, CompileOptions(textures=textures, ceiling=False))
    for o in scene.objects:
        w, ln, h = o.dimensions.as_tuple()
        dist = 1.6 * max(h, w, ln) + 0.05
        pitch = math.radians(15)
        x, y, z = (
            o.position.x,
            o.position.y - dist * math.cos(pitch),
            h / 2 + dist * math.sin(pitch),
        )
        # x axis right, y axis up-and-back: the camera looks along +y, tilted down
        spec.worldbody.add_camera(
            name=f"cam/{o.id}",
            pos=[x, y, z],
            xyaxes=[1, 0, 0, 0, math.sin(pitch), math.cos(pitch)],
            fovy=40,
        )
    model = spec.compile()
    model.light_diffuse[:] = 0.3
    model.light_specular[:] = 0.0
    model.vis.headlight.ambient[:] = 0.6
    model.vis.headlight.diffuse[:] = 0.3
    model.vis.map.znear = 0.001
    return model


def _gl(model: Any, ids: list[str]) -> list[np.ndarray]:
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    out = []
    with mujoco.Renderer(model, SIZE, SIZE) as r:
        for oid in ids:
            r.update_scene(data, camera=f"cam/{oid}")
            out.append(r.render().copy())
    return out


def _warp(model: Any, ids: list[str], device: str, textures: bool) -> list[np.ndarray]:
    """MuJoCo Warp's ray-traced images of every camera (uint8 RGB)."""
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    names = [f"cam/{oid}" for oid in ids]
    with wp.ScopedDevice(device):
        m = mjw.put_model(model)
        d = mjw.put_data(model, data)
        rc = mjw.create_render_context(
            model,
            nworld=1,
            cam_res=(SIZE, SIZE),
            render_rgb=True,
            render_depth=False,
            use_textures=textures,
            use_shadows=False,
            cam_active=names,
        )
        mjw.refit_bvh(m, d, rc)
        mjw.render(m, d, rc)
        out = []
        for k in range(len(names)):
            rgb = wp.zeros((1, SIZE, SIZE), dtype=wp.vec3, device=device)
            mjw.get_rgb(rc, k, rgb)
            im = np.clip(rgb.numpy()[0] * 255.0 + 0.5, 0, 255).astype(np.uint8)
            out.append(im)
    return out


def _stats(name: str, t: np.ndarray, f: np.ndarray) -> dict[str, float]:
    """Spread (std, 0..255, the most varied channel) of the textured and untextured images in
    the centre third of the image (inside every object)."""
    c = slice(SIZE // 3, 2 * SIZE // 3)
    tt, ff = t[c, c].reshape(-1, 3).astype(float), f[c, c].reshape(-1, 3).astype(float)
    return {
        f"{name}_textured_std": float(tt.std(0).max()),
        f"{name}_flat_std": float(ff.std(0).max()),
    }


def _close_up(scene_json: Path) -> np.ndarray:
    """A close-up (480 x 320 px) of a generated scene's pick object, from the front and
    above, compiled from its ``scene.json`` with the run's assets."""
    import mujoco

    from factory.schema import load_scene
    from factory.sim.compile import compile_scene

    scene = load_scene(scene_json)
    assets = scene_json.parents[2] / "assets"
    pick = next(o for o in scene.objects if o.task_role == "pick")
    model = compile_scene(scene, assets).model
    model.vis.map.znear = 0.001
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    body = model.body(pick.id).id
    cam.lookat[:] = data.xpos[body] + [0.0, 0.0, pick.dimensions.height / 2]
    cam.distance, cam.elevation, cam.azimuth = 0.45, -25.0, 120.0
    with mujoco.Renderer(model, 320, 480) as r:
        r.update_scene(data, camera=cam)
        return r.render().copy()


def _figure(
    images: list[np.ndarray],
    labels: list[str],
    scene_crop: np.ndarray | None,
    out: Path,
    close_up: np.ndarray | None = None,
) -> None:
    from PIL import Image, ImageDraw

    n = len(REQUESTS)
    pad = 18
    rows = math.ceil(len(images) / n)
    w = n * SIZE
    h = rows * (SIZE + pad)
    if scene_crop is not None:
        scale = 2.0  # the stage's render, cropped and doubled
        crop = Image.fromarray(scene_crop).resize(
            (int(scene_crop.shape[1] * scale), int(scene_crop.shape[0] * scale)),
            Image.Resampling.LANCZOS,
        )
        h += crop.height + pad
    canvas = Image.new("RGB", (w, h), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    for k, (im, label) in enumerate(zip(images, labels, strict=True)):
        row, col = divmod(k, n)
        canvas.paste(Image.fromarray(im), (col * SIZE, row * (SIZE + pad) + pad))
        draw.text((col * SIZE + 3, row * (SIZE + pad) + 3), label, fill=(0, 0, 0))
    if scene_crop is not None:
        y = rows * (SIZE + pad)
        draw.text(
            (3, y + 3),
            '"a kitchen where the robot picks up a coke can and puts it in the bowl" '
            "(left: stage=generate's corner render, cropped; right: a close-up of the scene)",
            fill=(0, 0, 0),
        )
        canvas.paste(crop, (0, y + pad))
        if close_up is not None:
            canvas.paste(Image.fromarray(close_up), (crop.width, y + pad))
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/images/real_meshes.png"))
    ap.add_argument("--assets", type=Path, default=None, help="assets folder (default: a temp)")
    ap.add_argument("--scene-image", type=Path, default=None)
    ap.add_argument(
        "--scene-crop", type=int, nargs=4, default=None, metavar=("X0", "Y0", "X1", "Y1")
    )
    ap.add_argument("--scene-json", type=Path, default=None, help="close-up of its pick object")
    ap.add_argument("--warp", default=None, help="also render with MuJoCo Warp on this device")
    ap.add_argument("--json", type=Path, default=None, help="write the statistics here")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    os.environ.setdefault("MUJOCO_GL", "egl")
    assets = args.assets or Path(tempfile.mkdtemp(prefix="real_meshes_")) / "assets"
    t0 = time.perf_counter()
    scene, labels = _scene(assets)
    stats: dict[str, Any] = {"assets_s": round(time.perf_counter() - t0, 2)}
    ids = [oid for oid, _ in labels]
    textured, flat = _model(scene, assets, True), _model(scene, assets, False)
    gl_t, gl_f = _gl(textured, ids), _gl(flat, ids)
    for oid, a, b in zip(ids, gl_t, gl_f, strict=True):
        stats[oid] = _stats("gl", a, b)
    figure_images, figure_labels = list(gl_t), [lab for _, lab in labels]
    if args.warp:
        t1 = time.perf_counter()
        wp_t = _warp(textured, ids, args.warp, True)
        wp_f = _warp(textured, ids, args.warp, False)
        stats["warp_s"] = round(time.perf_counter() - t1, 1)
        for oid, a, b, g in zip(ids, wp_t, wp_f, gl_t, strict=True):
            stats[oid] |= _stats("warp", a, b)
            c = slice(SIZE // 3, 2 * SIZE // 3)
            x, y = a[c, c].astype(float).ravel(), g[c, c].astype(float).ravel()
            r = float(np.corrcoef(x, y)[0, 1]) if x.std() > 0 and y.std() > 0 else float("nan")
            stats[oid]["warp_gl_r"] = r
        figure_images += wp_t[: len(REQUESTS)]
        figure_labels += [f"{text} (Warp)" for text in REQUESTS]
    crop = None
    if args.scene_image is not None:
        from PIL import Image

        im = np.asarray(Image.open(args.scene_image).convert("RGB"))
        if args.scene_crop:
            x0, y0, x1, y1 = args.scene_crop
            im = im[y0:y1, x0:x1]
        crop = im
    close = _close_up(args.scene_json) if args.scene_json else None
    _figure(figure_images, figure_labels, crop, args.out, close)
    text = json.dumps(stats, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
