"""``stage=augment``: many task-consistent variants of every scene in the run.

Jobs are (parent scene, variant index); they are sharded over array tasks, and each variant's
seed is derived from (seed, parent, index), so the same run_dir, config and seed give the same
variants and a re-run after a kill finishes only what is missing. Levels compose in the order
layout, category, configuration. Every variant is checked with the strict physics protocol
(no interpenetration over 1 cm, every object stable), and a variant of a mobile-task scene
with the route check (:func:`check_route`); those that fail are dropped and counted per level
and reason (``L: physics``, ``L: no_route``, ...). A kept variant is a full scene directory
``<parent>__<levels>_<k>`` with ``source = augment:<parent>``, its parameters and seed in
``report.json``, its ``model.xml`` and renders.

Configuration alone (``augment.levels=[configuration]``) is batched per parent: the parents
are sharded (each shard makes all variants of its parents), one call of
:func:`factory.augment.levels.configurations` finds ``variants_per_scene`` distinct valid
configurations (seed from (seed, parent)), and one batched whole-scene check
(:func:`factory.augment.check.verify_whole_scene`, the same verdict as :func:`check_physics`)
confirms them all. Those variants move only task objects on their supports, not the floor's
furniture; for a mobile-task parent whose variants move the pick object (its reach changes)
they are route-checked too, as rows of the parent's model
(:func:`factory.augment.routes.configuration_routes`), and those that fail are dropped and
counted with the route check's reason (``P: no_pick_pose``, ``P: no_route``, ...).
"""

from __future__ import annotations

import hashlib
import logging
from collections import Counter
from typing import Any

from factory.assets import AssetLibrary
from factory.augment.check import PhysicsCheck, batch_sizes
from factory.augment.levels import (
    AugmentError,
    Variant,
    category,
    configuration,
    configurations,
    layout,
)
from factory.context import StageContext
from factory.errors import ConfigError, StoreError

log = logging.getLogger(__name__)

LEVELS: dict[str, Any] = {"layout": layout, "category": category, "configuration": configuration}
"""Level name -> function, in composition order."""

ABBREV = {"layout": "L", "category": "C", "configuration": "P"}


def variant_seed(seed: int, parent: str, index: int) -> int:
    """A stable seed per (run seed, parent, variant index)."""
    h = hashlib.sha256(f"{seed}|{parent}|{index}".encode()).hexdigest()
    return int(h[:8], 16)


def batch_seed(seed: int, parent: str) -> int:
    """A stable seed per (run seed, parent) for the batched configuration variants."""
    return variant_seed(seed, f"{parent}:configurations", 0)


def physics_check(cfg: Any, assets_root: Any, backend: Any) -> PhysicsCheck:
    """The stage's :class:`PhysicsCheck` from the ``sim`` and ``augment`` configs."""
    from factory.sim.stability import StabilityProtocol

    lo, hi = batch_sizes(backend.name)
    if cfg.augment.batch > 0:
        lo = hi = cfg.augment.batch
    return PhysicsCheck(
        assets_root=assets_root,
        backend=backend,
        protocol=StabilityProtocol(
            duration=cfg.sim.duration,
            max_translation=cfg.sim.max_translation,
            max_rotation_deg=cfg.sim.max_rotation_deg,
            timestep=cfg.sim.timestep,
        ),
        batch_min=lo,
        batch_max=max(lo, hi),
    )


def check_physics(scene: Any, assets: Any, tol: float = 0.01, backend: Any = "cpu") -> str | None:
    """``None`` if the scene is collision-free and stable (strict protocol), else why not."""
    from factory.sim.metrics import measure_scene

    m = measure_scene(scene, assets, backend=backend, tol=tol, trimesh_test=False)
    if m["collision"]["colliding"]:
        return f"colliding: {', '.join(m['collision']['colliding'][:4])}"
    if m["stability"]["unstable"]:
        return f"unstable: {', '.join(m['stability']['unstable'][:4])}"
    return None


def check_route(scene: Any, assets: Any) -> str | None:
    """``None`` if the scene has no mobile task or its route check passes
    (:func:`factory.nav.route.check_route`: both supports reachable for the robot's base,
    1.5 m apart at least, one free region between them), else the reason (``no_route``,
    ``place_support_too_close``, ...)."""
    from factory.nav import route

    if not route.is_mobile_task(scene):
        return None
    verdict = route.check_route(scene, assets)
    if verdict.ok:
        return None
    log.info("variant %s fails the route check: %s", scene.id, verdict.detail)
    return verdict.reason


def make_variant(
    parent: Any,
    levels: list[str],
    library: AssetLibrary,
    seed: int,
    check: PhysicsCheck | None,
    task_ids: list[str] | None,
) -> Variant:
    """Applies the levels (in composition order) to the parent scene."""
    scene = parent
    params: list[dict[str, Any]] = []
    for i, name in enumerate(lv for lv in LEVELS if lv in levels):
        v = LEVELS[name](scene, library, seed + 101 * i, check, task_ids)
        scene = v.scene
        params.append(v.params)
    return Variant(scene, {"applied": params})


def run(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point."""
    from factory.augment.check import verify_whole_scene
    from factory.augment.distinct import Distinctness
    from factory.augment.routes import configuration_routes
    from factory.console import FILE_ONLY
    from factory.context import run_items
    from factory.scenes.build import compile_one, render_one
    from factory.schema import scene_to_json, validate
    from factory.store import atomic_write_json, atomic_write_text

    store = ctx.require_store()
    acfg = ctx.cfg.augment
    if acfg.variants_per_scene < 1:
        raise ConfigError("augment.variants_per_scene must be >= 1")
    unknown = [lv for lv in acfg.levels if lv not in LEVELS]
    if unknown or not acfg.levels:
        raise ConfigError(
            f"augment.levels {list(acfg.levels)} must be a non-empty subset of {list(LEVELS)}"
        )
    parents = [i for i in store.scene_ids() if "__" not in i]
    if not parents:
        raise StoreError(
            f"no scenes to augment in {store.scenes_dir}: run stage=generate or stage=ingest first"
        )
    tag = "".join(ABBREV[lv] for lv in LEVELS if lv in acfg.levels)
    batched = list(acfg.levels) == ["configuration"]
    if batched:  # a parent's variants are made together: shard the parents
        jobs = [(p, k) for p in ctx.shard.select(parents) for k in range(acfg.variants_per_scene)]
        mine = jobs
    else:
        jobs = [(p, k) for p in parents for k in range(acfg.variants_per_scene)]
        mine = ctx.shard.select(jobs)
    library = AssetLibrary.from_config(ctx.cfg.assets, store.assets_dir)

    from factory.sim.validate import make_backend

    backend = make_backend(ctx.cfg.sim)
    check = physics_check(ctx.cfg, store.assets_dir, backend)
    dropped: Counter[str] = Counter()
    by_name = {f"{p}__{tag}{k}": (p, k) for p, k in mine}
    task_ids = list(acfg.task_objects) or None
    batches: dict[str, tuple[int, Any, list[str]]] = {}

    def batch_of(parent_id: str) -> tuple[int, Any, list[str]]:
        """``(seed, found, why_not)`` for all variants of a parent: the
        :class:`~factory.augment.levels.ConfigurationBatch` (``None`` if none could be made)
        and per variant index an empty string or why it is dropped."""
        if parent_id not in batches:
            batches.clear()  # one parent at a time: names are sorted by parent
            parent = store.load_scene(parent_id)  # SchemaError for a broken parent
            seed = batch_seed(ctx.cfg.seed, parent_id)
            n = acfg.variants_per_scene
            try:
                found = configurations(
                    parent,
                    library,
                    seed,
                    n,
                    check if acfg.physics_critic else None,
                    task_ids,
                    Distinctness(acfg.min_distance, acfg.min_yaw_deg),
                )
            except AugmentError as e:
                log.info("configurations of %s: %s", parent_id, e)
                batches[parent_id] = (seed, None, [str(e).split(":")[0]] * n)
                return batches[parent_id]
            verdict = verify_whole_scene(parent, found.ids, found.poses, check)
            log.info(
                "configurations of %s: %d found, %d pass the whole-scene check; %s",
                parent_id,
                len(found),
                int(verdict.ok.sum()),
                found.stats,
                extra=FILE_ONLY,
            )
            why = ["no distinct valid configuration"] * n
            for k in range(len(found)):
                why[k] = "" if verdict.ok[k] else "physics"
                if why[k]:
                    log.info("variant %s__%s%d dropped: %s", parent_id, tag, k, verdict.reasons[k])
            ok = [k for k in range(len(found)) if not why[k]]
            if ok:  # the mobile task's route, for the physically valid ones
                routes = configuration_routes(parent, found.ids, found.poses[ok], store.assets_dir)
                for k, reason in zip(ok, routes, strict=True):
                    if reason:
                        why[k] = reason
                        log.info(
                            "variant %s__%s%d dropped: route check %s", parent_id, tag, k, reason
                        )
            batches[parent_id] = (seed, found, why)
        return batches[parent_id]

    def one(name: str) -> str:
        parent_id, k = by_name[name]
        if store.scene_json(name).is_file() and not ctx.cfg.force:
            return "skipped"
        if batched:
            seed, found, why = batch_of(parent_id)
            if why[k]:
                dropped[f"{tag}: {why[k]}"] += 1
                return "skipped"
            made = found.variant(k)
            variant = Variant(made.scene, {"applied": [made.params]})
        else:
            parent = store.load_scene(parent_id)  # SchemaError for a broken parent
            seed = variant_seed(ctx.cfg.seed, parent_id, k)
            try:
                variant = make_variant(
                    parent,
                    list(acfg.levels),
                    library,
                    seed,
                    check if acfg.physics_critic else None,
                    task_ids,
                )
            except AugmentError as e:
                dropped[f"{tag}: {str(e).split(':')[0]}"] += 1
                log.info("variant %s dropped: %s", name, e)
                return "skipped"
        scene = variant.scene
        scene.id = name
        scene.source = f"augment:{parent_id}"
        scene.seed = seed
        validate(scene)
        if not batched:
            failed = check_physics(scene, store.assets_dir, backend=backend)
            if failed is not None:
                dropped[f"{tag}: physics"] += 1
                log.info("variant %s dropped: %s", name, failed)
                return "skipped"
            blocked = check_route(scene, store.assets_dir)
            if blocked is not None:
                dropped[f"{tag}: {blocked}"] += 1
                log.info("variant %s dropped: route check %s", name, blocked)
                return "skipped"
        atomic_write_json(
            store.report_json(name),
            {
                "schema_version": 1,
                "augment": {
                    "parent": parent_id,
                    "index": k,
                    "seed": seed,
                    "levels": list(acfg.levels),
                    **variant.params,
                },
            },
        )
        atomic_write_text(store.scene_json(name), scene_to_json(scene))
        compile_one(store, name, ctx.cfg.compile, force=True)
        if acfg.render:
            render_one(store, name, ctx.cfg.render, force=True)
        return "done"

    result = run_items("augment", sorted(by_name), one)
    kept = sum(1 for n in by_name if store.scene_json(n).is_file())
    return {
        **result,
        "kept": kept,
        "dropped": dict(dropped),
        "acceptance": kept / len(by_name) if by_name else 0.0,
    }
