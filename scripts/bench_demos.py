"""Benchmark of demonstration recording: successful demos per hour (per CPU core), success rate
and failure reasons, planning time per segment, rendering frames/s.

    python scripts/bench_demos.py [--scenes 2] [--episodes 4] [--cores 1] [--batch 16]
        [--executor cpu|warp] [--gpu-batch 512] [--workers N]
        [--task pick_place|mobile_pick_place|open|close|place_inside]
        [--runs cold warm] [--set KEY=VALUE ...]
        [--run-dir runs/bench_demos] [--out benchmarks/results/demos-cpu1.json]

``--executor warp`` runs the episodes on the GPU (MuJoCo Warp worlds and batch renderer) with
``--workers`` planning processes (default: cores - 1), and changes the defaults to the GPU
production size: 8 scenes x 1,536 episodes on every core, one cold run, the stage's own
``demos.gpu_batch`` (``python scripts/bench_demos.py --executor warp`` is the GPU benchmark).
Eight scenes, because a run's first scene pays the kernel compilation and its last the writers'
last writes (about 1 minute and 50 s on a bare H200), fixed costs that a production job
spreads over its scenes, and because their episodes (about 4.5 MB each, 55 GB) fit on a 64 GiB
disk, where ten kitchens' did not; the JSON's ``per_scene`` shows the first scene's cost apart,
and ``--scenes 3`` gives the earlier, shorter figure. A run folder holding more scenes than
``--scenes`` is recorded whole (``stage=demos`` takes every scene of its run).
``--kernel-cache DIR`` sets ``sim.kernel_cache``; the JSON says how many compiled modules the
cache held at the start (``bare_machine``: none) and each run's time to its first stored
episode (from the command's start, kernel compilation included).

The tasks that simulate their episodes themselves (``mobile_pick_place``, ``open``, ``close``,
``place_inside``: ``demo_execution = "episode"``) run on the GPU as
:mod:`factory.demos.episode_execution` and ``demos.episode_physics`` say. ``open`` and
``close`` (``episode_physics=auto``, the default): ``--workers`` processes only plan, the main
process steps each scene's plans as MuJoCo Warp worlds, rebuilds the recordings and verdicts
from their states on the host and draws the successes with the task's cameras
(:mod:`factory.demos.episode_physics`); ``--set demos.episode_physics=cpu`` gives the earlier
path, and ``place_inside`` and ``mobile_pick_place`` take it: the processes plan and simulate
each episode on the CPU without images and the GPU only draws the recorded states (the mobile
robot's five cameras; the fixed-base Panda's left, right and wrist), so their demos per
GPU-node hour are bounded by the node's CPU cores. The JSON's ``task`` names the task, its
``per_scene`` rows the GPU and plan-waiting seconds of each scene, each run's
``episode_physics`` where the episodes were simulated and ``cpu_s_per_demo`` the CPU seconds a
stored demo cost outside drawing (planning, and the CPU physics or the host's work around the
GPU's: ``cpu_physics_s_per_demo``).

Scenes are generated first (kitchens with a pick-and-place task, or living rooms with a mobile
"move the can from the coffee table to the desk" task, or for ``--task open`` / ``close`` /
``place_inside`` the same kitchens built with articulated furniture; not timed; kept in
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
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROMPTS = {
    "pick_place": "a kitchen where the robot picks up a mug and puts it in the bowl",
    "mobile_pick_place": (
        "a living room where the robot moves the coke can from the coffee table to the desk"
    ),
    # the articulated tasks: the fixed task's kitchens, built with articulated furniture; the
    # task opens or closes the first part of each that the robot can work
    # (docs/ARTICULATED_TASKS.md, "Which part")
    "open": "a kitchen where the robot picks up a mug and puts it in the bowl",
    "close": "a kitchen where the robot picks up a mug and puts it in the bowl",
    # place_inside: the same kitchens; the task puts the scene's pick object (the mug) away in
    # the first drawer the robot can work (docs/ARTICULATED_TASKS.md, "Putting things away")
    "place_inside": "a kitchen where the robot picks up a mug and puts it in the bowl",
}
"""The generation request of each task's benchmark scenes."""
GENERATE_ARGS = {name: ["assets.articulated=true"] for name in ("open", "close", "place_inside")}
"""More ``stage=generate`` overrides of a task's benchmark scenes."""


def _cli(
    args: list[str],
    cores: int,
    env: dict[str, str],
    episodes: Path | None = None,
    failed: list[str] | None = None,
) -> tuple[float, float | None]:
    """Runs the CLI; returns its wall time (s) and, with ``episodes`` (the run's episode
    store), the time from its start to the first stored episode (s; None if none was).
    A failed command exits, or with ``failed`` has its error's last lines appended there."""
    cmd = [sys.executable, "-m", "factory", *args]
    if shutil.which("taskset") and cores < (os.cpu_count() or 1):
        cmd = ["taskset", "-c", f"0-{cores - 1}", *cmd]
    t0 = time.perf_counter()
    first: float | None = None
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=err, text=True)
        while proc.poll() is None:
            if (
                episodes is not None
                and first is None
                and next(episodes.glob("shard-*.zarr/*/zarr.json"), None)
            ):
                first = time.perf_counter() - t0
                print(f"first episode stored after {first:.1f} s", flush=True)
            time.sleep(0.5)
        if proc.returncode != 0:
            err.seek(0)
            tail = err.read()[-4000:]
            if failed is None:
                raise SystemExit(f"{' '.join(cmd)} failed:\n{tail}")
            failed.append(tail.strip().splitlines()[-1] if tail.strip() else "no message")
            print(f"{' '.join(cmd)} failed:\n{tail}", file=sys.stderr, flush=True)
    return time.perf_counter() - t0, first


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


def _kernel_cache(setting: str | None) -> dict[str, object]:
    """The Warp kernel cache the stage will use and what it holds before the first run:
    ``bare_machine`` when it holds no compiled module (every kernel is compiled in the run)."""
    from factory.sim.kernel_cache import cached_modules, kernel_cache_dir

    # unset: the stage inherits this environment (WARP_CACHE_PATH or Warp's default)
    folder = str(Path(os.path.expanduser(setting)).resolve()) if setting else kernel_cache_dir()
    n = cached_modules(folder)
    return {"folder": folder, "modules_at_start": n, "bare_machine": n == 0}


KERNELS_READY = re.compile(r"GPU kernels ready in ([\d.]+) s")


def _kernels_ready(run: Path) -> list[float]:
    """The stage log's "GPU kernels ready in X s" times (s), one per worlds set-up."""
    return [
        float(m[1])
        for log in sorted((run / "logs").glob("demos-*.log"))
        for m in KERNELS_READY.finditer(log.read_text())
    ]


def main() -> None:
    from factory.tasks import get_task

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=None, help="default 2 (cpu), 10 (warp)")
    p.add_argument(
        "--episodes", type=int, default=None, help="per scene; default 4 (cpu), 1536 (warp)"
    )
    p.add_argument("--cores", type=int, default=None, help="default 1 (cpu), all (warp)")
    p.add_argument("--batch", type=int, default=16)
    p.add_argument("--run-dir", type=Path, default=ROOT / "runs" / "bench_demos")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--gl", default=None, help="MUJOCO_GL for rendering (egl, osmesa)")
    p.add_argument("--executor", default="cpu", choices=["cpu", "warp", "auto"])
    p.add_argument(
        "--gpu-batch", type=int, default=None, help="demos.gpu_batch (default: the stage's)"
    )
    p.add_argument(
        "--kernel-cache",
        default=None,
        help="sim.kernel_cache (default: the stage's: WARP_CACHE_PATH or Warp's own folder)",
    )
    p.add_argument("--workers", type=int, default=0, help="0: --cores (cpu), cores - 1 (warp)")
    p.add_argument(
        "--task",
        default="pick_place",
        choices=sorted(PROMPTS),
        help=(
            "mobile_pick_place: living rooms; open, close, place_inside: kitchens with "
            "articulated furniture; these four on the CPU executor: one episode at a time per "
            "worker; --executor warp: --workers processes plan (open, close: the GPU simulates "
            "and renders) or plan and simulate (the GPU renders) with the task's cameras "
            "(factory.demos.gpu_pipeline, factory.demos.episode_execution, "
            "factory.demos.episode_physics)"
        ),
    )
    p.add_argument(
        "--runs",
        nargs="+",
        default=None,
        choices=["cold", "warm"],
        help="which runs; default cold warm (cpu), cold (warp: its later scenes are warm)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        help="extra CLI override (repeatable), e.g. demos.freeze_beyond=0",
    )
    args = p.parse_args()
    gpu = args.executor == "warp"
    for name, cpu_default, gpu_default in (
        ("scenes", 2, 8),
        ("episodes", 4, 1536),
        ("cores", 1, os.cpu_count() or 1),
        ("runs", ["cold", "warm"], ["cold"]),
    ):
        if getattr(args, name) is None:
            setattr(args, name, gpu_default if gpu else cpu_default)
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
                *GENERATE_ARGS.get(args.task, []),
            ],
            os.cpu_count() or 1,
            env,
        )
    extra = list(args.set)
    if args.gpu_batch is not None:
        extra.append(f"demos.gpu_batch={args.gpu_batch}")
    if args.kernel_cache:
        extra.append(f"sim.kernel_cache={args.kernel_cache}")
    cache = _kernel_cache(args.kernel_cache) if gpu else None
    workers = args.workers or (max(1, args.cores - 1) if args.executor == "warp" else args.cores)
    results: dict[str, dict[str, object]] = {}
    failed: list[str] = []
    for label in args.runs:
        shutil.rmtree(run / "episodes", ignore_errors=True)
        shutil.rmtree(run / "logs", ignore_errors=True)
        wall, first = _cli(
            [
                "stage=demos",
                f"run_dir={run}",
                f"task={args.task}",
                f"demos.episodes_per_scene={args.episodes}",
                f"demos.workers={workers}",
                f"demos.batch={args.batch}",
                f"demos.executor={args.executor}",
                *extra,
            ],
            args.cores,
            env,
            run / "episodes",
            failed,
        )
        if failed:  # what the stage did before it failed, from its log
            results[label] = {
                "error": failed[-1],
                "wall_s": wall,
                "first_episode_s": first,
                "per_scene": _per_scene(run),
                "kernels_ready_s": _kernels_ready(run),
            }
            break
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
            "first_episode_s": first,
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
            "kernels_ready_s": _kernels_ready(run),
        }
        # The CPU seconds a successful demo costs outside drawing: planning, and its physics
        # where the CPU simulates it (the CPU executor, or demos.episode_physics=cpu in the
        # planner processes), else the main process's host work around MuJoCo Warp's physics
        # (filing the states, rebuilding the recordings and verdicts).
        plans = sec["plan_per_episode"]
        plan_s = plans.get("mean", 0.0) * plans.get("n", 0)
        physics = sec.get("gpu_physics")
        host_s = physics["host"] + physics["record"] if physics else 0.0
        cpu_sim_s = 0.0 if physics else sec["simulate"]
        results[label].update(
            episode_physics="warp" if physics else "cpu",
            gpu_physics_s=physics,
            cpu_plan_s=plan_s,
            cpu_simulate_s=cpu_sim_s,
            cpu_host_physics_s=host_s,
            cpu_s_per_demo=(plan_s + cpu_sim_s + host_s) / max(ok, 1),
            cpu_physics_s_per_demo=(cpu_sim_s + host_s) / max(ok, 1),
        )
        r = results[label]
        print(
            f"{label}: {ok} successful demos in {wall:.1f} s on {args.cores} core(s): "
            f"{r['demos_per_core_hour']:.0f} demos per core-hour, success rate "
            f"{r['success_rate']:.2f}, failures {r['failures'] or 'none'}; planning per segment "
            f"median {sec['plan_per_segment'].get('median', 0):.3f} s, p95 "
            f"{sec['plan_per_segment'].get('p95', 0):.3f} s; rendering "
            f"{r['render_frames_per_s'] or 0:.1f} frames/s ({cams} cameras, RGB + depth); "
            f"CPU per demo {r['cpu_s_per_demo']:.2f} s (physics on the {r['episode_physics']}: "
            f"{r['cpu_physics_s_per_demo']:.3f} s of it)"
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
        "kernel_cache": cache,
        "task": args.task,
        "demo_execution": get_task(args.task).demo_execution,
        "workers": workers,
        "scenes": args.scenes,
        "episodes_per_scene": args.episodes,
        "results": results,
    }
    kind = "" if args.task == "pick_place" else f"{args.task.removesuffix('_pick_place')}-"
    name = f"demos-{kind}{'gpu' if args.executor == 'warp' else 'cpu'}{args.cores}.json"
    path = args.out or ROOT / "benchmarks" / "results" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")
    if failed:
        raise SystemExit(f"the demos stage failed: {failed[-1]}")


if __name__ == "__main__":
    main()
