"""``stage=validate``: physics metrics for every scene, and optional repair.

Per scene (sharded): compile, simulate the scene as it stands for the protocol's duration,
measure collisions (MuJoCo contacts and the trimesh ray test) and stability, and write
``scenes/<id>/report.json`` (key ``validate``). A summary table (#objects, collision %,
stability %, per scene and per room type) goes to stdout and ``validate/summary.json``.

With ``validate.repair=true``, unstable objects whose settled pose is stable are moved to it,
other unstable objects and the smaller of two colliding objects are removed (with whatever
stands on them), the scene is saved and recompiled, and every change is recorded in the
report. Task objects are never removed silently: removing one is logged as a warning.

Scene checks that live above this floor (the mobile task's route check,
``factory.nav.route``) come in as ``checks``: name -> :data:`SceneCheck`, run on the final
compiled model; their results go to the report (``validate.checks.<name>``), the rows and the
summary (``checks``: per name, passed and failed by reason). ``factory.scenes.validate_stage``
is the stage's entry point that passes them.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Mapping
from typing import Any

import mujoco
import numpy as np

from factory.context import StageContext, run_items
from factory.schema import Euler, Scene, Vec3, scene_to_json
from factory.sim.backend import get_backend, resolve_backend_name
from factory.sim.compile import CompileOptions, compile_scene, model_xml
from factory.sim.layout_batch import check_by_layout
from factory.sim.metrics import scene_metrics
from factory.sim.stability import FreeBodies, StabilityProtocol, StabilityResult, check_stability
from factory.store import RunStore, atomic_write_json, atomic_write_text, file_lock, sha256_bytes

log = logging.getLogger(__name__)

REPORT_SCHEMA_VERSION = 1

SceneCheck = Callable[[Scene, mujoco.MjModel], "dict[str, Any] | None"]
"""A scene check: ``check(scene, model)`` on the scene's compiled model returns a JSON-ready
dict whose ``reason`` is ``""`` when the scene passes, or None when it does not apply."""


def protocol_of(sim: Any) -> StabilityProtocol:
    """The stability protocol from the ``sim`` config; initial interpenetration is measured
    as a collision here, not treated as an invalid candidate."""
    return StabilityProtocol(
        duration=sim.duration,
        max_translation=sim.max_translation,
        max_rotation_deg=sim.max_rotation_deg,
        penetration_tol=math.inf,
        resettle=sim.resettle,
        timestep=sim.timestep,
    )


def make_backend(sim: Any) -> Any:
    """The physics backend named by the ``sim`` config, with its options."""
    name = resolve_backend_name(sim.backend)
    options: dict[str, Any] = {}
    if name == "cpu":
        options = {"nthread": sim.nthread}
    elif name == "mjx":
        options = {"max_free_bodies": sim.mjx_max_free_bodies}
    elif name == "warp":
        options = {"sleep": sim.sleep}
    return get_backend(name, **options)


def _euler_of(quat_wxyz: np.ndarray) -> Euler:
    from scipy.spatial.transform import Rotation

    w, x, y, z = quat_wxyz
    ax, ay, az = Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True)
    return Euler(float(ax), float(ay), float(az))


def _remove(scene: Scene, oid: str, why: str, changes: list[dict[str, Any]]) -> None:
    """Removes ``oid`` and, recursively, whatever stands on it."""
    for obj in list(scene.objects):
        if obj.placement.kind == "on_top" and obj.placement.support_id == oid:
            _remove(scene, obj.id, f"its support {oid} was removed", changes)
    obj = scene.object(oid)
    if obj.task_role:
        log.warning("scene %s: removing task object %s (%s)", scene.id, oid, why)
    scene.objects = [o for o in scene.objects if o.id != oid]
    changes.append({"action": "remove", "object": oid, "reason": why})


def _repair_round(
    scene: Scene, model: mujoco.MjModel, result: StabilityResult, metrics: dict[str, Any]
) -> list[dict[str, Any]]:
    changes: list[dict[str, Any]] = []
    sizes = {o.id: math.prod(o.dimensions.as_tuple()) for o in scene.objects}
    removed: set[str] = set()
    for pair in metrics["collision"]["pairs"]:
        a, b = pair.split("|")
        if a in removed or b in removed or a not in sizes or b not in sizes:
            continue
        victim = min((a, b), key=lambda o: (sizes[o], o))
        other = b if victim == a else a
        depth = metrics["per_object"][victim]["penetration_m"]
        _remove(scene, victim, f"interpenetrates {other} by {depth * 100:.1f} cm", changes)
        removed.update(c["object"] for c in changes)
    if changes:
        return changes  # re-simulate before judging stability
    unstable = metrics["stability"]["unstable"]
    if not unstable:
        return changes
    if result.accepted[0]:
        free = FreeBodies.of(model)
        settled = result.settled_qpos[0]
        for j, oid in enumerate(free.names):
            adr = free.qposadr[j]
            obj = scene.object(oid)
            pos = settled[adr : adr + 3]
            moved = float(np.linalg.norm(pos - np.array(obj.position.as_tuple())))
            if moved < 1e-3:
                continue
            obj.position = Vec3(*(float(v) for v in pos))
            obj.rotation = _euler_of(settled[adr + 3 : adr + 7])
            changes.append({"action": "settle", "object": oid, "moved_m": round(moved, 4)})
        return changes
    for oid in unstable:
        if any(o.id == oid for o in scene.objects):
            e = metrics["per_object"][oid]
            _remove(
                scene,
                oid,
                f"unstable: moved {e.get('translation_m', 0):.3f} m, "
                f"turned {e.get('rotation_deg', 0):.1f} deg",
                changes,
            )
    return changes


def validate_scene(
    scene: Scene,
    assets_root: Any,
    cfg: Any,
    backend: Any,
    first: StabilityResult | None = None,
    checks: Mapping[str, SceneCheck] | None = None,
) -> tuple[Scene, dict[str, Any]]:
    """Validates (and with ``cfg.validate.repair`` repairs) one scene.

    Args:
        scene: the scene.
        assets_root: where its assets are.
        cfg: the run config.
        backend: a physics backend instance.
        first: the scene's stability result as it is, when already checked in a batch of
            its layout (:func:`~factory.sim.layout_batch.check_by_layout`).
        checks: scene checks run on the (repaired) scene's model; their results go to the
            report's ``checks``.

    Returns:
        the (possibly repaired) scene and its report dict.
    """
    protocol = protocol_of(cfg.sim)
    options = CompileOptions(**vars(cfg.compile))
    history: list[dict[str, Any]] = []
    rounds = cfg.validate.max_repair_rounds if cfg.validate.repair else 0
    for r in range(rounds + 1):
        model = compile_scene(scene, assets_root, options).model
        if r == 0 and first is not None:
            result = first
        else:
            result = check_stability(model, backend=backend, protocol=protocol)
        metrics = scene_metrics(
            scene, model, result, cfg.validate.collision_tol, cfg.validate.trimesh
        )
        if r == rounds:
            break
        changes = _repair_round(scene, model, result, metrics)
        if not changes:
            break
        history.append({"round": r, "changes": changes})
    results: dict[str, Any] = {}
    for name, check in (checks or {}).items():
        out = check(scene, model)
        if out is not None:
            results[name] = out
            if out.get("reason"):
                log.info(
                    "scene %s: %s check: %s", scene.id, name, out.get("detail") or out["reason"]
                )
    report = {
        "schema_version": REPORT_SCHEMA_VERSION,
        "scene_id": scene.id,
        "backend": result.backend,
        "protocol": vars(protocol) | {"penetration_tol": None},
        "metrics": metrics,
        "repair": history,
        "checks": results,
        "sim_seconds": result.seconds,
    }
    return scene, report


def _row(scene_id: str, m: dict[str, Any], checks: dict[str, Any] | None = None) -> dict[str, Any]:
    tri = m.get("collision_trimesh") or {}
    return {
        "checks": {name: str(c.get("reason", "")) for name, c in (checks or {}).items()},
        "scene": scene_id,
        "objects": m["objects"],
        "collision_pct": 100 * m["collision"]["ratio"],
        "collision_trimesh_pct": 100 * tri["ratio"] if tri else None,
        "stability_pct": 100 * m["stability"]["ratio"],
        "per_room_type": m["per_room_type"],
    }


def _aggregate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    n_obj = sum(r["objects"] for r in rows)
    rooms: dict[str, dict[str, int]] = {}
    for r in rows:
        for rt, c in r["per_room_type"].items():
            acc = rooms.setdefault(rt, {"objects": 0, "colliding": 0, "stable": 0})
            for k in acc:
                acc[k] += c[k]

    def pct(num: float, den: float) -> float:
        return 100.0 * num / den if den else 0.0

    passed: dict[str, int] = {}
    failed: dict[str, dict[str, int]] = {}
    for r in rows:
        for name, reason in r.get("checks", {}).items():
            passed.setdefault(name, 0)
            fails = failed.setdefault(name, {})
            if reason:
                fails[reason] = fails.get(reason, 0) + 1
            else:
                passed[name] += 1
    checks = {name: {"passed": passed[name], "failed": failed[name]} for name in sorted(passed)}
    return {
        "scenes": len(rows),
        "checks": checks,
        "objects": n_obj,
        "objects_per_scene": n_obj / len(rows) if rows else 0.0,
        "collision_pct": pct(sum(r["collision_pct"] * r["objects"] for r in rows) / 100, n_obj),
        "stability_pct": pct(sum(r["stability_pct"] * r["objects"] for r in rows) / 100, n_obj),
        "per_room_type": {
            rt: {
                "objects": c["objects"],
                "collision_pct": pct(c["colliding"], c["objects"]),
                "stability_pct": pct(c["stable"], c["objects"]),
            }
            for rt, c in sorted(rooms.items())
        },
    }


def format_table(rows: list[dict[str, Any]], total: dict[str, Any]) -> str:
    """The summary as a fixed-width text table."""
    w = max([len("scene"), *(len(r["scene"]) for r in rows)])
    lines = [f"{'scene':<{w}}  #objects  collision %  trimesh %  stability %"]
    for r in rows:
        tri = "-" if r["collision_trimesh_pct"] is None else f"{r['collision_trimesh_pct']:.1f}"
        lines.append(
            f"{r['scene']:<{w}}  {r['objects']:>8}  {r['collision_pct']:>11.1f}  {tri:>9}  "
            f"{r['stability_pct']:>11.1f}"
        )
    lines.append(
        f"{'ALL':<{w}}  {total['objects']:>8}  {total['collision_pct']:>11.1f}  {'':>9}  "
        f"{total['stability_pct']:>11.1f}"
    )
    for rt, c in total["per_room_type"].items():
        lines.append(
            f"{'  ' + rt:<{w}}  {c['objects']:>8}  {c['collision_pct']:>11.1f}  {'':>9}  "
            f"{c['stability_pct']:>11.1f}"
        )
    for name, c in total.get("checks", {}).items():
        failed = ", ".join(f"{k} {v}" for k, v in sorted(c["failed"].items()))
        lines.append(
            f"{name} check: {c['passed']} passed" + (f", failed: {failed}" if failed else "")
        )
        for r in rows:
            if r.get("checks", {}).get(name):
                lines.append(f"  {r['scene']}: {r['checks'][name]}")
    return "\n".join(lines)


def run(ctx: StageContext, checks: Mapping[str, SceneCheck] | None = None) -> dict[str, Any]:
    """Stage entry point: every scene of the shard; ``checks`` are the scene checks of the
    floors above (see the module's description)."""
    store: RunStore = ctx.require_store()
    cfg = ctx.cfg
    ids = store.scene_ids()
    if not ids:
        from factory.errors import StoreError

        raise StoreError(f"no scenes in {store.scenes_dir}: run stage=ingest first")
    mine = ctx.shard.select(ids)
    backend = make_backend(cfg.sim)
    rows: list[dict[str, Any]] = []
    settings = json.dumps(
        {
            "sim": vars(cfg.sim),
            "validate": vars(cfg.validate),
            "compile": vars(cfg.compile),
            "checks": sorted(checks or {}),
        },
        sort_keys=True,
    ).encode()

    def digest_of(scene_id: str) -> str:
        return sha256_bytes(store.scene_json(scene_id).read_bytes() + b"\0" + settings)

    def pending(scene_id: str) -> bool:
        return cfg.force or not store.is_done(
            store.scene_dir(scene_id), "validate", digest_of(scene_id)
        )

    checked: dict[str, StabilityResult] = {}
    order = list(mine)

    def prefetch(scene_id: str) -> None:
        """Checks the next ``validate.batch_scenes`` pending scenes, layouts batched."""
        at = order.index(scene_id)
        todo = [s for s in order[at:] if pending(s)][: max(1, cfg.validate.batch_scenes)]
        options = CompileOptions(**vars(cfg.compile))
        models = {
            s: compile_scene(store.load_scene(s), store.assets_dir, options).model for s in todo
        }
        checked.clear()
        checked.update(check_by_layout(models, backend, protocol_of(cfg.sim)))

    def one(scene_id: str) -> str:
        scene_dir = store.scene_dir(scene_id)
        digest = digest_of(scene_id)
        report_path = store.report_json(scene_id)
        if not cfg.force and store.is_done(scene_dir, "validate", digest):
            done = json.loads(report_path.read_text())["validate"]
            rows.append(_row(scene_id, done["metrics"], done.get("checks")))
            return "skipped"
        if cfg.validate.batch_scenes > 1 and scene_id not in checked:
            prefetch(scene_id)
        scene = store.load_scene(scene_id)
        repaired, report = validate_scene(
            scene, store.assets_dir, cfg, backend, first=checked.pop(scene_id, None), checks=checks
        )
        if report["repair"]:
            text = scene_to_json(repaired)
            store.save_scene(repaired)
            compiled = compile_scene(
                repaired, store.assets_dir, CompileOptions(**vars(cfg.compile))
            )
            atomic_write_text(store.model_xml(scene_id), model_xml(compiled, scene_dir))
            digest = sha256_bytes(text.encode() + b"\0" + settings)
            n = sum(len(h["changes"]) for h in report["repair"])
            log.info("scene %s repaired: %d change(s)", scene_id, n)
        existing: dict[str, Any] = {}
        if report_path.is_file():
            try:
                existing = json.loads(report_path.read_text())
            except json.JSONDecodeError:
                existing = {}
        existing.update(schema_version=REPORT_SCHEMA_VERSION, validate=report)
        atomic_write_json(report_path, existing)
        store.mark_done(scene_dir, "validate", digest, ["report.json"])
        rows.append(_row(scene_id, report["metrics"], report["checks"]))
        return "done"

    counts = run_items("validate", mine, one)
    rows.sort(key=lambda r: r["scene"])
    out_dir = store.root / "validate"
    atomic_write_json(
        out_dir / f"summary-{ctx.shard.name}.json", {"schema_version": 1, "scenes": rows}
    )
    with file_lock(store.root / ".validate.lock"):
        all_rows: list[dict[str, Any]] = []
        for p in sorted(out_dir.glob("summary-*.json")):
            all_rows.extend(json.loads(p.read_text())["scenes"])
        all_rows.sort(key=lambda r: r["scene"])
        total = _aggregate(all_rows)
        atomic_write_json(
            out_dir / "summary.json", {"schema_version": 1, "total": total, "scenes": all_rows}
        )
    print(format_table(rows, _aggregate(rows)))
    return {**counts, **{k: v for k, v in _aggregate(rows).items() if k != "per_room_type"}}


__all__ = ["SceneCheck", "format_table", "protocol_of", "run", "validate_scene"]
