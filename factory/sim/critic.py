"""The physics critic the scene agent calls: first good candidate, or a structured failure.

Given a scene, the object being placed (already in the scene, at any pose) and ``n`` candidate
poses for it, all candidates are simulated together as one batch; the critic returns the first
candidate (in the given order) that is valid, collision-free and stable (or accepted after
resettling), with its settled pose. If none is, it says which object fell, how far, why, and
what to try next.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import ConfigError
from factory.schema import Scene
from factory.sim.backend import Backend
from factory.sim.compile import compile_scene
from factory.sim.stability import (
    FreeBodies,
    StabilityProtocol,
    candidates_from_poses,
    check_stability,
)


def poses_from_xyz_yaw(poses: Any) -> np.ndarray:
    """``(n, 4)`` ``[x, y, z, yaw_deg]`` (bottom centre, world frame) or ``(n, 7)`` body poses
    ``[x, y, z, qw, qx, qy, qz]`` -> ``(n, 7)``."""
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    if p.shape[1] == 7:
        return p
    if p.shape[1] != 4:
        raise ConfigError("candidate poses must be (n, 4) [x, y, z, yaw_deg] or (n, 7)")
    half = np.radians(p[:, 3]) / 2
    z = np.zeros(len(p))
    return np.column_stack([p[:, :3], np.cos(half), z, z, np.sin(half)])


def _remedy(kind: str, obj: str, placed: str) -> str:
    if kind == "interpenetrating":
        return f"the candidate overlaps {obj}: sample positions farther from it"
    if kind == "invalid":
        return "the simulation was invalid: check the object's size and mass"
    if obj != placed:
        return f"placing {placed} here knocks {obj} over: keep clear of it"
    if kind == "tipped":
        return (
            f"{placed} tips over: use a smaller or lower object, a wider base, or a flatter support"
        )
    return f"{placed} falls off: choose another support or a position nearer its centre"


def physics_critic(
    scene: Scene,
    object_id: str,
    candidates: Any,
    *,
    assets_root: str | Path | None = None,
    backend: str | Backend = "cpu",
    protocol: StabilityProtocol | None = None,
) -> dict[str, Any]:
    """Judges candidate placements of one object.

    Args:
        scene: the scene, with the object present (its pose is replaced by each candidate).
        object_id: the object being placed (a free object of the scene).
        candidates: ``(n, 4)`` ``[x, y, z, yaw_deg]`` or ``(n, 7)`` poses, world frame.
        assets_root: the run's ``assets/`` folder.
        backend: physics backend.
        protocol: stability thresholds.

    Returns:
        ``{"ok": True, "candidate": i, "pose": {...}, "settled_pose": {...}, ...}`` for the
        first accepted candidate, else ``{"ok": False, "failures": [...], "summary": ...,
        "suggestion": ...}``; JSON-ready either way.
    """
    protocol = protocol or StabilityProtocol()
    poses = poses_from_xyz_yaw(candidates)
    if len(poses) == 0:
        raise ConfigError("no candidates to judge: pass at least one pose")
    model = compile_scene(scene, assets_root).model
    q0 = candidates_from_poses(model, {object_id: poses})
    result = check_stability(model, q0, backend=backend, protocol=protocol)
    j_obj = result.object_ids.index(object_id)
    free = FreeBodies.of(model)
    adr = free.qposadr[free.index(object_id)]
    for i in np.flatnonzero(result.accepted).tolist():
        if result.penetration[i].max() > protocol.penetration_tol:
            continue
        settled = result.settled_qpos[i, adr : adr + 7]
        return {
            "ok": True,
            "candidate": int(i),
            "candidates": len(poses),
            "pose": [float(v) for v in poses[i]],
            "settled_pose": [float(v) for v in settled],
            "resettled": bool(result.resettled[i]),
            "translation_m": float(result.translation[i, j_obj]),
            "rotation_deg": float(result.rotation_deg[i, j_obj]),
        }
    failures: list[dict[str, Any]] = []
    for i in range(len(poses)):
        if result.invalid[i]:
            kind = "interpenetrating" if "interpenetrating" in result.reasons[i] else "invalid"
            pair = result.reasons[i].split(": ", 1)[-1].split(" by ")[0]
            other = next((p for p in pair.split("|") if p != object_id), object_id)
            failures.append(
                {"candidate": i, "kind": kind, "object": other, "reason": result.reasons[i]}
            )
            continue
        moved = result.translation[i] + 1e-3 * result.rotation_deg[i]
        j = int(np.argmax(moved))
        name = result.object_ids[j]
        t, r = float(result.translation[i, j]), float(result.rotation_deg[i, j])
        kind = "tipped" if t <= protocol.max_translation else "fell"
        failures.append(
            {
                "candidate": i,
                "kind": kind,
                "object": name,
                "translation_m": round(t, 4),
                "rotation_deg": round(r, 2),
                "reason": f"{name} moved {t:.3f} m and turned {r:.1f} deg",
            }
        )
    kind_obj: tuple[str, str] = Counter(
        (str(f["kind"]), str(f["object"])) for f in failures
    ).most_common(1)[0][0]
    return {
        "ok": False,
        "candidates": len(poses),
        "failures": failures,
        "summary": f"{len(failures)} of {len(poses)} candidates failed; most often "
        f"{kind_obj[1]} {kind_obj[0]}",
        "suggestion": _remedy(kind_obj[0], kind_obj[1], object_id),
        "max_translation_m": protocol.max_translation,
        "max_rotation_deg": protocol.max_rotation_deg,
    }
