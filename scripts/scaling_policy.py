"""The scaling experiment: closed-loop success in held-out scenes vs the number of training
scenes (the SAGE paper's scaling curve), with the planner as the reference line.

Given a run whose merged dataset (``<run>/dataset/merged``) holds demonstrations of ``S`` scenes
and whose other scenes are held out, it trains one policy per point ``N`` of ``--points``
(``stage=train train.scenes=N``: the first ``N`` of the dataset's scene ids, sorted, so every
point's scenes contain the previous point's), evaluates each on the same held-out scenes and
initial configurations (``stage=eval``), and the planner once on them
(``eval.policy=planner``). Every step is a call of the real command line, which resumes: a
killed experiment re-run continues where it stopped.

Writes ``--out`` and ``<run>/eval/scaling.json`` (the run report shows it) as JSON: per point
the scenes, demos, training steps and seconds, success rate with its 95 % interval, failure
reasons; the planner's. And ``--plot`` (SVG): success vs training scenes on a log axis, 95 %
intervals as bars, the planner as a line.

Preparing a run (augmented variants count as scenes; seeds of held-out scenes differ)::

    python -m factory stage=generate run_dir=runs/scaling \\
        'generate.prompts=[a kitchen where the robot picks up a mug and puts it in the bowl]' \\
        generate.scenes_per_prompt=19
    python -m factory stage=demos run_dir=runs/scaling demos.episodes_per_scene=20 ...
    python -m factory stage=dataset run_dir=runs/scaling

then (holding out the last three scenes by listing them; default: the run's scenes that are not
in the dataset)::

    python scripts/scaling_policy.py --run-dir runs/scaling --points 1 2 4 8 16 \\
        --heldout s17 s18 s19 --steps 5000 --episodes 30 --parallel 4
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

log = logging.getLogger("scaling")
REPO = Path(__file__).resolve().parents[1]


def factory(args: list[str], log_path: Path, env: dict[str, str]) -> None:
    """``python -m factory <args>``; its output goes to ``log_path``.

    Raises:
        RuntimeError: the command failed (the log's last lines in the message).
    """
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with log_path.open("a") as f:
        f.write(f"\n$ python -m factory {' '.join(args)}\n")
        f.flush()
        done = subprocess.run(
            [sys.executable, "-m", "factory", *args], stdout=f, stderr=f, env=env, cwd=REPO
        )
    if done.returncode != 0:
        tail = "".join(log_path.read_text().splitlines(keepends=True)[-15:])
        raise RuntimeError(f"python -m factory {' '.join(args)} failed:\n{tail}")


def hydra_list(items: list[str]) -> str:
    return "[" + ",".join(items) + "]"


def dataset_scenes(run: Path) -> tuple[list[str], dict[str, int]]:
    """The merged dataset's scene ids (sorted) and episodes per scene."""
    meta = json.loads((run / "dataset" / "merged" / "meta" / "factory.json").read_text())
    per: dict[str, int] = {}
    for e in meta["episodes"]:
        per[e["scene_id"]] = per.get(e["scene_id"], 0) + 1
    return sorted(meta["scenes"]), per


def read_results(run: Path, name: str) -> dict[str, Any]:
    return json.loads((run / "eval" / name / "results.json").read_text())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run-dir", required=True, type=Path)
    p.add_argument("--points", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    p.add_argument("--heldout", nargs="*", default=None, help="held-out scene ids")
    p.add_argument("--policy", default="diffusion")
    p.add_argument("--inputs", default="state", choices=["state", "rgb", "rgbd"])
    p.add_argument("--steps", type=int, default=5000)
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--device", default="auto")
    p.add_argument("--episodes", type=int, default=30, help="configurations per held-out scene")
    p.add_argument("--parallel", type=int, default=1, help="points trained/evaluated at once")
    p.add_argument("--threads", type=int, default=0, help="CPU threads per job (0: cores/jobs)")
    p.add_argument("--train-arg", action="append", default=[], help="extra train.* override")
    p.add_argument("--eval-arg", action="append", default=[], help="extra eval.* override")
    p.add_argument("--no-planner", action="store_true", help="skip the planner's reference")
    p.add_argument("--tag", default="run")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--plot", type=Path, default=None)
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")

    run = a.run_dir.resolve()
    out = a.out or REPO / "benchmarks" / "results" / f"scaling-{a.tag}.json"
    plot = a.plot or out.with_suffix(".svg")
    scenes, per_scene = dataset_scenes(run)
    run_scenes = sorted(p.name for p in (run / "scenes").iterdir() if p.is_dir())
    heldout = a.heldout if a.heldout else [s for s in run_scenes if s not in scenes]
    train_pool = [s for s in scenes if s not in heldout]
    if not heldout:
        sys.exit("no held-out scenes: list them with --heldout or add scenes without demos")
    if len(train_pool) < len(scenes):
        # held-out scenes with demos in the dataset: train.scenes takes ids, not a count
        log.info("held-out scenes %s are in the dataset; they are never trained on", heldout)
    points = sorted({n for n in a.points if 1 <= n <= len(train_pool)})
    if not points:
        sys.exit(f"no point of {a.points} fits the dataset's {len(train_pool)} training scenes")
    cores = os.cpu_count() or 1
    threads = a.threads or max(1, cores // max(1, a.parallel))
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    logs = run / "logs" / "scaling"
    log.info(
        "scaling: points %s of %d training scenes, held out %s x %d configurations, %s/%s, "
        "%d steps, %d job(s) at once, %d thread(s) each",
        points,
        len(train_pool),
        heldout,
        a.episodes,
        a.policy,
        a.inputs,
        a.steps,
        a.parallel,
        threads,
    )
    common_eval = [
        f"eval.scenes={hydra_list(heldout)}",
        f"eval.episodes_per_scene={a.episodes}",
        f"eval.nthread={threads}",
        f"eval.device={a.device}",
        *a.eval_arg,
    ]

    def one_point(n: int) -> dict[str, Any]:
        name = f"scale_{a.policy}_{a.inputs}_{n:03d}"
        chosen = train_pool[:n]
        t0 = time.perf_counter()
        factory(
            [
                "stage=train",
                f"run_dir={run}",
                f"train.name={name}",
                f"train.policy={a.policy}",
                f"train.inputs={a.inputs}",
                f"train.scenes={hydra_list(chosen)}",
                f"train.steps={a.steps}",
                f"train.batch_size={a.batch_size}",
                f"train.device={a.device}",
                f"train.threads={threads}",
                *a.train_arg,
            ],
            logs / f"{name}.log",
            env,
        )
        t_train = time.perf_counter() - t0
        factory(
            ["stage=eval", f"run_dir={run}", f"eval.policy={name}", "eval.videos=1", *common_eval],
            logs / f"{name}.log",
            env,
        )
        res = read_results(run, name)
        train_json = json.loads((run / "policy" / name / "train.json").read_text())
        log.info(
            "scaling: %d scene(s), %d demos: success %.3f (%d/%d)",
            n,
            train_json["episodes"],
            res["success_rate"],
            res["successes"],
            res["episodes"],
        )
        return {
            "scenes": n,
            "scene_ids": chosen,
            "demos": int(train_json["episodes"]),
            "frames": int(train_json["frames"]),
            "policy": name,
            "steps": int(train_json["steps"]),
            "train_seconds_this_call": round(t_train, 1),
            "success_rate": res["success_rate"],
            "ci95": res["ci95"],
            "successes": res["successes"],
            "episodes": res["episodes"],
            "failures": res["failures"],
            "per_scene": res["per_scene"],
            "scenes_skipped": res.get("scenes_skipped", {}),
        }

    t_all = time.perf_counter()
    with ThreadPoolExecutor(max(1, a.parallel)) as pool:
        planner_job = None
        if not a.no_planner:
            planner_job = pool.submit(
                factory,
                ["stage=eval", f"run_dir={run}", "eval.policy=planner", *common_eval],
                logs / "planner.log",
                env,
            )
        futures = [pool.submit(one_point, n) for n in points]
        rows, failed = [], []
        for n, fut in zip(points, futures, strict=True):
            try:
                rows.append(fut.result())
            except RuntimeError as e:  # one point failing keeps the others
                log.error("scaling: point %d failed: %s", n, e)
                failed.append({"scenes": n, "error": str(e)[-2000:]})
        planner = None
        if planner_job is not None:
            try:
                planner_job.result()
                res = read_results(run, "planner")
                planner = {k: res[k] for k in ("success_rate", "ci95", "successes", "episodes")}
                planner["failures"] = res["failures"]
                planner["scenes_skipped"] = res.get("scenes_skipped", {})
            except RuntimeError as e:
                log.error("scaling: the planner's evaluation failed: %s", e)
    result = {
        "schema_version": 1,
        "benchmark": "scaling-policy",
        "tag": a.tag,
        "machine": {
            "host": platform.node(),
            "python": platform.python_version(),
            "cpus": cores,
            "gpu": _gpu_name(),
        },
        "run_dir": str(run),
        "policy": a.policy,
        "inputs": a.inputs,
        "steps": a.steps,
        "batch_size": a.batch_size,
        "train_args": a.train_arg,
        "heldout": heldout,
        "episodes_per_heldout_scene": a.episodes,
        "demos_per_scene": {s: per_scene.get(s, 0) for s in train_pool},
        "points": rows,
        "failed_points": failed,
        "planner": planner,
        "seconds": round(time.perf_counter() - t_all, 1),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    plot.write_text(scaling_svg(result))
    # the run report's Scaling section reads eval/scaling.json ("rows")
    (run / "eval" / "scaling.json").write_text(json.dumps({**result, "rows": rows}, indent=2))
    for r in rows:
        print(
            f"{r['scenes']:>4} scenes {r['demos']:>5} demos  "
            f"success {100 * r['success_rate']:5.1f} % "
            f"[{100 * r['ci95'][0]:.1f}, {100 * r['ci95'][1]:.1f}]"
        )
    if planner:
        print(f"planner          success {100 * planner['success_rate']:5.1f} %")
    print(f"wrote {out} and {plot}")


def _gpu_name() -> str:
    try:
        done = subprocess.run(
            ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return done.stdout.strip().splitlines()[0] if done.returncode == 0 else ""
    except (OSError, IndexError, subprocess.TimeoutExpired):
        return ""


def scaling_svg(result: dict[str, Any]) -> str:
    """The scaling plot: success (%) vs training scenes (log axis) with 95 % intervals."""
    from factory.report.charts import Series, line_chart, standalone_svg

    rows = result["points"]
    xs = [float(r["scenes"]) for r in rows]
    series = [
        Series(
            f"{result['policy']} ({result['inputs']})",
            xs,
            [100 * r["success_rate"] for r in rows],
            [100 * r["ci95"][0] for r in rows],
            [100 * r["ci95"][1] for r in rows],
        )
    ]
    planner = result.get("planner")
    if planner and xs:
        series.append(
            Series(
                "planner (privileged)",
                [min(xs), max(xs)],
                [100 * planner["success_rate"]] * 2,
            )
        )
    demos = ", ".join(f"{r['scenes']}: {r['demos']}" for r in rows)
    n_held = len(result["heldout"])
    svg = line_chart(
        series,
        title=f"success in {n_held} held-out scenes vs training scenes (demos {demos})",
        x_label=f"training scenes (demos: {demos})",
        y_label=f"success in {n_held} held-out scenes (%)",
        log_x=True,
        y_range=(0.0, 100.0),
        markers=True,
        width=640,
        height=300,
    )
    return standalone_svg(svg) if svg else ""


if __name__ == "__main__":
    main()
