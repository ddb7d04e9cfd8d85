"""Where the GPU demo executor's time goes: one scene's planned episodes (tiled to many worlds,
truncated to --steps physics steps) executed with and without rendering, for several world
counts, broadphases and island sleeping on/off. Prints and writes JSON.

    python scripts/experiments/profile_warp_demos.py --run-dir RUN [--scene ID] [--steps 1000]
        [--worlds 32 256 1024] [--out profile.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path


def main() -> None:
    import mujoco

    from factory.config import DemosConfig
    from factory.demos.execute.cpu import RecordConfig
    from factory.demos.execute.warp import WarpExecutor
    from factory.store import RunStore
    from factory.tasks.pick_place.demos import scene_planner
    from factory.tasks.pick_place.plan import EpisodePlan

    p = argparse.ArgumentParser()
    p.add_argument("--run-dir", type=Path, required=True)
    p.add_argument("--scene", default=None)
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--plans", type=int, default=16)
    p.add_argument("--worlds", type=int, nargs="+", default=[32, 256, 1024])
    p.add_argument("--out", type=Path, default=Path("profile_warp_demos.json"))
    args = p.parse_args()
    sid = args.scene or RunStore(args.run_dir).scene_ids()[0]
    setup, planner = scene_planner(args.run_dir, sid, DemosConfig())
    plans = []
    seed = 0
    while len(plans) < args.plans:
        r = planner.plan_episode(seed, True)
        seed += 1
        if isinstance(r, EpisodePlan):
            k = min(args.steps, len(r.ctrl))
            plans.append(dataclasses.replace(r, ctrl=r.ctrl[:k], targets=r.targets[:k]))
    model = setup.model
    info = {"scene": sid, "ngeom": model.ngeom, "nbody": model.nbody, "nv": model.nv}
    rows = []

    def measure(n: int, render: bool, broadphase: str | None = None, sleep: bool = True) -> None:
        flags = model.opt.enableflags
        bit = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        model.opt.enableflags = (flags | bit) if sleep else (flags & ~bit)
        try:
            cfg = RecordConfig(render=render)
            ex = WarpExecutor(setup, cfg, broadphase=broadphase)
            tiled = [plans[i % len(plans)] for i in range(n)]
            ex.execute(tiled[: min(n, 8)])  # compile and warm up
            ex.times = type(ex.times)()
            t0 = time.perf_counter()
            recs = ex.execute(tiled)
            wall = time.perf_counter() - t0
        finally:
            model.opt.enableflags = flags
        steps = max(len(p.ctrl) for p in tiled)
        ok = sum(bool(r.outcome and r.outcome.reason != "sim_overflow") for r in recs)
        row = {
            "worlds": n,
            "render": render,
            "broadphase": broadphase or str(ex.m.opt.broadphase),
            "sleep": sleep,
            "wall_s": wall,
            **{f"{k}_s": v for k, v in vars(ex.times).items()},
            "world_steps_per_s": n * steps / ex.times.frames,
            "ms_per_step": 1000 * ex.times.frames / steps,
            "no_overflow": ok,
        }
        rows.append(row)
        print(json.dumps(row), flush=True)

    for n in args.worlds:
        measure(n, render=False)
        measure(n, render=True)
    mid = args.worlds[len(args.worlds) // 2]
    for bp in ("nxn", "sap_tile"):
        measure(mid, render=False, broadphase=bp)
    measure(mid, render=False, sleep=False)
    args.out.write_text(json.dumps({"info": info, "rows": rows}, indent=1) + "\n")
    print(json.dumps(info))


if __name__ == "__main__":
    main()
