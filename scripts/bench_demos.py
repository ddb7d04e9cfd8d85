"""Benchmark of demonstration recording: successful demos per hour (per CPU core), success rate
and failure reasons, planning time per segment, rendering frames/s.

    python scripts/bench_demos.py [--scenes 2] [--episodes 4] [--cores 1] [--batch 16]
        [--executor cpu|warp] [--gpu-batch 512] [--workers N] [--task pick_place|mobile_pick_place]
        [--runs cold warm] [--set KEY=VALUE ...]
        [--run-dir runs/bench_demos] [--out benchmarks/results/demos-cpu1.json]

``--executor warp`` runs the episodes on the GPU (MuJoCo Warp worlds and batch renderer) with
``--workers`` planning processes (default: cores - 1).

Scenes are generated first (kitchens with a pick-and-place task, or living rooms with a mobile
"move the can from the coffee table to the desk" task; not timed; kept in
``--run-dir`` and reused). ``stage=demos`` then runs through the real CLI on ``--cores`` cores
(``taskset``; planning workers, simulation threads and Mesa's renderer threads all limited to
them) twice: a cold run into an empty episode store and a warm run after deleting the episodes
(same scenes, imports and caches warm on disk). The numbers come from the stage's summary and
the wall clock.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROMPTS = {
    "pick_place": "a kitchen where the robot picks up a mug and puts it in the bowl",
    "mobile_pick_place": (
        "a living room where the robot moves the coke can from the coffee table to the desk"
    ),
}
"""The generation request of each task's benchmark scenes."""


def _cli(args: list[str], cores: int, env: dict[str, str]) -> float:
    cmd = [sys.executable, "-m", "factory", *args]
    if shutil.which("taskset") and cores < (os.cpu_count() or 1):
        cmd = ["taskset", "-c", f"0-{cores - 1}", *cmd]
    t0 = time.perf_counter()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-4000:]}")
    return time.perf_counter() - t0


def _gpu_name() -> str | None:
    """The GPU's name (nvidia-smi), None without one."""
    if not shutil.which("nvidia-smi"):
        return None
    out = subprocess.run(
        ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True, text=True
    )
    return out.stdout.strip() or None


SCENE_LINE = re.compile(
    r"scene (\S+): (\d+) new, ([\d.]+) s \(GPU ([\d.]+) s, waiting for plans ([\d.]+) s, "
    r"for earlier writes ([\d.]+) s\)"
)


def _per_scene(run: Path) -> list[dict[str, float | str]]:
    """The GPU pipeline's per-scene lines of the stage log, with demos per hour of each
    scene's wall time (the first scene's includes the kernel compile)."""
    rows: list[dict[str, float | str]] = []
    for log in sorted((run / "logs").glob("demos-*.log")):
        for m in SCENE_LINE.finditer(log.read_text()):
            new, wall, gpu = int(m[2]), float(m[3]), float(m[4])
            rows.append(
                {
                    "scene": m[1],
                    "new": new,
                    "wall_s": wall,
                    "gpu_s": gpu,
                    "wait_plans_s": float(m[5]),
                    "wait_writes_s": float(m[6]),
                    "demos_per_hour": new / wall * 3600 if wall else 0.0,
                }
            )
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=2)
    p.add_argument("--episodes", type=int, default=4, help="episodes per scene")
    p.add_argument("--cores", type=int, default=1)
    p.add_argument("--batch", type=int, default=16)
    p.add_argument("--run-dir", type=Path, default=ROOT / "runs" / "bench_demos")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--gl", default=None, help="MUJOCO_GL for rendering (egl, osmesa)")
    p.add_argument("--executor", default="cpu", choices=["cpu", "warp", "auto"])
    p.add_argument("--gpu-batch", type=int, default=512)
    p.add_argument("--workers", type=int, default=0, help="0: --cores (cpu), cores - 1 (warp)")
    p.add_argument(
        "--task",
        default="pick_place",
        choices=sorted(PROMPTS),
        help=(
            "mobile_pick_place: living rooms; CPU executor: one episode at a time per worker; "
            "--executor warp: --workers processes plan and simulate, the GPU renders "
            "(factory.demos.gpu_pipeline, factory.demos.episode_execution)"
        ),
    )
    p.add_argument(
        "--runs",
        nargs="+",
        default=["cold", "warm"],
        choices=["cold", "warm"],
        help="which runs (a long GPU run: 'cold' alone, its later scenes are warm)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        help="extra CLI override (repeatable), e.g. demos.freeze_beyond=0",
    )
    args = p.parse_args()
    env = dict(os.environ)
    env["LP_NUM_THREADS"] = str(args.cores)  # Mesa llvmpipe render threads
    env["OMP_NUM_THREADS"] = str(args.cores)
    if args.gl:
        env["MUJOCO_GL"] = args.gl
    run = args.run_dir
    scenes = sorted((run / "scenes").glob("*/scene.json")) if run.exists() else []
    if len(scenes) < args.scenes:
        _cli(
            [
                "stage=generate",
                f"run_dir={run}",
                f"generate.prompts=[{PROMPTS[args.task]}]",
                f"generate.scenes_per_prompt={args.scenes}",
                "generate.render=false",
            ],
            os.cpu_count() or 1,
            env,
        )
    workers = args.workers or (max(1, args.cores - 1) if args.executor == "warp" else args.cores)
    results = {}
    for label in args.runs:
        shutil.rmtree(run / "episodes", ignore_errors=True)
        shutil.rmtree(run / "logs", ignore_errors=True)
        wall = _cli(
            [
                "stage=demos",
                f"run_dir={run}",
                f"task={args.task}",
                f"demos.episodes_per_scene={args.episodes}",
                f"demos.workers={workers}",
                f"demos.batch={args.batch}",
                f"demos.executor={args.executor}",
                f"demos.gpu_batch={args.gpu_batch}",
                *args.set,
            ],
            args.cores,
            env,
        )
        summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
        sec = summary["seconds"]
        ok = summary["new_successes"]
        infos = []
        for store in (run / "episodes").glob("shard-*.zarr"):
            for ep in store.iterdir():
                meta = ep / "zarr.json"
                if meta.is_file():
                    infos.append(json.loads(meta.read_text())["attributes"])
        frames = sum(i["n_frames"] for i in infos)
        cams = len(infos[0]["cameras"]) if infos else 0
        results[label] = {
            "wall_s": wall,
            "stage_wall_s": sec["wall"],
            "successful_demos": ok,
            "failures": summary["failures"],
            "success_rate": summary["success_rate"],
            "demos_per_hour": ok / wall * 3600,
            "demos_per_core_hour": ok / wall * 3600 / args.cores,
            "seconds_per_demo": wall / max(ok, 1),
            "plan_per_segment_s": sec["plan_per_segment"],
            "plan_per_episode_s": sec["plan_per_episode"],
            "simulate_s": sec["simulate"],
            "render_s": sec["render"],
            "frames": frames,
            "render_frames_per_s": frames / sec["render"] if sec["render"] else None,
            "render_images_per_s": frames * cams * 2 / sec["render"] if sec["render"] else None,
            "sim_seconds_simulated": frames / infos[0]["fps"] if infos else 0,
            "executor": summary.get("executor", "cpu"),
            "recorded_by": dict(Counter(i.get("recorder", "") for i in infos)),
            "gpu_seconds": sec.get("gpu"),
            "per_scene": _per_scene(run),
        }
        r = results[label]
        print(
            f"{label}: {ok} successful demos in {wall:.1f} s on {args.cores} core(s): "
            f"{r['demos_per_core_hour']:.0f} demos per core-hour, success rate "
            f"{r['success_rate']:.2f}, failures {r['failures'] or 'none'}; planning per segment "
            f"median {sec['plan_per_segment'].get('median', 0):.3f} s, p95 "
            f"{sec['plan_per_segment'].get('p95', 0):.3f} s; rendering "
            f"{r['render_frames_per_s'] or 0:.1f} frames/s ({cams} cameras, RGB + depth)"
        )
    out = {
        "benchmark": "demos",
        "machine": {
            "platform": platform.platform(),
            "cpus_total": os.cpu_count(),
            "cores_used": args.cores,
            "gl": env.get("MUJOCO_GL", "auto"),
            "gpu": _gpu_name(),
        },
        "executor": args.executor,
        "task": args.task,
        "workers": workers,
        "scenes": args.scenes,
        "episodes_per_scene": args.episodes,
        "results": results,
    }
    kind = "mobile-" if args.task == "mobile_pick_place" else ""
    name = f"demos-{kind}{'gpu' if args.executor == 'warp' else 'cpu'}{args.cores}.json"
    path = args.out or ROOT / "benchmarks" / "results" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
