"""Benchmark of fisheye rendering: frames per second of ``FisheyeRenderer`` on CPU cores.

    python scripts/bench_fisheye.py [--cores 1] [--resolutions 128 256] [--fov 180]
        [--frames 200] [--out benchmarks/results/fisheye-cpu1.json]

Renders the example kitchen (``factory/data/examples/kitchen_pick_place``) through a fisheye
camera added to the model at 1.2 m looking across the room. The process pins itself to
``--cores`` cores (``sched_setaffinity``) and Mesa's llvmpipe to as many render threads
(``LP_NUM_THREADS``), before the GL context exists. Per resolution it reports the set-up time
(lookup table + GL context), frames/s of ``render`` (RGB + ray-length depth), the split between
drawing and reading the cube faces (``render_atlas``) and the numpy resampling, and for scale
one pinhole ``mujoco.Renderer`` frame (RGB + depth, two passes) of the same size. The JSON is
printed and saved.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "factory" / "data" / "examples" / "kitchen_pick_place" / "scene.json"


def _timed(fn: Any, frames: int) -> float:
    """Seconds per call of ``fn`` over ``frames`` calls, after 3 warm-up calls."""
    for _ in range(3):
        fn()
    t0 = time.perf_counter()
    for _ in range(frames):
        fn()
    return (time.perf_counter() - t0) / frames


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cores", type=int, default=1)
    p.add_argument("--resolutions", type=int, nargs="+", default=[128, 256])
    p.add_argument("--fov", type=float, default=180.0)
    p.add_argument("--frames", type=int, default=200)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    cores = sorted(os.sched_getaffinity(0))[: args.cores]
    os.sched_setaffinity(0, cores)
    os.environ["LP_NUM_THREADS"] = str(args.cores)  # Mesa llvmpipe render threads
    os.environ["OMP_NUM_THREADS"] = str(args.cores)

    from factory.sim.gl import configure_gl

    gl = configure_gl("auto")
    import mujoco
    import numpy as np

    from factory.schema import load_scene
    from factory.sim.compile import compile_scene
    from factory.sim.fisheye import FisheyeRenderer, FisheyeSpec

    spec = compile_scene(load_scene(SCENE)).spec
    # looking along world +x, +z up: x_cam = -y, y_cam = +z
    rot = np.column_stack([(0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0)])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.reshape(-1))
    spec.worldbody.add_camera(name="fisheye", pos=[1.0, 2.5, 1.2], quat=quat)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)

    results: dict[str, Any] = {}
    for res in args.resolutions:
        lens = FisheyeSpec(resolution=res, fov_deg=args.fov)
        t0 = time.perf_counter()
        fisheye = FisheyeRenderer(model, lens)
        setup = time.perf_counter() - t0
        rgb, depth = fisheye.render(data, "fisheye")
        total = _timed(lambda f=fisheye: f.render(data, "fisheye"), args.frames)
        atlas = _timed(lambda f=fisheye: f.render_atlas(data, "fisheye"), args.frames)
        fisheye.close()
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, res)
        model.vis.global_.offheight = max(model.vis.global_.offheight, res)
        model.vis.quality.offsamples = 0
        pin = mujoco.Renderer(model, res, res)
        pin.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        pin.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        pin.scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False

        def pinhole(r: Any = pin) -> None:
            r.update_scene(data, "fisheye")
            r.disable_depth_rendering()
            r.render()
            r.enable_depth_rendering()
            r.render()

        pin_s = _timed(pinhole, args.frames)
        pin.close()
        lk = fisheye.lookup
        results[str(res)] = {
            "faces": list(lk.faces),
            "cube_size": lk.size,
            "atlas_shape": list(lk.atlas_shape),
            "setup_s": round(setup, 4),
            "frames_per_s": round(1.0 / total, 1),
            "ms_per_frame": round(total * 1e3, 3),
            "ms_draw_and_read_faces": round(atlas * 1e3, 3),
            "ms_resample": round((total - atlas) * 1e3, 3),
            "pinhole_rgb_depth_frames_per_s": round(1.0 / pin_s, 1),
            "image_mean": round(float(rgb[lens.mask].mean()), 2),
            "depth_range_m": [
                round(float(depth[lens.mask & (depth > 0)].min()), 3),
                round(float(depth.max()), 3),
            ],
        }
    doc = {
        "schema_version": 1,
        "benchmark": "fisheye",
        "machine": {
            "platform": platform.platform(),
            "host": platform.node(),
            "python": platform.python_version(),
            "mujoco": mujoco.__version__,
            "gl": gl,
            "cpus_total": os.cpu_count(),
            "cores_used": len(cores),
        },
        "scene": str(SCENE.relative_to(ROOT)),
        "fov_deg": args.fov,
        "frames": args.frames,
        "results": results,
    }
    text = json.dumps(doc, indent=2)
    print(text)
    out = args.out or ROOT / "benchmarks" / "results" / f"fisheye-cpu{len(cores)}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text + "\n")


if __name__ == "__main__":
    main()
