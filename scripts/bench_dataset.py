"""Benchmark of dataset writing: frames per second into LeRobot and the share of the demo time
spent writing.

    python scripts/bench_dataset.py [--run-dir runs/bench_demos] [--cores 1] [--workers N]
        [--out benchmarks/results/dataset-cpu1.json]

Takes a run whose ``stage=demos`` finished (e.g. the one ``scripts/bench_demos.py`` leaves) and
runs ``stage=dataset`` through the CLI on ``--cores`` cores, cold (no shard dataset yet) and warm
(the shard datasets deleted again, processes new). The demo time is the demos stage's wall time
from the run's manifest (same cores). Two shares of writing, each time / (demo time + time):

* ``stage``: the whole ``stage=dataset`` process (interpreter start, imports of lerobot and
  torch, every shard's export and the merge): what a user waits for after the demos;
* ``export``: the shard exports alone, i.e. what each SLURM array task adds to its demos when
  it exports its own shard in the same process (``all.stages=[demos,dataset]``); the merge
  runs once per run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run-dir", type=Path, default=ROOT / "runs" / "bench_demos")
    p.add_argument("--cores", type=int, default=1)
    p.add_argument("--workers", type=int, default=None, help="dataset.workers (default: cores)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    run = args.run_dir
    manifest = json.loads((run / "manifest.json").read_text())
    demos = manifest["stages"]["demos"]["shards"]
    demo_seconds = sum(s.get("seconds", 0.0) for s in demos.values())
    env = {**os.environ, "OMP_NUM_THREADS": str(args.cores)}
    workers = args.workers or args.cores
    cmd = [
        sys.executable,
        "-m",
        "factory",
        "stage=dataset",
        f"run_dir={run}",
        f"dataset.workers={workers}",
    ]
    if shutil.which("taskset") and args.cores < (os.cpu_count() or 1):
        cmd = ["taskset", "-c", f"0-{args.cores - 1}", *cmd]
    results = {}
    for label in ("cold", "warm"):
        shutil.rmtree(run / "dataset", ignore_errors=True)
        t0 = time.perf_counter()
        out = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if out.returncode != 0:
            raise SystemExit(f"stage=dataset failed:\n{out.stderr[-3000:]}")
        meta = json.loads((run / "dataset" / "merged" / "meta" / "factory.json").read_text())
        frames = sum(e["n_frames"] for e in meta["episodes"])
        stage = json.loads((run / "manifest.json").read_text())["stages"]["dataset"]
        summary = stage["shards"]["0-of-1"]["result"]
        export_s = summary["export_seconds"]
        results[label] = {
            "wall_s": wall,
            "episodes": len(meta["episodes"]),
            "frames": frames,
            "frames_per_s": frames / wall,
            "export_s": export_s,
            "export_frames_per_s": frames / export_s,
            "merge_s": summary["merge_seconds"],
            "other_s": wall - export_s - summary["merge_seconds"],
            "demo_seconds": demo_seconds,
            "share_of_total": wall / (demo_seconds + wall),
            "export_share_of_total": export_s / (demo_seconds + export_s),
            "bytes": sum(
                p.stat().st_size for p in (run / "dataset" / "merged").rglob("*") if p.is_file()
            ),
        }
        r = results[label]
        print(
            f"{label}: {r['episodes']} episodes, {frames} frames; demos {demo_seconds:.1f} s.\n"
            f"  stage=dataset {wall:.1f} s ({r['frames_per_s']:.0f} frames/s): "
            f"{100 * r['share_of_total']:.1f} % of demos + writing\n"
            f"  of which shard export {export_s:.1f} s ({r['export_frames_per_s']:.0f} frames/s): "
            f"{100 * r['export_share_of_total']:.1f} %; merge {r['merge_s']:.1f} s; "
            f"start-up and imports {r['other_s']:.1f} s"
        )
    path = args.out or ROOT / "benchmarks" / "results" / f"dataset-cpu{args.cores}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        json.dumps(
            {
                "benchmark": "dataset",
                "machine": {
                    "platform": platform.platform(),
                    "cpus_total": os.cpu_count(),
                    "cores_used": args.cores,
                    "workers": workers,
                },
                "run_dir": run.name,
                "results": results,
            },
            indent=2,
        )
        + "\n"
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
