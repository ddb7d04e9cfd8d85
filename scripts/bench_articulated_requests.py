"""Open, close and put-away requests through generation and demonstrations: usable scenes,
stored episodes, wall time and the moving joints of each generated model.

    python scripts/bench_articulated_requests.py
        [--runs fridge,microwave,kitchen_drawer,wardrobe,nightstand]
        [--run-root runs/articulated-requests] [--episodes 5] [--reuse]
        [--out benchmarks/results/articulated-requests-cpu2.json]
        [--machine "2-core VM, shared"] [--date 2026-11-29]

    # task=place_inside in generated bedrooms (the ``put_*`` runs)
    python scripts/bench_articulated_requests.py --runs 'put_*' \
        --out benchmarks/results/place-inside-bedroom-requests-cpu2.json

    # task=place_inside behind doors (the ``door_*`` runs)
    python scripts/bench_articulated_requests.py --runs 'door_*' --episodes 6 \
        --out benchmarks/results/place-inside-doors-cpu2.json

For each run (a request and a scene count, :data:`RUNS`) it calls ``stage=generate`` with the
request alone (no ``assets.articulated``: the request's task turns it on) and then
``stage=demos`` with no ``task=`` (the task is the scenes' ``task.kind``, read by
``task_for_scene``), the CPU executor, no images, through the command line; then reads each
scene's ``task``, its compiled ``model.xml``'s hinge and slide joints of articulated links
(MuJoCo joint group 3), and the demos' summary (stored / tried, failures by reason, each
unusable scene's reason).
``--runs`` takes names of :data:`RUNS` and shell patterns of them (``put_*``). ``--reuse``
reads runs made before. Prints and saves JSON; runs of an earlier ``--out`` that
are not named in ``--runs`` keep their results (each run records its ``git_sha``).
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

RUNS: dict[str, tuple[str, int]] = {
    "fridge": ("open the fridge door", 3),
    "microwave": ("close the microwave door", 2),
    "kitchen_drawer": ("a kitchen where the robot closes the top drawer", 2),
    "wardrobe": ("open the wardrobe door", 2),
    "nightstand": ("open the top drawer of the nightstand", 2),
    # task=place_inside in bedrooms: a nightstand's drawer, a dresser's (drawer chest's)
    "put_pill_nightstand": ("put the pill bottle in the drawer of the nightstand", 3),
    "put_book_nightstand": ("a bedroom where the robot puts the book in the nightstand drawer", 2),
    "put_phone_nightstand": ("put the phone in the drawer of the nightstand", 2),
    "put_mug_dresser": ("put the mug in the top drawer of the dresser", 3),
    "put_candle_chest": ("put the candle in the drawer of the chest of drawers", 2),
    "put_mug_bedroom": ("a bedroom where the robot puts the mug in the drawer", 2),
    # task=place_inside behind doors: a microwave's cavity, a fridge's shelf, a cabinet's floor
    "door_mug_microwave": ("put the mug in the microwave", 3),
    "door_can_microwave": ("put the can in the microwave", 3),
    "door_bottle_fridge": ("put the bottle in the fridge", 2),
    "door_cup_cabinet": ("put the cup in the cabinet", 2),
    "door_mug_nightstand": ("put the mug in the nightstand", 2),
}
"""Run name -> (request, scenes)."""

COMMON = ("sim.backend=cpu", "seed=0")


def _cli(*args: str) -> float:
    """Runs ``python -m factory ARGS``; returns its wall time (s)."""
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "factory", *args], cwd=ROOT)
    if out.returncode not in (0, 3):  # 3: some items failed (reported in the summary)
        sys.exit(f"bench_articulated_requests: {' '.join(args[:2])} failed ({out.returncode})")
    return time.perf_counter() - t0


def _commands(run: Path, request: str, scenes: int, episodes: int) -> list[list[str]]:
    return [
        [
            "stage=generate",
            f"run_dir={run}",
            f"generate.prompts=[{request}]",
            f"generate.scenes_per_prompt={scenes}",
            *COMMON,
        ],
        [
            "stage=demos",
            f"run_dir={run}",
            "demos.executor=cpu",
            f"demos.episodes_per_scene={episodes}",
            "demos.render=false",
            *COMMON,
        ],
    ]


def _scene_facts(scene_dir: Path) -> dict[str, object]:
    """A scene's task and the hinge and slide joints of its articulated links."""
    import mujoco

    from factory.sim.compile import LINK_JOINT_GROUP

    scene = json.loads((scene_dir / "scene.json").read_text())
    model = mujoco.MjModel.from_xml_path(str(scene_dir / "model.xml"))
    moving = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    links = [
        j
        for j in range(model.njnt)
        if model.jnt_group[j] == LINK_JOINT_GROUP and int(model.jnt_type[j]) in moving
    ]
    report = json.loads((scene_dir / "report.json").read_text()).get("generate", {})
    return {
        "task": scene.get("task"),
        "room_types": sorted({r["room_type"] for r in scene["rooms"]}),
        "link_joints": len(links),
        "hinges": sum(int(model.jnt_type[j]) == moving[0] for j in links),
        "slides": sum(int(model.jnt_type[j]) == moving[1] for j in links),
        "task_check": (report.get("task_check") or {}).get("detail"),
        "rejected_attempts": len(report.get("rejected_attempts", [])),
    }


def _cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else the machine type."""
    info = Path("/proc/cpuinfo")
    if info.is_file():
        for line in info.read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.machine()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--runs",
        default="fridge,microwave,kitchen_drawer,wardrobe,nightstand",
        help="comma-separated names of RUNS or patterns of them ('put_*')",
    )
    p.add_argument("--run-root", type=Path, default=ROOT / "runs" / "articulated-requests")
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--reuse", action="store_true", help="read runs made before")
    p.add_argument("--machine", default="", help='what the machine is ("2-core VM, shared")')
    p.add_argument("--date", default=time.strftime("%Y-%m-%d"), help="the measurement's date")
    p.add_argument(
        "--out",
        type=Path,
        default=ROOT / "benchmarks" / "results" / "articulated-requests-cpu2.json",
    )
    args = p.parse_args()
    results: dict[str, object] = {}
    if args.out.is_file():  # runs not re-run keep their results (and their commit)
        before = json.loads(args.out.read_text())
        results = {
            k: {"git_sha": before.get("git_sha"), **v} for k, v in before.get("runs", {}).items()
        }
    sha = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    names = [n for pat in args.runs.split(",") for n in RUNS if fnmatch.fnmatchcase(n, pat)]
    for name in dict.fromkeys(names):
        request, n = RUNS[name]
        run = args.run_root / name
        gen_cmd, demos_cmd = _commands(run, request, n, args.episodes)
        gen_s = demos_s = None
        if not args.reuse:
            gen_s = round(_cli(*gen_cmd), 1)
            demos_s = round(_cli(*demos_cmd), 1)
        summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
        scenes = {d.name: _scene_facts(d) for d in sorted((run / "scenes").iterdir())}
        per_scene = summary.get("scenes", {})
        usable = [s for s in scenes if per_scene.get(s, {}).get("episodes", 0) > 0]
        results[name] = {
            "request": request,
            "git_sha": sha,
            "commands": [
                "python -m factory " + " ".join(c).replace(str(args.run_root), "<runs>")
                for c in (gen_cmd, demos_cmd)
            ],
            "generate_seconds": gen_s,
            "demos_seconds": demos_s,
            "scenes_usable": f"{len(usable)} / {len(scenes)}",
            "stored": summary.get("new_successes"),
            "tried": summary["new_successes"]
            + sum(v for k, v in summary["failures"].items() if k != "scene_unusable"),
            "failures": summary.get("failures"),
            "unusable": {s: v["error"] for s, v in per_scene.items() if v.get("error")},
            "scenes": {s: {**facts, "demos": per_scene.get(s)} for s, facts in scenes.items()},
        }
    out = {
        "schema_version": 1,
        "benchmark": "articulated-requests",
        "date": args.date,
        "machine": {
            "label": args.machine,
            "cpus": os.cpu_count(),
            "cpu": _cpu_model(),
            "gpu": None,
            "python": platform.python_version(),
        },
        "command": "python scripts/bench_articulated_requests.py "
        + shlex.join(sys.argv[1:]).replace(str(args.run_root), "<runs>"),
        "runs": results,
    }
    text = json.dumps(out, indent=2)
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(text + "\n")
    tmp.replace(args.out)


if __name__ == "__main__":
    main()
