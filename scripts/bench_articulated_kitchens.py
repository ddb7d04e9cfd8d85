"""Articulated kitchens through generation and validation: joints, things stored inside.

    python scripts/bench_articulated_kitchens.py [--scenes 3] [--run-dir runs/articulated]
        [--out benchmarks/results/generate-articulated-kitchens-cpu2.json] [--reuse]

Runs ``stage=generate`` (the pick-and-place kitchen request, ``assets.articulated=true``) and
``stage=validate`` through the command line, then reads every scene: its objects, the link
joints of its compiled model (MuJoCo joint group 3), and the things stored inside articulated
furniture (below the support's top surface), counted by the holder's category. ``--reuse``
reads a run made before (no generation, no validation). Prints and saves JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REQUEST = "a kitchen where the robot picks up a mug and puts it in the bowl"


def _cli(*args: str) -> None:
    out = subprocess.run([sys.executable, "-m", "factory", *args], cwd=ROOT)
    if out.returncode != 0:
        sys.exit(f"bench_articulated_kitchens: {' '.join(args[:1])} failed ({out.returncode})")


def _stored_inside(scene, assets: Path) -> Counter[str]:
    """Holder category -> things stored inside it."""
    from factory.scenes.interiors import stored_inside

    return Counter(holder.category for _, holder in stored_inside(scene, assets))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=3)
    p.add_argument("--run-dir", type=Path, default=ROOT / "runs" / "articulated")
    p.add_argument(
        "--out",
        type=Path,
        default=ROOT / "benchmarks" / "results" / "generate-articulated-kitchens-cpu2.json",
    )
    p.add_argument("--reuse", action="store_true", help="read a run made before")
    args = p.parse_args()
    run = args.run_dir
    common = ["sim.backend=cpu", "demos.executor=cpu", "assets.articulated=true"]
    t0 = time.perf_counter()
    if not args.reuse:
        _cli(
            "stage=generate",
            f"run_dir={run}",
            f"generate.prompts=[{REQUEST}]",
            f"generate.scenes_per_prompt={args.scenes}",
            "seed=0",
            *common,
        )
    gen_s = time.perf_counter() - t0
    if not args.reuse:
        _cli("stage=validate", f"run_dir={run}", *common)

    from factory.schema import scene_from_json
    from factory.sim.compile import LINK_JOINT_GROUP, compile_scene

    scenes = {}
    for path in sorted((run / "scenes").glob("*/scene.json")):
        scene = scene_from_json(path.read_text())
        model = compile_scene(scene, run / "assets").model
        links = sum(int(model.jnt_group[j] == LINK_JOINT_GROUP) for j in range(model.njnt))
        held = _stored_inside(scene, run / "assets")
        scenes[scene.id] = {
            "objects": len(scene.objects),
            "link_joints": links,
            "stored_inside": sum(held.values()),
            "stored_inside_by_holder": dict(sorted(held.items())),
        }
    summaries = (
        sorted((run / "validate").glob("*summary*.json")) if (run / "validate").exists() else []
    )
    result = {
        "schema_version": 1,
        "benchmark": "generate-articulated-kitchens",
        "machine": {"cpus": os.cpu_count(), "gpu": None},
        "git_sha": subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip(),
        "command": "python scripts/bench_articulated_kitchens.py " + " ".join(sys.argv[1:]),
        "request": REQUEST,
        "generate_seconds": None if args.reuse else round(gen_s, 1),
        "scenes": scenes,
        "validate_summary": json.loads(summaries[-1].read_text()).get("total")
        if summaries
        else None,
    }
    text = json.dumps(result, indent=2)
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(text + "\n")
    tmp.replace(args.out)


if __name__ == "__main__":
    main()
