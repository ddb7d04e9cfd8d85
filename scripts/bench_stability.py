"""Benchmark: full-scene stability checks per second, per backend, scene size and batch size.

A *full-scene check* simulates every object of a scene for the protocol's 2.0 s (1,000 steps
of 2 ms) from one candidate state and judges it. Scenes are synthetic rooms with N objects:
half are 40 cm boxes on the floor, half convex-mesh cylinders (12-gon hulls) standing on them,
so there is object-object contact. Candidates jitter the cylinders' poses.

Cold time (first call: model upload, kernel compilation / JIT) is reported apart from warm
throughput (a second call on the same batch). Results are printed and saved as JSON under
``benchmarks/results/`` with the machine.

    python scripts/bench_stability.py                         # cpu (and warp/mjx if usable)
    python scripts/bench_stability.py --backends warp --objects 20 --batches 1024 8192
    python scripts/bench_stability.py --agree 1000            # cpu vs warp verdicts
    python scripts/bench_stability.py --backends warp warp-strict mjx --objects 20 --raw

``warp`` lets bodies at rest sleep and stops a batch once all its worlds sleep (the default);
``warp-strict`` simulates every step of every body (``sim.sleep=false``); ``mjx`` is MJX's Warp
implementation on CUDA. ``--raw`` times bare graph-captured ``mujoco_warp.step`` calls on the
same model and batch (sleeping off and on), the engine rate the checks are compared with.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from factory.schema import AssetRef, Physics, Placement, Room, Scene, SceneObject, Size3, Vec3
from factory.schema.asset import AssetMeta, asset_meta_to_json
from factory.sim.backend import cuda_available, get_backend
from factory.sim.compile import compile_scene
from factory.sim.stability import (
    FreeBodies,
    StabilityProtocol,
    check_stability,
)

log = logging.getLogger("bench_stability")
RESULTS = Path(__file__).resolve().parent.parent / "benchmarks" / "results"


def machine() -> dict[str, Any]:
    """What this ran on."""
    info: dict[str, Any] = {
        "host": platform.node(),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "processor": platform.processor() or platform.machine(),
    }
    try:
        with open("/proc/cpuinfo") as f:
            names = [ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")]
        info["cpu_model"] = names[0] if names else None
    except OSError:
        pass
    if cuda_available():
        try:
            out = subprocess.run(
                ["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"],
                capture_output=True,
                text=True,
                timeout=20,
                check=False,
            )
            info["gpu"] = out.stdout.strip()
        except OSError:
            info["gpu"] = "cuda (nvidia-smi missing)"
    import mujoco

    info["mujoco"] = mujoco.__version__
    return info


def _cylinder_asset(assets: Path) -> str:
    import trimesh

    aid = "bench-cylinder"
    folder = assets / aid
    if not (folder / "meta.json").is_file():
        folder.mkdir(parents=True, exist_ok=True)
        mesh = trimesh.creation.cylinder(radius=0.05, height=0.12, sections=12)
        mesh.apply_translation([0, 0, 0.06])
        mesh.export(folder / "visual.obj")
        meta = AssetMeta(
            asset_id=aid,
            backend="procedural",
            visual="visual.obj",
            extents=[float(e) for e in mesh.extents],
            collision=["visual.obj"],
            license="CC0-1.0",
            provenance={"generator": "bench_stability"},
        )
        (folder / "meta.json").write_text(asset_meta_to_json(meta))
    return aid


def bench_scene(n_objects: int, assets: Path) -> Scene:
    """A room with n/2 boxes on the floor and n/2 mesh cylinders on top of them."""
    n_base = (n_objects + 1) // 2
    side = int(np.ceil(np.sqrt(n_base)))
    size = 1.0 * side + 1.0
    room = Room(
        id="room", room_type="bench", position=Vec3(0, 0, 0), dimensions=Size3(size, size, 2.5)
    )
    aid = _cylinder_asset(assets)
    objs = []
    for i in range(n_objects):
        b = i % n_base
        x, y = 1.0 + (b % side), 1.0 + (b // side)
        if i < n_base:
            objs.append(
                SceneObject(
                    id=f"box_{i}",
                    room_id="room",
                    category="box",
                    position=Vec3(x, y, 0.0),
                    dimensions=Size3(0.4, 0.4, 0.4),
                    physics=Physics(mass=5.0),
                )
            )
        else:
            k = i - n_base
            objs.append(
                SceneObject(
                    id=f"cyl_{k}",
                    room_id="room",
                    category="can",
                    position=Vec3(x, y, 0.4),
                    dimensions=Size3(0.1, 0.1, 0.12),
                    physics=Physics(mass=0.3),
                    placement=Placement(kind="on_top", support_id=f"box_{b}"),
                    asset=AssetRef(backend="procedural", asset_id=aid),
                )
            )
    return Scene(id=f"bench_{n_objects}", rooms=[room], objects=objs, source="example")


def candidates(model: Any, n: int, seed: int = 0, spread: float = 0.05) -> np.ndarray:
    """``(n, nq)``: the cylinders jittered in x, y (+-spread m) and yaw."""
    rng = np.random.default_rng(seed)
    free = FreeBodies.of(model)
    q = np.tile(model.qpos0, (n, 1))
    for j, name in enumerate(free.names):
        if not name.startswith("cyl_"):
            continue
        adr = free.qposadr[j]
        q[:, adr : adr + 2] += rng.uniform(-spread, spread, size=(n, 2))
        yaw = rng.uniform(0, np.pi, size=n)
        q[:, adr + 3] = np.cos(yaw / 2)
        q[:, adr + 6] = np.sin(yaw / 2)
    return q


def run_case(
    backend_name: str, model: Any, batch: int, protocol: StabilityProtocol, nthread: int
) -> dict[str, Any]:
    opts: dict[str, Any] = {"nthread": nthread} if backend_name == "cpu" else {}
    if backend_name == "mjx":
        opts = {"max_free_bodies": 64}
    engine_name = backend_name
    if backend_name == "warp-strict":
        engine_name, opts = "warp", {"sleep": False}
    t0 = time.perf_counter()
    backend = get_backend(engine_name, **opts)
    q = candidates(model, batch)
    cold = time.perf_counter()
    r1 = check_stability(model, q, backend=backend, protocol=protocol)
    cold = time.perf_counter() - cold + (cold - t0)
    warm = time.perf_counter()
    r2 = check_stability(model, q, backend=backend, protocol=protocol)
    warm = time.perf_counter() - warm
    nstep = protocol.nstep(model)
    steps_run = getattr(backend, "steps_run", None)
    return {
        "backend": backend_name,
        "impl": getattr(backend, "impl", None),
        "steps_run_per_launch": list(steps_run) if steps_run else None,
        "batch": batch,
        "cold_s": round(cold, 3),
        "warm_s": round(warm, 3),
        "warm_sim_s": round(r2.seconds, 3),
        "checks_per_s": round(batch / warm, 2),
        "protocol_world_steps_per_s": round(batch * nstep / warm, 1),
        "stable_fraction": float(r2.stable.mean()),
        "invalid": int(r2.invalid.sum()),
        "same_verdicts_cold_warm": bool(np.array_equal(r1.stable, r2.stable)),
    }


def raw_rate(model: Any, batch: int, nstep: int, sleep: bool) -> dict[str, Any]:
    """World-steps/s of bare graph-captured ``mujoco_warp.step`` calls on ``batch`` worlds."""
    import copy

    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    from factory.sim.backend_warp import WarpBackend

    m_cpu = copy.copy(model)
    bit = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    flags = int(model.opt.enableflags)
    m_cpu.opt.enableflags = flags | bit if sleep else flags & ~bit
    m = mjw.put_model(m_cpu)
    q = candidates(model, batch)
    nconmax, njmax = WarpBackend.initial_sizes(model, q)
    d = mjw.put_data(m_cpu, mujoco.MjData(m_cpu), nworld=batch, nconmax=nconmax, njmax=njmax)
    d.qpos.assign(wp.array(q.astype(np.float32), dtype=float))
    chunk = 50
    with wp.ScopedCapture() as cap:
        for _ in range(chunk):
            mjw.step(m, d)
    wp.capture_launch(cap.graph)  # warm-up
    wp.synchronize()
    d.qpos.assign(wp.array(q.astype(np.float32), dtype=float))
    t0 = time.perf_counter()
    for _ in range(nstep // chunk):
        wp.capture_launch(cap.graph)
    wp.synchronize()
    sec = time.perf_counter() - t0
    steps = chunk * (nstep // chunk)
    return {
        "batch": batch,
        "sleep": sleep,
        "steps": steps,
        "seconds": round(sec, 3),
        "world_steps_per_s": round(batch * steps / sec, 1),
    }


def agreement(
    model: Any, n: int, protocol: StabilityProtocol, spread: float, other: str = "warp"
) -> dict[str, Any]:
    """cpu vs ``other`` verdicts on the same n candidates (wide jitter: a mix of outcomes)."""
    q = candidates(model, n, seed=7, spread=spread)
    cpu = check_stability(model, q, backend="cpu", protocol=protocol)
    engine = get_backend("warp", sleep=False) if other == "warp-strict" else get_backend(other)
    warp = check_stability(model, q, backend=engine, protocol=protocol)
    same = cpu.stable == warp.stable
    return {
        "other": other,
        "candidates": n,
        "agreement_pct": round(100.0 * float(same.mean()), 3),
        "cpu_stable": int(cpu.stable.sum()),
        "other_stable": int(warp.stable.sum()),
        "disagreeing": int((~same).sum()),
        "invalid_cpu": int(cpu.invalid.sum()),
        "invalid_other": int(warp.invalid.sum()),
        "max_translation_diff_m": float(
            np.max(
                np.abs(
                    np.nan_to_num(cpu.translation, posinf=9)
                    - np.nan_to_num(warp.translation, posinf=9)
                )
            )
        ),
    }


def sleep_agreement(
    model: Any, n: int, protocol: StabilityProtocol, spread: float
) -> dict[str, Any]:
    """warp with sleeping vs the strict warp verdicts (sleeping off) on n candidates."""
    q = candidates(model, n, seed=11, spread=spread)
    strict = check_stability(model, q, backend=get_backend("warp", sleep=False), protocol=protocol)
    asleep = check_stability(model, q, backend=get_backend("warp", sleep=True), protocol=protocol)
    same = strict.stable == asleep.stable
    return {
        "candidates": n,
        "spread_m": spread,
        "agreement_pct": round(100.0 * float(same.mean()), 3),
        "strict_stable": int(strict.stable.sum()),
        "sleep_stable": int(asleep.stable.sum()),
        "disagreeing": int((~same).sum()),
        "max_translation_diff_m": float(
            np.max(
                np.abs(
                    np.nan_to_num(strict.translation, posinf=9)
                    - np.nan_to_num(asleep.translation, posinf=9)
                )
            )
        ),
    }


def main() -> None:
    default_backends = ["cpu"] + (["warp"] if cuda_available() else [])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--backends", nargs="+", default=default_backends)
    p.add_argument("--objects", nargs="+", type=int, default=[5, 20, 50])
    p.add_argument(
        "--batches",
        nargs="+",
        type=int,
        default=None,
        help="batch sizes (default: cpu 8 32; warp 1024 4096 8192; mjx 64)",
    )
    p.add_argument("--nthread", type=int, default=0)
    p.add_argument("--agree", type=int, default=0, help="cpu vs warp agreement on N candidates")
    p.add_argument("--agree-objects", type=int, default=20)
    p.add_argument("--timestep", type=float, default=None, help="check step (s); default 2 ms")
    p.add_argument("--spread", type=float, default=0.21, help="agreement jitter (m)")
    p.add_argument("--agree-with", nargs="+", default=["warp"], help="backends compared to cpu")
    p.add_argument("--sleep-agree", type=int, default=0, help="warp sleep vs strict on N")
    p.add_argument("--raw", action="store_true", help="bare mujoco_warp step rate per batch")
    p.add_argument("--out", default=None)
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    protocol = StabilityProtocol(resettle=False, timestep=args.timestep)
    defaults = {
        "cpu": [8, 32],
        "warp": [1024, 4096, 8192],
        "warp-strict": [1024, 4096, 8192],
        "mjx": [64],
    }
    results: dict[str, Any] = {
        "schema_version": 1,
        "benchmark": "stability",
        "machine": machine(),
        "protocol": vars(protocol),
        "step_s": args.timestep or 0.002,
        "cases": [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        assets = Path(tmp) / "assets"
        for n_obj in args.objects:
            scene = bench_scene(n_obj, assets)
            model = compile_scene(scene, assets).model
            for name in args.backends:
                if name == "mjx" and n_obj > 5 and not cuda_available():
                    continue  # MJX-JAX compiles for minutes at scene sizes: see backend_mjx
                for batch in args.batches or defaults[name]:
                    case = {
                        "objects": n_obj,
                        **run_case(name, model, batch, protocol, args.nthread),
                    }
                    log.info("%s", case)
                    results["cases"].append(case)
            if args.raw:
                nstep = protocol.nstep(model)
                for batch in args.batches or defaults["warp"]:
                    for sleep in (False, True):
                        row = {"objects": n_obj, **raw_rate(model, batch, nstep, sleep)}
                        log.info("raw %s", row)
                        results.setdefault("raw", []).append(row)
        if args.agree:
            scene = bench_scene(args.agree_objects, assets)
            model = compile_scene(scene, assets).model
            results["agreement"] = [
                {
                    "objects": args.agree_objects,
                    "spread_m": args.spread,
                    **agreement(model, args.agree, protocol, args.spread, other),
                }
                for other in args.agree_with
            ]
            log.info("agreement: %s", results["agreement"])
        if args.sleep_agree:
            scene = bench_scene(args.agree_objects, assets)
            model = compile_scene(scene, assets).model
            results["sleep_agreement"] = [
                {
                    "objects": args.agree_objects,
                    **sleep_agreement(model, args.sleep_agree, protocol, sp),
                }
                for sp in (0.05, args.spread)
            ]
            log.info("sleep agreement: %s", results["sleep_agreement"])
    print(json.dumps(results, indent=2))
    out = (
        Path(args.out)
        if args.out
        else RESULTS / (f"stability-{platform.node()}-{time.strftime('%Y%m%d-%H%M%S')}.json")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    log.info("wrote %s", out)


if __name__ == "__main__":
    main()
