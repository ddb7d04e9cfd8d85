"""Benchmark of the policies' tool-action tracker: mink's per-arm QP tracker
(``factory.robots.ik.IKSolver.track``, what ``ToolActionTracker`` ran before) against the batched
one (``factory.robots.ik_batch.BatchTracker``), on the same tool paths.

Each of ``--worlds`` arms starts near the home posture and follows targets that drift 4 mm and
0.5 deg a frame with 1 mm of noise (a policy's predicted tool path), ``--frames`` frames, each
frame started from the previous command; then the same arms towards targets a metre out of
reach (every step spent). Reports milliseconds per frame for the batch and per arm, and the
largest joint difference between the two trackers on the reachable path.

    python scripts/bench_tool_tracker.py --worlds 8 90 --frames 40 --tag cpu2

Prints and saves JSON to ``benchmarks/results/tool-tracker-<tag>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from factory.cores import usable_cores  # noqa: E402
from factory.robots.ik import IKConfig, IKSolver  # noqa: E402
from factory.robots.ik_batch import BatchTracker  # noqa: E402
from factory.robots.panda import HOME_QPOS  # noqa: E402
from factory.store import atomic_write_json, git_sha  # noqa: E402

CFG = IKConfig(max_iters=20, pos_tol=5e-4, rot_tol_deg=0.5)  # ToolActionTracker's


def paths(n: int, frames: int, far: bool) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """Start joints (n, 7) and per frame the targets' positions (n, 3) and rotations (n, 3, 3)."""
    rng = np.random.default_rng(n)
    q0 = np.asarray(HOME_QPOS, float) + rng.normal(0, 0.2, (n, 7))
    pos0, rot0, _ = BatchTracker(CFG).kinematics(q0)
    dirs = rng.normal(0, 1, (n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    axes = rng.normal(0, 1, (n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    offset = np.array([1.0, 0.0, 0.0]) if far else np.zeros(3)
    pos = [
        pos0 + offset + dirs * 0.004 * (f + 1) + rng.normal(0, 0.001, (n, 3)) for f in range(frames)
    ]
    rot = [
        Rotation.from_rotvec(axes * np.radians(0.5) * (f + 1)).as_matrix() @ rot0
        for f in range(frames)
    ]
    return q0, pos, rot


def run(n: int, frames: int, far: bool) -> dict:
    q0, pos, rot = paths(n, frames, far)
    mink_ik, batch = IKSolver(CFG), BatchTracker(CFG)
    qm, qb = q0.copy(), q0.copy()
    t_mink = t_batch = 0.0
    worst = 0.0
    for p, r in zip(pos, rot, strict=True):
        t = time.perf_counter()
        for i in range(n):
            target = np.eye(4)
            target[:3, :3], target[:3, 3] = r[i], p[i]
            qm[i] = mink_ik.track(target, qm[i])
        t_mink += time.perf_counter() - t
        t = time.perf_counter()
        qb = batch.track(p, r, qb)
        t_batch += time.perf_counter() - t
        worst = max(worst, float(np.abs(qm - qb).max()))
    row = {
        "worlds": n,
        "frames": frames,
        "targets": "out of reach (1 m)" if far else "reachable path",
        "mink_ms_per_frame": round(1000 * t_mink / frames, 3),
        "batch_ms_per_frame": round(1000 * t_batch / frames, 3),
        "mink_ms_per_world": round(1000 * t_mink / frames / n, 4),
        "batch_ms_per_world": round(1000 * t_batch / frames / n, 4),
        "speedup": round(t_mink / max(t_batch, 1e-12), 2),
    }
    if not far:
        row["max_joint_difference_rad"] = worst
    return row


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--worlds", type=int, nargs="+", default=[8, 90])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--tag", default="cpu")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = []
    for n in args.worlds:
        for far in (False, True):
            rows.append(run(n, args.frames if not far else max(5, args.frames // 4), far))
            print(json.dumps(rows[-1]), flush=True)
    sha = (git_sha() or "")[:7]
    out = {
        "schema_version": 1,
        "benchmark": "tool-tracker",
        "date": datetime.date.today().isoformat(),
        "machine": {"cpu": platform.processor() or platform.machine(), "cores": usable_cores()},
        "git_sha": sha,
        "command": "python scripts/bench_tool_tracker.py " + " ".join(sys.argv[1:]),
        "ik": {
            "max_iters": CFG.max_iters,
            "pos_tol_m": CFG.pos_tol,
            "rot_tol_deg": CFG.rot_tol_deg,
        },
        "rows": rows,
    }
    path = args.out or ROOT / "benchmarks" / "results" / f"tool-tracker-{args.tag}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(path, out)
    print(f"saved {path}")


if __name__ == "__main__":
    main()
