"""Benchmark of the factory's two renderers' lighting on one scene state: MuJoCo's OpenGL
renderer (the CPU executor and the CPU env) against MuJoCo Warp's ray tracer (the GPU executor
and the Warp env; on Warp's CPU device where there is no CUDA), with every light of the scene
on, then each light alone (the headlight included), per camera: the mean absolute RGB
difference (0-255) and the mean signed one (Warp minus OpenGL).

With ``--refine MAX_EDGE:MAX_NORMAL_DEG[:MIN_EDGE[:MAX_FACES]]`` (repeatable) the run is copied
to a scratch folder whose visual meshes (never the collision pieces) are refined by
:func:`factory.sim.lit_mesh.refine_for_lighting` with those rules, and measured there
too (on top of the meshes as built: the baseline and the copies are compiled with
``compile.light_mesh_edge=0``; ``--edge E`` measures the compiler's own refinement at E):
OpenGL's fixed-function lighting is computed at the vertices and interpolated across each
triangle, Warp's at every ray's hit, so coarse meshes light differently on the two, and
refinement tells by how much (docs/POLICY.md, "Results measured", 2026-11-30).

    python scripts/bench_render_lighting.py --run-dir runs/heldout --scene kitchen_3627575a_2 \\
        --edge 0.1 --refine 0.04:0:0:100000000 --refine 0.15:8 --tag cpu2

Prints and saves JSON to ``benchmarks/results/render-lighting-<tag>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from factory.sim.gl import configure_gl  # noqa: E402

configure_gl("auto")

import mujoco  # noqa: E402

from factory.store import atomic_write_json, git_sha  # noqa: E402

CAMERAS = ("left", "right", "wrist")
SIZE = 128


def reset_state(
    run: Path, scene: str, seed: int, edge: float = 0.0
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The CPU env's model of ``scene``, compiled with ``compile.light_mesh_edge=edge`` (the
    env compiles with the default options; ``0``: the meshes as the assets were built), and
    its state after reset to configuration ``seed``."""
    import dataclasses

    import factory.sim.compile as compile_module

    plain = compile_module.compile_scene

    def compile_with_edge(scene_: Any, root: Any = None, options: Any = None) -> Any:
        base = options or compile_module.CompileOptions()
        return plain(scene_, root, dataclasses.replace(base, light_mesh_edge=edge))

    compile_module.compile_scene = compile_with_edge  # type: ignore[assignment]
    try:
        return _reset_state(run, scene, seed)
    finally:
        compile_module.compile_scene = plain  # type: ignore[assignment]


def _reset_state(run: Path, scene: str, seed: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    from factory.policy.env import make_vec_env
    from factory.policy.eval import Job, run_batch
    from factory.policy.obs_spec import ObsSpec

    spec = ObsSpec(cameras=CAMERAS, width=SIZE, height=SIZE)
    vec, _ = make_vec_env(run, scene, 1, spec, nthread=2, executor="cpu")
    run_batch(
        vec,
        [Job(scene=scene, seed=seed, index=0, max_steps=1)],
        lambda obs, steps: np.zeros((len(steps), vec.action_dim), np.float32),
    )
    sim: Any = vec.sim  # the fixed task's batch simulation: its model and scratch data
    model, data = sim.model, sim.load(0)
    mujoco.mj_forward(model, data)
    return model, data


def draw_opengl(model: mujoco.MjModel, data: mujoco.MjData, names: list[str]) -> list[np.ndarray]:
    """Each camera's RGB (H, W, 3) float as the recordings draw it
    (:class:`~factory.demos.record.frame_render.CameraStrip`: 1 cm near plane, no shadows,
    reflections or skybox, geom groups 0-2)."""
    from factory.demos.record.frame_render import CameraStrip

    cams = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, n) for n in names]
    strip = CameraStrip(model, cams, SIZE, SIZE, "uint16_mm")
    try:
        rgbs, _ = strip.render(data)
    finally:
        strip.close()
    return [x.astype(np.float64) for x in rgbs]


def draw_warp(model: mujoco.MjModel, data: mujoco.MjData, names: list[str]) -> list[np.ndarray]:
    """Each camera's RGB (H, W, 3) float from MuJoCo Warp with the recordings' render context
    (:func:`factory.demos.execute.warp.render_context`)."""
    import mujoco_warp as mjw
    import warp as wp

    from factory.demos.execute.warp import render_context

    wm = mjw.put_model(model)
    rc = render_context(model, 1, (SIZE, SIZE), names)
    wd = mjw.put_data(model, data)
    mjw.forward(wm, wd)
    mjw.refit_bvh(wm, wd, rc)
    mjw.render(wm, wd, rc)
    out = []
    for i in range(len(names)):
        buf = wp.zeros((1, SIZE, SIZE), dtype=wp.vec3)
        mjw.get_rgb(rc, i, buf)
        out.append(np.clip(buf.numpy()[0] * 255.0, 0, 255))
    return out


def draw_time(model: mujoco.MjModel, data: mujoco.MjData, repeats: int = 20) -> dict[str, Any]:
    """OpenGL's time (ms) to draw the three policy cameras of this state as the recordings do
    (after one warm-up draw), and the model's visual faces."""
    import time

    from factory.demos.record.frame_render import CameraStrip
    from factory.robots.panda import CAMERAS as CAMERA_NAMES

    cams = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAMES[c]) for c in CAMERAS]
    strip = CameraStrip(model, cams, SIZE, SIZE, "uint16_mm")
    try:
        strip.render(data)
        t0 = time.perf_counter()
        for _ in range(repeats):
            strip.render(data)
        ms = (time.perf_counter() - t0) / repeats * 1000
    finally:
        strip.close()
    faces = sum(
        int(model.mesh_facenum[i]) for i in range(model.nmesh) if "visual" in model.mesh(i).name
    )
    return {"opengl_ms_per_frame_3_cameras": round(ms, 1), "visual_faces": faces}


def compare(
    model: mujoco.MjModel, data: mujoco.MjData, numquads: int = 0, matte: bool = False
) -> dict[str, Any]:
    """Warp against OpenGL with every light, then with each light alone; ``numquads`` > 0
    sets MuJoCo's ``visual/quality numquads`` first, ``matte`` removes specular light."""
    if numquads > 0:
        model.vis.quality.numquads = numquads
    if matte:
        model.mat_specular[:] = 0
        model.light_specular[:] = 0
        model.vis.headlight.specular[:] = 0
    from factory.robots.panda import CAMERAS as CAMERA_NAMES

    names = [CAMERA_NAMES[c] for c in CAMERAS]

    def row() -> dict[str, Any]:
        a, b = draw_warp(model, data, names), draw_opengl(model, data, names)
        return {
            c: {
                "rgb_mean_abs": round(float(np.abs(x - y).mean()), 2),
                "rgb_mean_signed": round(float((x - y).mean()), 2),
            }
            for c, x, y in zip(CAMERAS, a, b, strict=True)
        }

    out: dict[str, Any] = {"all_lights": row()}
    active, head = model.light_active.copy(), int(model.vis.headlight.active)
    try:
        for k in range(-1, model.nlight):
            model.light_active[:] = 0
            model.vis.headlight.active = 1 if k < 0 else 0
            if k >= 0:
                model.light_active[k] = 1
            kind = "headlight" if k < 0 else ("directional" if model.light_type[k] else "spot")
            out[f"only_{'headlight' if k < 0 else f'light_{k}'}"] = {"kind": kind, **row()}
    finally:
        model.light_active[:] = active
        model.vis.headlight.active = head
    return out


def refined_copy(run: Path, scene: str, spec: Any, into: Path) -> tuple[Path, dict[str, int]]:
    """A copy of ``run``'s scenes and assets whose visual meshes used by ``scene`` are refined
    by :func:`factory.sim.lit_mesh.refine_for_lighting` with ``spec`` (texture coordinates
    carried along); returns it and the face counts."""
    import re

    from factory.sim.lit_mesh import obj_lines, read_obj, refine_for_lighting

    dst = into / run.name
    shutil.copytree(run / "scenes", dst / "scenes")
    shutil.copytree(run / "assets", dst / "assets")
    if (run / "manifest.json").is_file():
        shutil.copy(run / "manifest.json", dst / "manifest.json")
    xml = (run / "scenes" / scene / "model.xml").read_text()
    used = sorted(set(re.findall(r'file="([^"]*visual[^"]*\.obj)"', xml)))
    before = after = 0
    for name in used:
        f = dst / "assets" / name
        vertices, faces, uv = read_obj(f)
        v, fa, t = refine_for_lighting(vertices, faces, uv, spec)
        before += len(faces)
        after += len(fa)
        f.write_text(obj_lines(v, fa, t))
    return dst, {"visual_faces_before": before, "visual_faces_after": after}


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--run-dir", type=Path, required=True)
    ap.add_argument("--scene", required=True)
    ap.add_argument("--seed", type=int, default=None, help="default: its first eval seed")
    ap.add_argument(
        "--refine",
        action="append",
        default=[],
        metavar="MAX_EDGE:MAX_NORMAL_DEG[:MIN_EDGE[:MAX_FACES]]",
        help="also measure with the scene's visual meshes refined so (repeatable; "
        "'0.04:0:0:100000000' is a uniform 4 cm subdivision)",
    )
    ap.add_argument(
        "--edge",
        type=float,
        action="append",
        default=[],
        help="also measure the scene compiled with compile.light_mesh_edge=EDGE (m; repeatable)",
    )
    ap.add_argument(
        "--draw-time",
        action="store_true",
        help="only time OpenGL's drawing of the three cameras, as built and at each --edge "
        "(run it on an idle machine)",
    )
    ap.add_argument(
        "--numquads",
        type=int,
        default=0,
        help="draw box faces in OpenGL with this many quads per side (MuJoCo's "
        "visual/quality numquads; 0: the scene's own)",
    )
    ap.add_argument(
        "--matte",
        action="store_true",
        help="no specular light in either renderer (materials', lights' and the headlight's)",
    )
    ap.add_argument("--tag", default="cpu")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    from factory.policy.env import eval_seed

    seed = args.seed if args.seed is not None else eval_seed(0, args.scene, 0)
    look = (args.numquads, args.matte)
    if args.draw_time:
        rows_t = {
            f"light_mesh_edge_{e:g}m": draw_time(*reset_state(args.run_dir, args.scene, seed, e))
            for e in [0.0, *args.edge]
        }
        for k, v in rows_t.items():
            print(k, v, flush=True)
        _save(args, seed, {"draw_time": rows_t})
        return
    rows: dict[str, Any] = {
        "as_built": compare(*reset_state(args.run_dir, args.scene, seed), *look)
    }
    print("as built", rows["as_built"]["all_lights"], flush=True)
    for edge in args.edge:
        key = f"compiled_light_mesh_edge_{edge:g}m"
        rows[key] = compare(*reset_state(args.run_dir, args.scene, seed, edge), *look)
        print(key, rows[key]["all_lights"], flush=True)
    from factory.sim.lit_mesh import LightingRefinement

    for text in args.refine:
        values = [float(x) for x in text.split(":")]
        spec = LightingRefinement(
            *values[:3], **({"max_faces": int(values[3])} if len(values) > 3 else {})
        )
        with tempfile.TemporaryDirectory() as tmp:
            copy, faces = refined_copy(args.run_dir, args.scene, spec, Path(tmp))
            key = f"refined_{text}"
            rows[key] = {**faces, **compare(*reset_state(copy, args.scene, seed), *look)}
            print(key, faces, rows[key]["all_lights"], flush=True)
    _save(args, seed, rows)


def _save(args: argparse.Namespace, seed: int, rows: dict[str, Any]) -> None:
    """Writes the JSON of a run."""
    import warp as wp

    out = {
        "schema_version": 1,
        "benchmark": "render-lighting",
        "date": datetime.date.today().isoformat(),
        "machine": platform.platform(),
        "warp_device": str(wp.get_preferred_device()),
        "git_sha": (git_sha() or "")[:7],
        "command": " ".join(sys.argv),
        "scene": args.scene,
        "seed": seed,
        "size_px": SIZE,
        "numquads": args.numquads,
        "matte": args.matte,
        "results": rows,
    }
    path = args.out or ROOT / "benchmarks" / "results" / f"render-lighting-{args.tag}.json"
    atomic_write_json(path, out)
    print(f"saved {path}")


if __name__ == "__main__":
    main()
