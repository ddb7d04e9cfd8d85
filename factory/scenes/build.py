"""``stage=compile``, ``stage=render`` and ``stage=export``: per-scene artifacts.

* compile: ``scenes/<id>/model.xml`` (meshes stay in ``assets/``, referenced relatively);
* render: ``scenes/<id>/renders/{top,corner_0..3}.png`` from ``model.xml``;
* export: the scene in SAGE's packed format under ``export.out``.

Each is idempotent: a scene whose inputs (scene, options, assets) are unchanged is skipped.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import asdict
from pathlib import Path
from typing import Any

from factory.context import StageContext, run_items
from factory.errors import ConfigError, StoreError
from factory.store import RunStore, atomic_write_bytes, atomic_write_text

log = logging.getLogger(__name__)


def _digest(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.hexdigest()


def _scene_ids(ctx: StageContext, store: RunStore) -> list[str]:
    ids = store.scene_ids()
    if not ids:
        raise StoreError(f"no scenes in {store.scenes_dir}: run stage=ingest (or stage=all) first")
    return ctx.shard.select(ids)


def compile_one(store: RunStore, scene_id: str, options: Any, force: bool = False) -> str:
    """Compiles one scene of the run into ``model.xml``."""
    from factory.sim.compile import CompileOptions, compile_scene, model_xml

    scene_path = store.scene_json(scene_id)
    scene = store.load_scene(scene_id)
    metas = []
    for obj in scene.objects:
        if obj.asset is not None and obj.asset.asset_id:
            meta = store.asset_dir(obj.asset.asset_id) / "meta.json"
            metas.append(meta.read_bytes() if meta.is_file() else b"missing")
    opts = CompileOptions(**asdict(options))
    digest = _digest(scene_path.read_bytes(), json.dumps(asdict(opts)).encode(), *metas)
    scene_dir = store.scene_dir(scene_id)
    if not force and store.is_done(scene_dir, "compile", digest):
        return "skipped"
    compiled = compile_scene(scene, store.assets_dir, opts)
    atomic_write_text(store.model_xml(scene_id), model_xml(compiled, scene_dir))
    store.mark_done(scene_dir, "compile", digest, ["model.xml"])
    return "done"


def render_one(store: RunStore, scene_id: str, cfg: Any, force: bool = False) -> str:
    """Renders one compiled scene's views to ``renders/*.png``."""
    import mujoco

    from factory.scenes.render import png_bytes, render_views

    xml = store.model_xml(scene_id)
    if not xml.is_file():
        raise StoreError(f"scene {scene_id!r} has no model.xml: run stage=compile first")
    scene_dir = store.scene_dir(scene_id)
    digest = _digest(
        xml.read_bytes(), store.scene_json(scene_id).read_bytes(), json.dumps(asdict(cfg)).encode()
    )
    if not force and store.is_done(scene_dir, "render", digest):
        return "skipped"
    try:
        model = mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as e:
        raise StoreError(f"{xml} does not load: {e}; re-run stage=compile force=true") from None
    images = render_views(model, store.load_scene(scene_id), cfg.views, cfg.width, cfg.height)
    out = store.renders_dir(scene_id)
    for view, image in images.items():
        atomic_write_bytes(out / f"{view}.png", png_bytes(image))
    store.mark_done(scene_dir, "render", digest, [f"renders/{v}.png" for v in images])
    return "done"


def run_compile(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point: compile."""
    store = ctx.require_store()
    ids = _scene_ids(ctx, store)
    return run_items(
        "compile", ids, lambda i: compile_one(store, i, ctx.cfg.compile, ctx.cfg.force)
    )


def run_render(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point: render."""
    from factory.sim.gl import configure_gl

    store = ctx.require_store()
    if ctx.cfg.render.width <= 0 or ctx.cfg.render.height <= 0:
        raise ConfigError("render.width and render.height must be positive")
    configure_gl(ctx.cfg.render.gl)
    ids = _scene_ids(ctx, store)
    return run_items("render", ids, lambda i: render_one(store, i, ctx.cfg.render, ctx.cfg.force))


def run_export(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point: export (SAGE format)."""
    from factory.scenes.sage_assets import export_sage

    store = ctx.require_store()
    cfg = ctx.cfg.export
    if cfg.format != "sage":
        raise ConfigError(f"export.format={cfg.format!r} is not supported: use sage")
    out = Path(cfg.out) if cfg.out else store.root / "export" / cfg.format
    ids = _scene_ids(ctx, store)

    def one(scene_id: str) -> str:
        export_sage(store.load_scene(scene_id), store, out / scene_id)
        return "done"

    return {**run_items("export", ids, one), "out": str(out)}
