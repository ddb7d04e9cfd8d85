"""Breadth of generation through the real command line: requests over many room types, each
scene generated (``stage=generate``, its last step the strict check with repair and the task
critic), then ``stage=validate``; per scene the objects, collision and stability as
``stage=validate`` measures them, the final check's changes, the task critic's verdict and
the corner views (blocked within 1 m, share of the room's objects seen:
:mod:`factory.scenes.view_rays`), and an independent check with plain MuJoCo on each
``model.xml`` (contacts deeper than 1 cm at rest; free bodies that move more than 0.2 m or
turn more than 8 degrees in 2 s).

    python scripts/bench_breadth.py --requests-file reqs.txt --scenes-per-request 2 --shards 2
    python scripts/bench_breadth.py --run-dir R        # summarise a run already generated

Writes ``benchmarks/results/<out>.json`` and, with ``--sheet``, a contact sheet of the first
corner view of up to 20 scenes (``docs/images/<sheet>``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from factory.sim.gl import configure_gl

configure_gl("auto")

import mujoco  # noqa: E402

from factory.scenes.render import VIEWS, clear_view_cameras, render_views  # noqa: E402
from factory.store import RunStore  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _cli(*args: str) -> None:
    out = subprocess.run([sys.executable, "-m", "factory", *args], cwd=ROOT, text=True)
    if out.returncode != 0:
        raise SystemExit(f"python -m factory {' '.join(args)} failed ({out.returncode})")


def generate(run: Path, requests_file: Path, per_request: int, shards: int) -> float:
    """Generates and validates the run's scenes; returns the generation's wall seconds."""
    t0 = time.perf_counter()
    common = [
        f"run_dir={run}",
        f"generate.prompts_file={requests_file}",
        f"generate.scenes_per_prompt={per_request}",
        "generate.render=false",
        "sim.backend=cpu",
    ]
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "factory",
                "stage=generate",
                *common,
                f"shard.index={i}",
                f"shard.count={shards}",
            ],
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for i in range(shards)
    ]
    codes = [p.wait() for p in procs]
    seconds = time.perf_counter() - t0
    if any(codes):
        print(f"generate: shard exit codes {codes} (see {run}/logs)")
    _cli("stage=validate", f"run_dir={run}", "sim.backend=cpu")
    return seconds


def plain_mujoco_check(model_xml: Path, seconds: float = 2.0) -> dict[str, Any]:
    """An independent check with nothing but MuJoCo: the free bodies of ``model.xml`` at
    rest, any contact deeper than 1 cm at the first step, then ``seconds`` of simulation:
    bodies that moved more than 0.2 m or turned more than 8 degrees (the paper's thresholds)."""
    import numpy as np

    m = mujoco.MjModel.from_xml_path(str(model_xml))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    deep = sum(1 for c in d.contact[: d.ncon] if c.dist < -0.01)
    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    adr = [int(m.jnt_qposadr[j]) for j in free]
    q0 = d.qpos.copy()
    for _ in range(int(seconds / m.opt.timestep)):
        mujoco.mj_step(m, d)
    moved = 0
    for a in adr:
        shift = float(np.linalg.norm(d.qpos[a : a + 3] - q0[a : a + 3]))
        dot = abs(float(np.dot(d.qpos[a + 3 : a + 7], q0[a + 3 : a + 7])))
        turn = 2 * np.degrees(np.arccos(min(1.0, dot)))
        moved += int(shift > 0.2 or turn > 8.0)
    return {"free_bodies": len(adr), "deep_contacts": deep, "moved": moved}


def summarise(run: Path) -> list[dict[str, Any]]:
    store = RunStore(run)
    rows = []
    for sid in store.scene_ids():
        scene = store.load_scene(sid)
        report = json.loads(store.report_json(sid).read_text())
        gen, val = report.get("generate", {}), report.get("validate", {})
        model = mujoco.MjModel.from_xml_path(str(store.model_xml(sid)))
        _, views = clear_view_cameras(model, scene, VIEWS)
        metrics = val.get("metrics", {})
        rows.append(
            {
                "scene": sid,
                "request": gen.get("request"),
                "room_types": sorted({r.room_type for r in scene.rooms}),
                "objects": len(scene.objects),
                "collision_pct": 100 * metrics.get("collision", {}).get("ratio", float("nan")),
                "stability_pct": 100 * metrics.get("stability", {}).get("ratio", float("nan")),
                "final_check_changes": [
                    f"{c['action']} {c['object']}"
                    for c in gen.get("final_check", {}).get("changes", [])
                ],
                "generate_seconds": gen.get("seconds"),
                "final_check_seconds": gen.get("final_check", {}).get("seconds"),
                "task_check": (gen.get("task_check") or {}).get("reason"),
                "rejected_attempts": [r["reason"] for r in gen.get("rejected_attempts", [])],
                "views": views,
                "plain_mujoco": plain_mujoco_check(store.model_xml(sid)),
            }
        )
    return rows


def sheet(run: Path, rows: list[dict[str, Any]], out: Path, n: int = 20) -> None:
    from factory.scenes.render import contact_sheet, png_bytes

    store = RunStore(run)
    tiles = {}
    for r in rows[:n]:
        scene = store.load_scene(r["scene"])
        model = mujoco.MjModel.from_xml_path(str(store.model_xml(r["scene"])))
        tiles[r["scene"]] = render_views(model, scene, ["corner_0"], 320, 240)["corner_0"]
    out.write_bytes(png_bytes(contact_sheet(tiles, columns=5)))
    print(f"wrote {out}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--requests-file", type=Path)
    p.add_argument("--scenes-per-request", type=int, default=2)
    p.add_argument("--shards", type=int, default=os.cpu_count() or 1)
    p.add_argument("--run-dir", type=Path, default=None)
    p.add_argument("--sheet", default=None, help="docs/images/<name>.png: a contact sheet")
    p.add_argument("--out", default="generate-breadth-cpu")
    args = p.parse_args()
    run = args.run_dir or Path(tempfile.mkdtemp(prefix="breadth-")) / "run"
    seconds = None
    if not RunStore(run).scene_ids():
        if args.requests_file is None:
            raise SystemExit("--requests-file is needed to generate a run")
        seconds = generate(run, args.requests_file, args.scenes_per_request, args.shards)
    rows = summarise(run)
    views = [v for r in rows for v in r["views"].values()]
    total = {
        "scenes": len(rows),
        "room_types": len({t for r in rows for t in r["room_types"]}),
        "scenes_colliding": sum(r["collision_pct"] > 0 for r in rows),
        "scenes_unstable": sum(r["stability_pct"] < 100 for r in rows),
        "objects_mean": round(sum(r["objects"] for r in rows) / max(len(rows), 1), 1),
        "final_check_changes": sum(len(r["final_check_changes"]) for r in rows),
        "task_scenes": sum(r["task_check"] is not None for r in rows),
        "task_scenes_feasible": sum(r["task_check"] == "" for r in rows),
        "rejected_attempts": sum(len(r["rejected_attempts"]) for r in rows),
        "views": len(views),
        "views_blocked": sum(v["blocked"] for v in views),
        "views_under_half": sum(v["seen"] < v["objects"] / 2 for v in views),
        "plain_mujoco_scenes_with_deep_contacts": sum(
            r["plain_mujoco"]["deep_contacts"] > 0 for r in rows
        ),
        "plain_mujoco_scenes_with_moved_bodies": sum(r["plain_mujoco"]["moved"] > 0 for r in rows),
        "generate_wall_seconds": None if seconds is None else round(seconds, 1),
    }
    for r in rows:
        print(
            f"{r['scene']:<34} {','.join(r['room_types']):<22} {r['objects']:>4} obj  "
            f"{r['collision_pct']:5.1f} % coll  {r['stability_pct']:5.1f} % stable  "
            f"task {r['task_check']!s:<6} views "
            + " ".join(
                f"{v['seen']}/{v['objects']}{'B' if v['blocked'] else ''}"
                for v in r["views"].values()
            )
        )
    total = {k: v if v is None or isinstance(v, float) else int(v) for k, v in total.items()}
    print(json.dumps(total, indent=1))
    result = {
        "schema_version": 1,
        "benchmark": "generate-breadth",
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "command": " ".join(sys.argv[1:]).replace(str(run), "<run>"),
        "total": total,
        "scenes": rows,
    }
    out = ROOT / "benchmarks" / "results" / f"{args.out}.json"
    out.write_text(json.dumps(result, indent=1))
    print(f"wrote {out}")
    if args.sheet:
        sheet(run, rows, ROOT / "docs" / "images" / args.sheet)


if __name__ == "__main__":
    main()
