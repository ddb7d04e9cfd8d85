"""CPU/GPU agreement of demo execution on generated kitchens: the same planned episodes run on
the CPU executor (mujoco.batch, OpenGL) and the GPU executor (MuJoCo Warp, its ray tracer).

    python scripts/bench_demos_agreement.py --run-dir RUN [--scenes 4] [--episodes 32]
        [--size 128] [--out benchmarks/results/demos-agreement-gpu.json]

Plans come from the stage's own planner and seeds (``episode_seed``); per scene, the report has
both success counts, the share of agreeing verdicts, tool-path and object differences and the
mean RGB / median depth differences per camera; every disagreement is listed.
"""

from __future__ import annotations

import argparse
import json
import logging
import platform
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    from factory.config import DemosConfig
    from factory.demos.execute.agreement import compare_executors
    from factory.demos.execute.cpu import RecordConfig
    from factory.demos.record.slots import episode_seed
    from factory.errors import FactoryError
    from factory.store import RunStore
    from factory.tasks.pick_place.demos import scene_planner
    from factory.tasks.pick_place.plan import EpisodePlan

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run-dir", type=Path, required=True)
    p.add_argument("--scenes", type=int, default=4)
    p.add_argument("--episodes", type=int, default=32)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/demos-agreement-gpu.json")
    args = p.parse_args()
    logging.basicConfig(level=logging.WARNING)
    dc = DemosConfig()
    cfg = RecordConfig(width=args.size, height=args.size)
    per_scene = {}
    total_eps = agree = 0
    for sid in RunStore(args.run_dir).scene_ids():
        if len(per_scene) == args.scenes:
            break
        try:
            setup, planner = scene_planner(args.run_dir, sid, dc)
        except FactoryError as e:
            print(f"{sid}: skipped ({e})")
            continue
        plans = []
        for slot in range(4 * args.episodes):
            res = planner.plan_episode(episode_seed(0, sid, slot, 0), True)
            if isinstance(res, EpisodePlan):
                plans.append(res)
            if len(plans) == args.episodes:
                break
        t0 = time.perf_counter()
        agreement, _, _ = compare_executors(setup, plans, cfg)
        s = agreement.summary()
        s["seconds"] = time.perf_counter() - t0
        per_scene[sid] = s
        total_eps += s["episodes"]
        agree += round(s["verdicts_agree"] * s["episodes"])
        print(
            f"{sid}: {s['episodes']} episodes, CPU {s['cpu_successes']} / GPU "
            f"{s['gpu_successes']} successes, verdicts agree {s['verdicts_agree']:.3f}, "
            f"RGB mean abs {s['rgb_mean_abs']}, depth median mm {s['depth_median_abs_mm']}"
        )
    out = {
        "schema_version": 1,
        "benchmark": "demos-agreement",
        "machine": platform.platform(),
        "image_size": args.size,
        "episodes": total_eps,
        "verdicts_agree": agree / max(1, total_eps),
        "scenes": per_scene,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"verdicts agree on {agree}/{total_eps} episodes; wrote {args.out}")


if __name__ == "__main__":
    main()
