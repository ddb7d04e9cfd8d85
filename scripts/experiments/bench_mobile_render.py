"""Frames/s of the mobile task's rendering (``mobile_execute.render_frames``) on one core.

    python scripts/experiments/bench_mobile_render.py RUN_DIR --label after
        [--sizes 64 128] [--frames 200] [--repeats 3] [--seed 0] [--scene ID] [--no-cull]
        [--out benchmarks/results/mobile-render-cpu1.json]

One generated living room of ``RUN_DIR`` (its first scene, or ``--scene``) is composed with
the mobile robot; one episode is planned (``--seed``) and simulated without images; then its
first ``--frames`` recorded states are drawn with all five cameras (left, right, wrist and
the two fisheye cameras; RGB + depth) at each size, as ``stage=demos`` does. Besides the
frames/s of ``render_frames``, the same frames are drawn by the pinhole pass alone and by
the fisheye cameras alone, and the robot's and the scene's visual triangles are counted. Each
is timed ``--repeats`` times after a warm-up pass; the fastest pass counts (the machine is
shared), the median is kept too.

Run it pinned to one core (``taskset -c 0``; Mesa's llvmpipe threads are limited to one
here). The result is stored under ``--label`` in the JSON (other labels are kept), so a run
before and after a change sit side by side.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import subprocess
import time
from pathlib import Path

os.environ.setdefault("LP_NUM_THREADS", "1")  # Mesa llvmpipe render threads: one core

ROOT = Path(__file__).resolve().parent.parent.parent
log = logging.getLogger("bench_mobile_render")


def _triangles(model: object) -> dict[str, int]:
    """Faces of the visual mesh geoms (groups 0-2) of the robot and of the rest."""
    import mujoco

    m = model
    robot = scene = 0
    for g in range(m.ngeom):  # type: ignore[attr-defined]
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or m.geom_group[g] > 2:  # type: ignore[attr-defined]
            continue
        faces = int(m.mesh_facenum[m.geom_dataid[g]])  # type: ignore[attr-defined]
        body = m.body(m.geom_bodyid[g]).name  # type: ignore[attr-defined]
        if body.startswith("mobile/"):
            robot += faces
        else:
            scene += faces
    return {"robot_visual_faces": robot, "scene_visual_faces": scene}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--label", required=True)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=3, help="timed passes; the fastest counts")
    ap.add_argument("--scene", default=None)
    ap.add_argument(
        "--no-cull", action="store_true", help="MobileRenderer(cull=False), where it has it"
    )
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/mobile-render-cpu1.json")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from factory.sim.gl import configure_gl

    configure_gl("auto")  # before mujoco is imported
    import mujoco
    import numpy as np

    from factory.store import RunStore
    from factory.tasks.mobile_pick_place import (
        ALL_CAMERAS,
        FISHEYE_CAMERAS,
        MobileEpisodePlan,
        MobilePlanner,
        MobileRecordConfig,
        MobileRenderer,
        execute_mobile,
        mobile_setup,
        render_frames,
    )

    store = RunStore(args.run_dir)
    scene_id = args.scene or sorted(p.name for p in (args.run_dir / "scenes").iterdir())[0]
    t0 = time.perf_counter()
    setup = mobile_setup(store.load_scene(scene_id), store.assets_dir)
    setup_s = time.perf_counter() - t0
    plan = MobilePlanner(setup).plan_episode(args.seed)
    if not isinstance(plan, MobileEpisodePlan):
        raise SystemExit(f"{scene_id} seed {args.seed}: no plan ({plan.reason}: {plan.detail})")
    base_cfg = MobileRecordConfig(width=32, height=32, render=False)
    rec = execute_mobile(setup, plan, base_cfg)
    n = min(args.frames, len(rec.state))
    rec.state = rec.state[:n]
    model = setup.model
    results: dict[str, object] = {}
    sums: dict[str, dict[str, int]] = {}
    for size in args.sizes:
        row: dict[str, float] = {}
        for name, cams in (
            ("all", ALL_CAMERAS),
            ("pinhole", tuple(c for c in ALL_CAMERAS if c not in FISHEYE_CAMERAS)),
            ("fisheye", FISHEYE_CAMERAS),
        ):
            cfg = MobileRecordConfig(width=size, height=size, cameras=cams)
            extra = {"cull": False} if args.no_cull else {}
            renderer = MobileRenderer(model, cfg, **extra)
            times = []
            try:
                for _ in range(1 + args.repeats):  # the first is a warm-up (GL, caches)
                    rec.rgb, rec.depth, rec.render_seconds = {}, {}, 0.0
                    render_frames(setup, rec, cfg, renderer)
                    times.append(rec.render_seconds)
            finally:
                renderer.close()
            best = min(times[1:])  # the least disturbed by other processes on the core
            row[f"{name}_frames_per_s"] = n / best
            row[f"{name}_ms_per_frame"] = 1000.0 * best / n
            row[f"{name}_ms_per_frame_median"] = 1000.0 * float(np.median(times[1:])) / n
            if name == "all":
                sums[f"{size}px"] = {c: int(rec.rgb[c].sum(dtype=np.int64)) for c in rec.rgb}
        view = mujoco.MjData(model)
        t0 = time.perf_counter()
        for f in range(n):
            mujoco.mj_setState(model, view, rec.state[f], mujoco.mjtState.mjSTATE_INTEGRATION)
            mujoco.mj_forward(model, view)
        row["set_state_forward_ms_per_frame"] = 1000.0 * (time.perf_counter() - t0) / n
        results[f"{size}px"] = row
        log.info(
            "%d px: %.1f frames/s (5 cameras; %.1f ms per frame: pinhole pass %.1f ms, "
            "fisheye %.1f ms, state + forward %.1f ms)",
            size,
            row["all_frames_per_s"],
            row["all_ms_per_frame"],
            row["pinhole_ms_per_frame"],
            row["fisheye_ms_per_frame"],
            row["set_state_forward_ms_per_frame"],
        )
    sha = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip()
    entry = {
        "scene": scene_id,
        "seed": args.seed,
        "frames": n,
        "setup_s": setup_s,
        "ngeom": int(model.ngeom),
        **_triangles(model),
        "results": results,
        "code": sha,
        "date": time.strftime("%Y-%m-%d"),
        "affinity": sorted(os.sched_getaffinity(0)),
        "lp_num_threads": os.environ.get("LP_NUM_THREADS"),
        "mujoco_gl": os.environ.get("MUJOCO_GL", "auto"),
        "rgb_sums": sums,
    }
    doc: dict[str, object] = {}
    if args.out.is_file():
        doc = json.loads(args.out.read_text())
    doc.update(
        {
            "schema_version": 1,
            "benchmark": "mobile_render",
            "what": (
                "mobile_execute.render_frames: 5 cameras (left, right, wrist pinhole; "
                "fisheye_front, fisheye_back 180 deg), RGB + depth, on one core (Mesa "
                "llvmpipe); one planned episode's first frames on a generated living room"
            ),
            "machine": {"platform": platform.platform(), "cpus_total": os.cpu_count()},
        }
    )
    runs = doc.setdefault("runs", {})
    assert isinstance(runs, dict)
    runs[args.label] = entry
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    tmp.replace(args.out)
    log.info("wrote %s (%s)", args.out, args.label)


if __name__ == "__main__":
    main()
