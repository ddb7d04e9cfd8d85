"""Benchmark of augmentation: batched configuration variants per second, and variants per
minute with the acceptance rate of each level, and the paper-style figure.

    python scripts/bench_augment.py [--backend cpu|warp] [--count 100] [--verify 100]
        [--variants 6] [--levels configuration,category,layout] [--batch 0] [--duration 2.0]
        [--figure docs/images/augmentation.png | --figure ''] [--out results.json]

A base kitchen with a pick-and-place task is generated first (not timed).

* Configuration, batched (``configuration_batch``): :func:`factory.augment.levels.configurations`
  asks for ``--count`` distinct valid configurations of the task objects; ``cold`` is the first
  call in the process (the parent's whole-scene check, compiling the local scene, a GPU
  backend's kernels), ``warm`` a second call with another seed. A variant is *validated* when
  the batched strict check of its local scene passed (every dynamic object stable, no
  interpenetration over 1 cm) and the parent passed the whole-scene check outside it. Then the
  first ``--verify`` variants of the warm batch get the ordinary whole-scene check (the one of
  ``stage=validate``), batched: how many pass, and the rate of the two steps together.
* Levels (``levels``): each of ``--levels`` makes ``--variants`` variants one at a time, each
  checked with the ordinary whole-scene check (configuration: one variant per call).
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

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from factory.assets import AssetLibrary  # noqa: E402
from factory.augment.check import PhysicsCheck, batch_sizes, verify_whole_scene  # noqa: E402
from factory.augment.levels import AugmentError, configurations  # noqa: E402
from factory.augment.stage import LEVELS, check_physics, variant_seed  # noqa: E402
from factory.scenes.brain import AgentConfig, generate_scene  # noqa: E402
from factory.scenes.render import render_views  # noqa: E402
from factory.sim.backend import get_backend  # noqa: E402
from factory.sim.compile import compile_scene  # noqa: E402
from factory.sim.stability import StabilityProtocol  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TASK = "a kitchen where the robot picks up the mug and puts it in the bowl"


def _batch_row(batch: Any, seconds: float) -> dict[str, Any]:
    st = batch.stats
    return {
        "requested": st.get("requested"),
        "variants": len(batch),
        "seconds": round(seconds, 3),
        "variants_per_s": round(len(batch) / seconds, 2),
        "rows_checked": st.get("checked", 0),
        "rows_simulated": st.get("simulated", 0),
        "rows_valid": st.get("valid", 0),
        "drawn": st.get("drawn", 0),
        "footprint_free": st.get("footprint_free", 0),
        "rounds": st.get("rounds", 0),
        "local_scene": {
            "dynamic": st.get("local_dynamic"),
            "static_context": st.get("local_context"),
            "left_out": st.get("local_absent"),
        },
        "parent_check_s": st.get("parent_check_seconds"),
        "breakdown_s": st.get("seconds"),
        "failures": st.get("failures"),
    }


def bench_configuration(base: Any, lib: AssetLibrary, check: PhysicsCheck, args: Any) -> dict:
    """Cold and warm batched configuration variants, then the whole-scene check of some."""
    out: dict[str, Any] = {}
    batch = None
    for name, seed in (("cold", 1), ("warm", 2)):
        t0 = time.perf_counter()
        batch = configurations(base, lib, seed, args.count, check)
        seconds = time.perf_counter() - t0
        batch.stats["requested"] = args.count
        out[name] = _batch_row(batch, seconds)
        print(f"configuration batch {name}:", json.dumps(out[name]), flush=True)
    assert batch is not None
    n = min(args.verify, len(batch))
    if n:
        t0 = time.perf_counter()
        verdicts = verify_whole_scene(base, batch.ids, batch.poses[:n], check)
        seconds = time.perf_counter() - t0
        passed = int(verdicts.ok.sum())
        gen = out["warm"]["seconds"] * n / max(len(batch), 1)
        out["whole_scene_check"] = {
            "variants": n,
            "passed": passed,
            "agreement": round(passed / n, 4),
            "seconds": round(seconds, 3),
            "checks_per_s": round(n / seconds, 2),
            "failures": verdicts.failures(),
            "validated_and_checked_per_s": round(passed / (gen + seconds), 2),
        }
        print("whole-scene check:", json.dumps(out["whole_scene_check"]), flush=True)
    out["_batch"] = batch
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--backend", default="cpu", help="cpu, warp, mjx or auto (sim.backend)")
    p.add_argument("--count", type=int, default=0, help="variants per batch (0: cpu 100, GPU 2000)")
    p.add_argument("--verify", type=int, default=-1, help="whole-scene checks (-1: all)")
    p.add_argument("--batch", type=int, default=0, help="rows per check (0: by backend)")
    p.add_argument("--variants", type=int, default=6, help="variants per level, one at a time")
    p.add_argument("--levels", default="configuration,category,layout")
    p.add_argument(
        "--duration",
        type=float,
        default=2.0,
        help="simulated s per batched check (2.0; shorter only for smoke tests)",
    )
    p.add_argument("--figure", default=str(ROOT / "docs" / "images" / "augmentation.png"))
    p.add_argument("--out", default=None)
    args = p.parse_args()
    engine = get_backend(args.backend)
    if args.count <= 0:
        args.count = 100 if engine.name == "cpu" else 2000
    if args.verify < 0:
        args.verify = args.count
    lo, hi = batch_sizes(engine.name)
    if args.batch > 0:
        lo = hi = args.batch
    levels = [lv for lv in args.levels.split(",") if lv]
    rows: dict[str, dict] = {}
    w, h = 320, 240
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        base, _ = generate_scene(TASK, lib, seed=2, config=AgentConfig(max_objects=40))
        check = PhysicsCheck(
            lib.assets_dir,
            backend=engine,
            protocol=StabilityProtocol(duration=args.duration),
            batch_min=lo,
            batch_max=max(lo, hi),
        )
        config_batch = bench_configuration(base, lib, check, args)
        found = config_batch.pop("_batch")

        def view(scene) -> np.ndarray:
            model = compile_scene(scene, lib.assets_dir).model
            return render_views(model, scene, ["corner_0"], w, h)["corner_0"]

        sheet = Image.new("RGB", (4 * w, 3 * (h + 18)), "white")
        draw = ImageDraw.Draw(sheet)
        base_img = Image.fromarray(view(base)) if args.figure else None
        for r, level in enumerate(lv for lv in LEVELS if lv in levels):
            accepted, failed, images = 0, {}, []
            t0 = time.perf_counter()
            for k in range(args.variants):
                seed = variant_seed(0, f"{base.id}:{level}", k)
                try:
                    v = LEVELS[level](base, lib, seed, check).scene
                except AugmentError as e:
                    key = str(e).split(":")[0]
                    failed[key] = failed.get(key, 0) + 1
                    continue
                why = check_physics(v, lib.assets_dir, backend=engine)
                if why is not None:
                    failed["physics"] = failed.get("physics", 0) + 1
                    continue
                accepted += 1
                if len(images) < 3:
                    images.append(v)
            seconds = time.perf_counter() - t0
            rows[level] = {
                "attempted": args.variants,
                "accepted": accepted,
                "acceptance": accepted / args.variants if args.variants else 0.0,
                "failures": failed,
                "seconds": round(seconds, 1),
                "variants_per_minute": round(60 * args.variants / seconds, 2),
                "accepted_per_minute": round(60 * accepted / seconds, 2),
            }
            print(level, rows[level], flush=True)
            if base_img is None:
                continue
            if level == "configuration":
                images = [found.variant(i).scene for i in range(min(3, len(found)))]
            y = r * (h + 18)
            sheet.paste(base_img, (0, y))
            draw.text((4, y + h + 3), f"base | {level}", fill=(0, 0, 0))
            for c, v in enumerate(images):
                sheet.paste(Image.fromarray(view(v)), ((c + 1) * w, y))
                draw.text(((c + 1) * w + 4, y + h + 3), f"{level} variant {c + 1}", fill=(0, 0, 0))
    if args.figure and base_img is not None:
        sheet.save(args.figure, optimize=True)
    doc = {
        "schema_version": 2,
        "benchmark": "augment",
        "backend": engine.name,
        "machine": {
            "host": platform.node(),
            "python": platform.python_version(),
            "cpu_cores": len(os.sched_getaffinity(0)),
        },
        "scene": {"task": TASK, "seed": 2, "objects": len(base.objects)},
        "batch_rows": {"min": lo, "max": max(lo, hi)},
        "protocol_duration_s": args.duration,
        "configuration_batch": config_batch,
        "levels": rows,
    }
    print(json.dumps(doc, indent=2))
    out = (
        Path(args.out)
        if args.out
        else ROOT / "benchmarks" / "results" / (f"augment-{engine.name}-{platform.node()}.json")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
