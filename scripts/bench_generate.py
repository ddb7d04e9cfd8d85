"""Benchmark and evaluation of scene generation with the heuristic agent (CPU).

    python scripts/bench_generate.py speed            # s/scene, s/object, 20-object scenes,
                                                      # with and without the physics critic
    python scripts/bench_generate.py quality --scenes 10   # bedroom/kitchen/living room:
                                                      # objects per room, collision %, stable %
    python scripts/bench_generate.py time --requests "a kitchen" "a four-room apartment"
                                                      # s per scene, cold (empty asset cache)
                                                      # and warm (assets cached), per request
    python scripts/bench_generate.py time --scope scene --workers 1   # the whole-scene critic,
                                                      # rooms one after the other (before)

Quality numbers are the validate stage's: MuJoCo-contact collisions (> 1 cm into another
object) and the strict protocol (2 s, 0.2 m / 8 deg, no resettling). Results are printed and
saved as JSON under ``benchmarks/results/``; ``quality`` also writes a render sheet per room type
to ``docs/images/``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

from factory.sim.gl import configure_gl

configure_gl("auto")

from factory.assets import AssetLibrary  # noqa: E402
from factory.scenes.brain import AgentConfig, generate_scene  # noqa: E402
from factory.sim.compile import compile_scene  # noqa: E402
from factory.sim.metrics import measure_scene  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def measure(scene: Any, assets: Path, trimesh_test: bool = True) -> dict[str, Any]:
    return measure_scene(scene, assets, trimesh_test=trimesh_test)


def speed(args: argparse.Namespace) -> dict[str, Any]:
    rows = []
    for critic in (False, True):
        for seed in range(args.seeds):
            with tempfile.TemporaryDirectory() as tmp:
                lib = AssetLibrary(Path(tmp))
                # warm the asset cache so that the numbers are about placement and physics
                cfg = AgentConfig(physics_critic=critic, max_objects=20, extra_fill=2)
                t0 = time.perf_counter()
                scene, _ = generate_scene("a living room", lib, seed=seed, config=cfg)
                gen = time.perf_counter() - t0
                t1 = time.perf_counter()
                m = measure(scene, Path(tmp), trimesh_test=False)
                val = time.perf_counter() - t1
            rows.append(
                {
                    "physics_critic": critic,
                    "seed": seed,
                    "objects": len(scene.objects),
                    "generate_s": round(gen, 2),
                    "validate_s": round(val, 2),
                    "total_s": round(gen + val, 2),
                    "s_per_object": round((gen + val) / max(1, len(scene.objects)), 3),
                    "collision": m["collision"]["ratio"],
                    "stability": m["stability"]["ratio"],
                }
            )
            print(rows[-1])
    return {"rows": rows}


def timing(args: argparse.Namespace) -> dict[str, Any]:
    """Seconds per generated scene, cold (a new asset folder: every asset is built) and warm
    (the same request and seed again on the built assets), with the scene's size and, with
    ``--measure``, its validate-stage quality (not timed)."""
    rows = []
    for request in args.requests:
        for seed in range(args.seeds):
            with tempfile.TemporaryDirectory() as tmp:
                lib = AssetLibrary(Path(tmp))
                cfg = AgentConfig(critic_scope=args.scope, workers=args.workers)
                for run in args.runs:
                    t0 = time.perf_counter()
                    scene, report = generate_scene(request, lib, seed=seed, config=cfg)
                    row: dict[str, Any] = {
                        "request": request,
                        "seed": seed,
                        "run": run,
                        "scope": args.scope,
                        "workers": report.get("workers", 1),
                        "rooms": len(scene.rooms),
                        "objects": len(scene.objects),
                        "seconds": round(time.perf_counter() - t0, 2),
                    }
                    if run == "cold" and args.measure:
                        m = measure(scene, Path(tmp), trimesh_test=False)
                        row["colliding"] = len(m["collision"]["colliding"])
                        row["unstable"] = len(m["stability"]["unstable"])
                    rows.append(row)
                    print(row)
    summary: dict[str, Any] = {}
    for request in args.requests:
        for run in args.runs:
            sel = [r for r in rows if r["request"] == request and r["run"] == run]
            summary[f"{request} ({run})"] = {
                "scenes": len(sel),
                "seconds_mean": round(sum(r["seconds"] for r in sel) / len(sel), 2),
                "seconds_max": max(r["seconds"] for r in sel),
                "objects_mean": sum(r["objects"] for r in sel) / len(sel),
            }
    return {"cores": os.cpu_count(), "summary": summary, "rows": rows}


def quality(args: argparse.Namespace) -> dict[str, Any]:
    from factory.scenes.render import contact_sheet, png_bytes, render_views

    out: dict[str, Any] = {}
    for room in args.rooms:
        rows, images = [], {}
        with tempfile.TemporaryDirectory() as tmp:
            lib = AssetLibrary(Path(tmp))
            for seed in range(args.scenes):
                t0 = time.perf_counter()
                scene, _ = generate_scene(f"a {room}", lib, seed=seed)
                m = measure(scene, Path(tmp))
                rows.append(
                    {
                        "seed": seed,
                        "objects": m["objects"],
                        "colliding": len(m["collision"]["colliding"]),
                        "colliding_trimesh": len(m["collision_trimesh"]["colliding"]),
                        "unstable": len(m["stability"]["unstable"]),
                        "seconds": round(time.perf_counter() - t0, 1),
                    }
                )
                print(room, rows[-1])
                if seed < 3 and not args.no_sheets:
                    model = compile_scene(scene, Path(tmp)).model
                    images[f"{seed}"] = render_views(model, scene, ["corner_0"], 400, 300)[
                        "corner_0"
                    ]
        n = sum(r["objects"] for r in rows)
        out[room] = {
            "scenes": len(rows),
            "objects_per_room": n / len(rows),
            "collision_pct": 100 * sum(r["colliding"] for r in rows) / n,
            "collision_trimesh_pct": 100 * sum(r["colliding_trimesh"] for r in rows) / n,
            "stable_pct": 100 * (1 - sum(r["unstable"] for r in rows) / n),
            "seconds_per_scene": sum(r["seconds"] for r in rows) / len(rows),
            "rows": rows,
        }
        if images and not args.no_sheets:
            path = ROOT / "docs" / "images" / f"generated_{room.replace(' ', '_')}.png"
            path.write_bytes(png_bytes(contact_sheet(images, columns=3)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mode", choices=["speed", "quality", "time"])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--scenes", type=int, default=10)
    p.add_argument("--rooms", nargs="+", default=["bedroom", "kitchen", "living room"])
    p.add_argument(
        "--requests", nargs="+", default=["a bedroom", "a kitchen", "a four-room apartment"]
    )
    p.add_argument("--scope", choices=["local", "scene"], default="local")
    p.add_argument("--workers", type=int, default=None, help="processes for a home's rooms")
    p.add_argument("--measure", action="store_true", help="time: also collision/stability")
    p.add_argument("--runs", nargs="+", choices=["cold", "warm"], default=["cold", "warm"])
    p.add_argument("--no-sheets", action="store_true", help="quality: no render sheets")
    p.add_argument("--out", default=None)
    args = p.parse_args()
    modes = {"speed": speed, "quality": quality, "time": timing}
    result = modes[args.mode](args)
    doc = {
        "schema_version": 1,
        "benchmark": f"generate-{args.mode}",
        "machine": {"host": platform.node(), "python": platform.python_version()},
        **result,
    }
    print(json.dumps({k: v for k, v in doc.items() if k != "rows"}, indent=2, default=str)[:4000])
    out = (
        Path(args.out)
        if args.out
        else ROOT / "benchmarks" / "results" / (f"generate-{args.mode}-{platform.node()}.json")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
