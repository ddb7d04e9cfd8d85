"""Soak run of the demos stage with a kill -9 in the middle: nothing stored is lost or corrupt,
finished episodes are not redone.

    python scripts/experiments/gpu_soak.py [--scenes 10] [--episodes 1536] [--executor warp]
        [--kill-after-calls 3 | --kill-after-episodes N] [--kill-delay 10]
        [--kernel-cache DIR] [--run-dir runs/soak] [--out benchmarks/results/demos-soak-<card>.json]

Scenes are generated first (as ``scripts/bench_demos.py`` does; not timed). Then
``stage=demos`` runs in its own process group and is killed with SIGKILL (the whole group:
planners, writers, the GPU process) ``--kill-delay`` seconds after the stage log shows its
``--kill-after-calls``-th GPU call finished (so the kill lands in a later call), or once
``--kill-after-episodes`` episodes are stored (any executor). Every stored episode is then read
back (metadata and arrays, frame counts checked), the stage runs again to the end, and the
store is checked again: the episodes stored before the kill are unchanged (their metadata
files' bytes) and the second run stored only the others.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
from bench_demos import PROMPTS, _cli, _gpu_name, _kernel_cache  # noqa: E402


def _episodes(run: Path) -> dict[str, str]:
    """Stored episode id -> md5 of its metadata file."""
    out = {}
    for meta in sorted((run / "episodes").glob("shard-*.zarr/*/zarr.json")):
        out[meta.parent.name] = hashlib.md5(meta.read_bytes()).hexdigest()
    return out


def _check_store(run: Path) -> dict[str, object]:
    """Reads every stored episode back: metadata and arrays, frame counts."""
    from factory.demos.record.episodes import EpisodeStore

    ok, bad = 0, []
    for shard in sorted((run / "episodes").glob("shard-*.zarr")):
        store = EpisodeStore(shard)
        for ep in store.episode_ids():
            try:
                info = store.info(ep)
                arrays = store.arrays(ep)
                for name in ("state", "action"):
                    frames = arrays[name].shape[0]
                    if frames != info.n_frames:
                        raise ValueError(f"{name} has {frames} frames, not {info.n_frames}")
                    arrays[name][frames - 1]  # decodes the last chunk
                ok += 1
            except Exception as e:  # a corrupt episode is what this looks for
                bad.append(f"{shard.name}/{ep}: {type(e).__name__}: {e}")
    staging = sum(1 for _ in (run / "episodes").glob("shard-*.zarr/.staging*/*"))
    return {"readable": ok, "corrupt": bad, "staging_left": staging}


def _calls(run: Path) -> int:
    return sum(log.read_text().count("warp call:") for log in (run / "logs").glob("demos-*.log"))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=10)
    p.add_argument("--episodes", type=int, default=1536, help="per scene")
    p.add_argument("--executor", default="warp", choices=["cpu", "warp"])
    p.add_argument("--workers", type=int, default=0, help="0: cores - 1 (warp), cores (cpu)")
    p.add_argument("--kill-after-calls", type=int, default=3)
    p.add_argument("--kill-after-episodes", type=int, default=0, help="> 0: this trigger instead")
    p.add_argument("--kill-delay", type=float, default=10.0, help="s after the trigger")
    p.add_argument("--kernel-cache", default=None)
    p.add_argument("--run-dir", type=Path, default=ROOT / "runs" / "soak")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--set", action="append", default=[], help="extra CLI override")
    args = p.parse_args()
    run, cores = args.run_dir, os.cpu_count() or 1
    env = dict(os.environ)
    if len(list((run / "scenes").glob("*/scene.json"))) < args.scenes:
        _cli(
            [
                "stage=generate",
                f"run_dir={run}",
                f"generate.prompts=[{PROMPTS['pick_place']}]",
                f"generate.scenes_per_prompt={args.scenes}",
                "generate.render=false",
            ],
            cores,
            env,
        )
    workers = args.workers or (max(1, cores - 1) if args.executor == "warp" else cores)
    stage = [
        sys.executable,
        "-m",
        "factory",
        "stage=demos",
        f"run_dir={run}",
        f"demos.episodes_per_scene={args.episodes}",
        f"demos.workers={workers}",
        f"demos.executor={args.executor}",
        *([f"sim.kernel_cache={args.kernel_cache}"] if args.kernel_cache else []),
        *args.set,
    ]
    cache = _kernel_cache(args.kernel_cache) if args.executor == "warp" else None
    # 1. Run, kill -9 mid-way.
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        stage, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    trigger = None
    while proc.poll() is None:
        time.sleep(1.0)
        if trigger is None:
            if args.kill_after_episodes > 0:
                hit = len(_episodes(run)) >= args.kill_after_episodes
            else:
                hit = _calls(run) >= args.kill_after_calls
            if hit:
                trigger = time.perf_counter()
                print(f"trigger at {trigger - t0:.1f} s; kill in {args.kill_delay} s", flush=True)
        elif time.perf_counter() - trigger >= args.kill_delay:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            break
    killed_at = time.perf_counter() - t0
    finished_first = trigger is None or proc.returncode == 0
    before = _episodes(run)
    check_killed = _check_store(run)
    print(
        f"{'finished before the kill' if finished_first else 'killed'} at {killed_at:.1f} s: "
        f"{len(before)} episodes stored, {len(check_killed['corrupt'])} corrupt",  # type: ignore[arg-type]
        flush=True,
    )
    # 2. Run again to the end.
    t1 = time.perf_counter()
    out = subprocess.run(stage, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"the second run failed:\n{out.stderr[-4000:]}")
    wall2 = time.perf_counter() - t1
    after = _episodes(run)
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    changed = [e for e, h in before.items() if after.get(e) != h]
    result = {
        "benchmark": "demos-soak",
        "machine": {"cpus_total": cores, "gpu": _gpu_name()},
        "executor": args.executor,
        "kernel_cache": cache,
        "scenes": len(list((run / "scenes").glob("*/scene.json"))),
        "episodes_per_scene": args.episodes,
        "first_run": {
            "killed": not finished_first,
            "killed_after_s": killed_at,
            "gpu_calls_done": _calls(run) if args.executor == "warp" else None,
            "episodes_stored": len(before),
            "store_check": check_killed,
        },
        "second_run": {
            "wall_s": wall2,
            "new_successes": summary["new_successes"],
            "failures": summary["failures"],
            "episodes_stored": len(after),
        },
        "episodes_changed_by_the_second_run": changed,
        "store_check_after": _check_store(run),
        "nothing_lost_or_redone": not changed
        and not check_killed["corrupt"]
        and summary["new_successes"] == len(after) - len(before),
    }
    path = args.out or ROOT / "benchmarks" / "results" / (
        f"demos-soak-{'gpu' if args.executor == 'warp' else 'cpu'}.json"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(
        f"second run: {summary['new_successes']} new in {wall2:.1f} s; {len(after)} stored; "
        f"changed {len(changed)}; nothing lost or redone: {result['nothing_lost_or_redone']}; "
        f"wrote {path}"
    )


if __name__ == "__main__":
    main()
