"""``stage=ingest``: bring existing scenes into a run directory.

Inputs (``ingest.source``): a ``scene.json`` of ours, a SAGE layout JSON, a packed SAGE folder or
zip (layout + ``objects/*.ply`` + textures), or a folder holding any of these; with no source,
the bundled example scenes (``ingest.examples``). Each scene lands in
``scenes/<id>/scene.json``; SAGE meshes go to the asset cache (``assets/sage-*``).

Re-running skips scenes already present with the same content; a different scene under an
existing id is refused unless ``force=true``.
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from factory.context import StageContext, run_items
from factory.errors import ConfigError, StoreError
from factory.scenes.sage_assets import ARTICULATION_SUFFIX, import_sage_mesh
from factory.schema import Scene, SchemaError, load_scene, scene_to_json
from factory.schema.sage import extract_zip, read_package, sage_to_scene
from factory.store import RunStore

log = logging.getLogger(__name__)

EXAMPLES_DIR = Path(__file__).resolve().parent.parent / "data" / "examples"


@dataclass(frozen=True)
class SceneInput:
    """One thing to ingest: ``kind`` is ``scene`` (our JSON) or ``sage`` (layout/folder/zip)."""

    kind: str
    path: Path


def _json_kind(path: Path) -> str | None:
    if path.name.endswith(ARTICULATION_SUFFIX):
        return None  # the joint states beside an exported SAGE layout, not a scene
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError):
        return "scene" if path.name == "scene.json" else None
    if not isinstance(data, dict):
        return None
    if "schema_version" in data:
        return "scene"
    if "rooms" in data and "id" in data:
        return "sage"
    return None


def discover(source: str | Path) -> list[SceneInput]:
    """The scene inputs found at ``source`` (sorted by path).

    Raises:
        ConfigError: the source does not exist or holds nothing to ingest.
    """
    root = Path(source)
    if not root.exists():
        raise ConfigError(f"ingest.source {root} does not exist")
    found: list[SceneInput] = []

    def visit(p: Path, depth: int) -> None:
        if p.is_file():
            if p.suffix.lower() == ".zip":
                found.append(SceneInput("sage", p))
            elif p.suffix.lower() == ".json":
                kind = _json_kind(p)
                if kind is not None:
                    found.append(SceneInput(kind, p))
                elif depth == 0:
                    raise SchemaError(
                        f"{p} is neither a scene.json (no schema_version) nor a SAGE layout "
                        "(no 'id' and 'rooms')"
                    )
            return
        if (p / "scene.json").is_file():
            found.append(SceneInput("scene", p / "scene.json"))
            return
        layouts = [c for c in sorted(p.glob("*.json")) if c.is_file() and _json_kind(c) == "sage"]
        if layouts and (p / "objects").is_dir():
            found.append(SceneInput("sage", p))
            return
        if depth < 2:
            for child in sorted(p.iterdir()):
                if not child.name.startswith("."):
                    visit(child, depth + 1)

    visit(root, 0)
    if not found:
        raise ConfigError(f"ingest.source {root} holds no scene.json, SAGE layout or SAGE zip")
    return found


def _sage_scene(store: RunStore, inp: SceneInput) -> Scene:
    tmp: Path | None = None
    try:
        folder = inp.path
        if inp.path.suffix.lower() == ".zip":
            (store.root / ".tmp").mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix="sage-", dir=store.root / ".tmp"))
            folder = extract_zip(inp.path, tmp)
        pkg = read_package(folder)
        scene = sage_to_scene(pkg.layout)
        for obj in scene.objects:
            a = obj.asset
            if a is None or a.source_id not in pkg.meshes:
                continue
            a.asset_id = import_sage_mesh(
                store, pkg.meshes[a.source_id], pkg.textures.get(a.source_id), license="SAGE-10k"
            )
        meshes = sum(1 for o in scene.objects if o.asset is not None and o.asset.asset_id)
        log.info("SAGE scene %s: %d objects, %d with meshes", scene.id, len(scene.objects), meshes)
        return scene
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _same_scene(path: Path, scene: Scene) -> bool:
    """Whether the stored ``path`` holds ``scene`` in another text: a scene an older factory
    wrote in an older schema version, kept as it is (the later stages' stamps hash its bytes)."""
    try:
        return load_scene(path) == scene
    except SchemaError:
        return False


def ingest_one(store: RunStore, inp: SceneInput, force: bool = False) -> str:
    """Ingests one input; returns ``"done"`` or ``"skipped"`` (already there, same content)."""
    scene = load_scene(inp.path) if inp.kind == "scene" else _sage_scene(store, inp)
    target = store.scene_json(scene.id)
    text = scene_to_json(scene)
    if target.is_file():
        if target.read_text(encoding="utf-8") == text or _same_scene(target, scene):
            return "skipped"
        if not force:
            raise StoreError(
                f"scene {scene.id!r} from {inp.path} differs from the one already in {target}: "
                "pass force=true to replace it, or use another run_dir"
            )
    store.save_scene(scene)
    return "done"


def run(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point."""
    store = ctx.require_store()
    cfg = ctx.cfg.ingest
    if cfg.source:
        inputs = discover(cfg.source)
    else:
        inputs = []
        for name in cfg.examples:
            path = EXAMPLES_DIR / name / "scene.json"
            if not path.is_file():
                known = sorted(p.name for p in EXAMPLES_DIR.iterdir() if p.is_dir())
                raise ConfigError(f"unknown example {name!r}: choose from {known}")
            inputs.append(SceneInput("scene", path))
    mine = ctx.shard.select(inputs, key=lambda i: str(i.path))
    by_name = {str(i.path): i for i in mine}
    result = run_items(
        "ingest", list(by_name), lambda p: ingest_one(store, by_name[p], ctx.cfg.force)
    )
    return {**result, "scenes": len(store.scene_ids())}
