"""The last step of ``stage=generate``: the whole scene checked as ``stage=validate`` checks it,
repaired, and judged by its task.

1. **Strict check with repair** (the paper's last pass): the scene is compiled and simulated
   under the validation protocol (:func:`factory.sim.validate.validate_scene`, the ``sim.*``
   and ``validate.*`` settings, repair on): the smaller of two interpenetrating objects is
   removed, unstable objects are moved to their settled pose when it is stable, or removed
   (with what stands on them), for up to ``validate.max_repair_rounds`` rounds; then an object
   that stands more than ``validate.collision_tol`` into a wall, floor or ceiling at rest is
   removed too (``stage=validate`` counts pairs of objects; a plain contact check counts the
   building as well). What
   ``stage=validate`` then measures is what this step measured last: 0 % colliding and 100 %
   stable unless the rounds ran out (logged as a warning).
2. **Task feasibility** (a scene made for a task): the task's own critic
   (:meth:`factory.tasks.base.Task.feasibility`, e.g. the fixed pick-and-place: a free base
   spot, and the episodes' sampler placing the task objects within reach for enough seeds).

:func:`finish_scene` returns the finished scene and what happened (``report.json``'s
``generate.final_check`` and ``generate.task_check``); the stage makes another attempt with
another seed when the task check fails (``generate.task_attempts``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from factory.schema import Scene

log = logging.getLogger(__name__)

__all__ = ["attempt_seed", "finish_scene", "task_check"]

SEED_STRIDE = 7919
"""Attempt ``a`` (0 first) of a scene generates with seed ``seed + a * SEED_STRIDE``."""


def attempt_seed(seed: int, attempt: int) -> int:
    """The seed of attempt ``attempt`` (0: the scene's own seed)."""
    return seed + attempt * SEED_STRIDE


def strict_check(scene: Scene, assets_root: Path, cfg: Any) -> tuple[Scene, dict[str, Any]]:
    """Simulates ``scene`` under the validation protocol and repairs it (step 1).

    Args:
        scene: the generated scene (changed in place by the repairs).
        assets_root: the run's assets folder.
        cfg: the run config (``sim``, ``compile``, ``validate``; ``validate.repair`` is
            turned on and ``validate.trimesh`` off here whatever they say).

    Returns:
        the scene and ``{"rounds", "changes", "objects", "collision_ratio",
        "stability_ratio", "seconds"}`` (``changes``: each removal or settling with its
        reason).
    """
    from factory.sim.validate import make_backend, validate_scene

    t0 = time.perf_counter()
    # repair on; the trimesh ray test off: repairs follow MuJoCo's contacts, and the ray test
    # (the paper's second collision measure, reported by stage=validate) only costs time here
    run_cfg = replace(cfg, validate=replace(cfg.validate, repair=True, trimesh=False))
    scene, report = validate_scene(scene, assets_root, run_cfg, make_backend(cfg.sim))
    metrics = report["metrics"]
    changes = [c for r in report["repair"] for c in r["changes"]]
    into_walls = _into_structure(scene, assets_root, cfg.validate.collision_tol)
    if into_walls:  # stage=validate counts object pairs; a plain contact check counts walls too
        gone = scene.with_dependents(set(into_walls))
        scene.objects = [o for o in scene.objects if o.id not in gone]
        changes += [
            {"action": "remove", "object": oid, "reason": into_walls.get(oid, "its support went")}
            for oid in sorted(gone)
        ]
    out = {
        "rounds": len(report["repair"]),
        "changes": changes,
        "objects": len(scene.objects),
        "collision_ratio": metrics["collision"]["ratio"],
        "stability_ratio": metrics["stability"]["ratio"],
        "seconds": round(time.perf_counter() - t0, 2),
    }
    if changes:
        log.info(
            "scene %s: final check: %d change(s) (%s)",
            scene.id,
            len(changes),
            ", ".join(f"{c['action']} {c['object']}" for c in changes[:6]),
        )
    if out["collision_ratio"] > 0 or out["stability_ratio"] < 1:
        log.warning(
            "scene %s: still %.1f %% colliding, %.1f %% stable after %d repair rounds",
            scene.id,
            100 * out["collision_ratio"],
            100 * out["stability_ratio"],
            out["rounds"],
        )
    return scene, out


def _into_structure(scene: Scene, assets_root: Path, tol: float) -> dict[str, str]:
    """Objects that stand more than ``tol`` (m) into a wall, floor or ceiling at rest (the
    compiled scene's contacts at its initial state), with why: object id -> reason."""
    import mujoco

    from factory.sim.compile import compile_scene

    model = compile_scene(scene, assets_root).model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ids = {o.id for o in scene.objects}
    root = model.body_rootid
    out: dict[str, str] = {}
    for c in data.contact[: data.ncon]:
        if c.dist >= -tol:
            continue
        a, b = (model.body(int(root[model.geom_bodyid[g]])).name for g in (c.geom1, c.geom2))
        if (a in ids) != (b in ids):  # one object, one piece of the building
            oid, wall = (a, model.geom(c.geom2).name) if a in ids else (b, model.geom(c.geom1).name)
            out.setdefault(oid, f"{-c.dist * 100:.1f} cm into {wall}")
    return out


def task_check(scene: Scene, assets_root: Path | None) -> dict[str, Any] | None:
    """The scene's task's feasibility critic (step 2): None for a scene made for no task or
    a task without a critic; else a dict whose ``reason`` is ``""`` when the scene can host
    the task."""
    if scene.task is None:
        return None
    from factory.tasks import task_for_scene

    return task_for_scene(scene).feasibility(scene, assets_root)


def finish_scene(
    scene: Scene, assets_root: Path, cfg: Any, final_check: bool = True
) -> tuple[Scene, dict[str, Any]]:
    """Steps 1 and 2 on a generated scene.

    Returns:
        the finished scene and ``{"final_check": ..., "task_check": ...}`` (a key is absent
        where its step did not run).
    """
    out: dict[str, Any] = {}
    if final_check:
        scene, out["final_check"] = strict_check(scene, assets_root, cfg)
    check = task_check(scene, assets_root)
    if check is not None:
        out["task_check"] = check
    return scene, out
