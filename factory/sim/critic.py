"""The physics critic the scene agent calls: first good candidate, or a structured failure.

Given a scene, the object being placed (already in the scene, at any pose) and ``n`` candidate
poses for it, the candidates are simulated as one batch (or in chunks, in order, stopping at
the first chunk with a good one); the critic returns the first candidate (in the given order)
that is valid, collision-free and stable (or accepted after resettling), with its settled
pose. If none is, it says which object fell, how far, why, and what to try next.

``scope="scene"`` simulates the whole scene for every candidate; ``scope="local"`` only what
the candidates can touch (:mod:`factory.sim.local_critic`), so that its cost does not grow
with the scene.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from factory.errors import ConfigError
from factory.schema import Scene
from factory.sim.backend import Backend
from factory.sim.compile import compile_scene
from factory.sim.local_critic import local_scene, neighbourhood
from factory.sim.stability import (
    FreeBodies,
    StabilityProtocol,
    StabilityResult,
    candidates_from_poses,
    check_stability,
)

SCOPES: tuple[str, ...] = ("scene", "local")
"""What a placement check simulates: the whole scene, or what the candidates can touch."""

LOCAL_MARGIN = 0.05
"""The local scope's reach beyond the protocol's largest stable translation (m)."""


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


@dataclass
class _Judge:
    """A compiled model for one object's candidates and how to read its verdicts."""

    model: mujoco.MjModel
    q0: np.ndarray
    adr: int
    poses: np.ndarray
    object_id: str
    protocol: StabilityProtocol
    extra: dict[str, Any]

    @classmethod
    def build(
        cls,
        scene: Scene,
        object_id: str,
        candidates: Any,
        assets_root: str | Path | None,
        protocol: StabilityProtocol | None,
        scope: str,
    ) -> _Judge:
        poses = poses_from_xyz_yaw(candidates)
        if len(poses) == 0:
            raise ConfigError("no candidates to judge: pass at least one pose")
        if scope not in SCOPES:
            raise ConfigError(f"critic scope {scope!r} must be one of {', '.join(SCOPES)}")
        protocol = protocol or StabilityProtocol()
        extra: dict[str, Any] = {}
        if scope == "local":
            hood = neighbourhood(
                scene,
                object_id,
                poses,
                reach=protocol.max_translation + LOCAL_MARGIN,
                turn_deg=protocol.max_rotation_deg,
            )
            scene = local_scene(scene, hood)
            extra["simulated"] = hood.as_dict()
        model = compile_scene(scene, assets_root).model
        q0 = candidates_from_poses(model, {object_id: poses})
        free = FreeBodies.of(model)
        adr = int(free.qposadr[free.index(object_id)])
        return cls(model, q0, adr, poses, object_id, protocol, extra)

    def run(self, start: int, stop: int, backend: str | Backend) -> list[dict[str, Any]]:
        """The verdicts of candidates ``start..stop-1``, simulated as one batch."""
        result = check_stability(
            self.model, self.q0[start:stop], backend=backend, protocol=self.protocol
        )
        return [self._verdict(result, k, start + k) for k in range(stop - start)]

    def _verdict(self, result: StabilityResult, k: int, i: int) -> dict[str, Any]:
        """Candidate ``i`` (row ``k`` of ``result``): accepted with its settled pose, or why
        not."""
        if result.accepted[k] and result.penetration[k].max() <= self.protocol.penetration_tol:
            j = result.object_ids.index(self.object_id)
            settled = result.settled_qpos[k, self.adr : self.adr + 7]
            return {
                "ok": True,
                "candidate": i,
                "pose": [float(v) for v in self.poses[i]],
                "settled_pose": [float(v) for v in settled],
                "resettled": bool(result.resettled[k]),
                "translation_m": float(result.translation[k, j]),
                "rotation_deg": float(result.rotation_deg[k, j]),
            }
        if result.invalid[k]:
            kind = "interpenetrating" if "interpenetrating" in result.reasons[k] else "invalid"
            pair = result.reasons[k].split(": ", 1)[-1].split(" by ")[0]
            other = next((p for p in pair.split("|") if p != self.object_id), self.object_id)
            return {
                "ok": False,
                "candidate": i,
                "kind": kind,
                "object": other,
                "reason": result.reasons[k],
            }
        moved = result.translation[k] + 1e-3 * result.rotation_deg[k]
        j = int(np.argmax(moved))
        name = result.object_ids[j]
        t, r = float(result.translation[k, j]), float(result.rotation_deg[k, j])
        return {
            "ok": False,
            "candidate": i,
            "kind": "tipped" if t <= self.protocol.max_translation else "fell",
            "object": name,
            "translation_m": round(t, 4),
            "rotation_deg": round(r, 2),
            "reason": f"{name} moved {t:.3f} m and turned {r:.1f} deg",
        }


def candidate_verdicts(
    scene: Scene,
    object_id: str,
    candidates: Any,
    *,
    assets_root: str | Path | None = None,
    backend: str | Backend = "cpu",
    protocol: StabilityProtocol | None = None,
    scope: str = "scene",
) -> list[dict[str, Any]]:
    """Every candidate's verdict, as :func:`physics_critic` reads it (arguments as there).

    Returns:
        one dict per candidate, in order: ``{"ok": True, "candidate", "pose",
        "settled_pose", "resettled", "translation_m", "rotation_deg"}`` or ``{"ok": False,
        "candidate", "kind" (interpenetrating | invalid | tipped | fell), "object", "reason",
        ...}``.
    """
    judge = _Judge.build(scene, object_id, candidates, assets_root, protocol, scope)
    return judge.run(0, len(judge.poses), backend)


def physics_critic(
    scene: Scene,
    object_id: str,
    candidates: Any,
    *,
    assets_root: str | Path | None = None,
    backend: str | Backend = "cpu",
    protocol: StabilityProtocol | None = None,
    scope: str = "scene",
    chunk: int | None = None,
) -> dict[str, Any]:
    """Judges candidate placements of one object.

    Args:
        scene: the scene, with the object present (its pose is replaced by each candidate).
        object_id: the object being placed (a free object of the scene).
        candidates: ``(n, 4)`` ``[x, y, z, yaw_deg]`` or ``(n, 7)`` poses, world frame.
        assets_root: the run's ``assets/`` folder.
        backend: physics backend.
        protocol: stability thresholds.
        scope: ``scene`` simulates the whole scene per candidate; ``local`` only what the
            candidates can touch (:mod:`factory.sim.local_critic`: the object, its support
            chain and the groups of objects resting against them or within reach, nearby
            objects as static obstacles, the rest absent), with the same verdicts on a scene
            that is at rest without the object.
        chunk: simulate the candidates this many at a time, in order, and stop after the first
            chunk with an accepted one (default: all at once). The verdict is the same; a
            chunk of the backend's thread count saves the later candidates' time.

    Returns:
        ``{"ok": True, "candidate": i, "pose": {...}, "settled_pose": {...}, ...}`` for the
        first accepted candidate, else ``{"ok": False, "failures": [...], "summary": ...,
        "suggestion": ...}``; JSON-ready either way. With ``scope="local"`` both carry
        ``"simulated": {"dynamic", "static", "of"}`` (object counts).

    Raises:
        ConfigError: no candidates, a bad shape, an unknown scope or a static object.
    """
    judge = _Judge.build(scene, object_id, candidates, assets_root, protocol, scope)
    n = len(judge.poses)
    step = max(1, chunk or n)
    failures: list[dict[str, Any]] = []
    for start in range(0, n, step):
        for verdict in judge.run(start, min(n, start + step), backend):
            if verdict.pop("ok"):
                return {"ok": True, **verdict, "candidates": n, **judge.extra}
            failures.append(verdict)
    kind_obj: tuple[str, str] = Counter(
        (str(f["kind"]), str(f["object"])) for f in failures
    ).most_common(1)[0][0]
    return {
        "ok": False,
        "candidates": n,
        "failures": failures,
        "summary": f"{len(failures)} of {n} candidates failed; most often "
        f"{kind_obj[1]} {kind_obj[0]}",
        "suggestion": _remedy(kind_obj[0], kind_obj[1], object_id),
        "max_translation_m": judge.protocol.max_translation,
        "max_rotation_deg": judge.protocol.max_rotation_deg,
        **judge.extra,
    }
