"""Benchmark of augmentation: variants per minute and acceptance rate per level, and the
paper-style figure (a base scene and three variants per level).

    python scripts/bench_augment.py [--variants 6] [--backend cpu|warp]
        [--figure docs/images/augmentation.png]

A base kitchen with a pick-and-place task is generated first (not timed). Each level then
makes ``--variants`` variants; a variant is accepted when the level succeeded and the whole
scene passes the strict physics check (no interpenetration over 1 cm, every object stable).
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

from factory.sim.gl import configure_gl

configure_gl("auto")

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from factory.assets import AssetLibrary  # noqa: E402
from factory.augment.levels import AugmentError  # noqa: E402
from factory.augment.stage import LEVELS, check_physics, variant_seed  # noqa: E402
from factory.scenes.brain import AgentConfig, generate_scene  # noqa: E402
from factory.scenes.render import render_views  # noqa: E402
from factory.sim.compile import compile_scene  # noqa: E402
from factory.sim.critic import physics_critic  # noqa: E402
from factory.sim.stability import StabilityProtocol  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TASK = "a kitchen where the robot picks up the mug and puts it in the bowl"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", type=int, default=6)
    p.add_argument("--backend", default="cpu")
    p.add_argument("--figure", default=str(ROOT / "docs" / "images" / "augmentation.png"))
    p.add_argument("--out", default=None)
    args = p.parse_args()
    rows: dict[str, dict] = {}
    w, h = 320, 240
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        base, _ = generate_scene(TASK, lib, seed=2, config=AgentConfig(max_objects=40))

        def critic(sc, oid, poses):
            return physics_critic(
                sc,
                oid,
                poses,
                assets_root=lib.assets_dir,
                backend=args.backend,
                protocol=StabilityProtocol(),
            )

        def view(scene) -> np.ndarray:
            model = compile_scene(scene, lib.assets_dir).model
            return render_views(model, scene, ["corner_0"], w, h)["corner_0"]

        sheet = Image.new("RGB", (4 * w, 3 * (h + 18)), "white")
        draw = ImageDraw.Draw(sheet)
        base_img = Image.fromarray(view(base)) if args.figure else None
        for r, level in enumerate(LEVELS):
            accepted, failed, images = 0, {}, []
            t0 = time.perf_counter()
            for k in range(args.variants):
                seed = variant_seed(0, f"{base.id}:{level}", k)
                try:
                    v = LEVELS[level](base, lib, seed, critic).scene
                except AugmentError as e:
                    key = str(e).split(":")[0]
                    failed[key] = failed.get(key, 0) + 1
                    continue
                why = check_physics(v, lib.assets_dir, backend=args.backend)
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
                "acceptance": accepted / args.variants,
                "failures": failed,
                "seconds": round(seconds, 1),
                "variants_per_minute": round(60 * args.variants / seconds, 2),
                "accepted_per_minute": round(60 * accepted / seconds, 2),
            }
            print(level, rows[level])
            if base_img is None:
                continue
            y = r * (h + 18)
            sheet.paste(base_img, (0, y))
            draw.text((4, y + h + 3), f"base | {level}", fill=(0, 0, 0))
            for c, v in enumerate(images):
                sheet.paste(Image.fromarray(view(v)), ((c + 1) * w, y))
                draw.text(((c + 1) * w + 4, y + h + 3), f"{level} variant {c + 1}", fill=(0, 0, 0))
    if args.figure:
        sheet.save(args.figure, optimize=True)
    doc = {
        "schema_version": 1,
        "benchmark": "augment",
        "backend": args.backend,
        "machine": {"host": platform.node(), "python": platform.python_version()},
        "levels": rows,
    }
    print(json.dumps(doc, indent=2))
    out = (
        Path(args.out)
        if args.out
        else ROOT / "benchmarks" / "results" / (f"augment-{args.backend}-{platform.node()}.json")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
