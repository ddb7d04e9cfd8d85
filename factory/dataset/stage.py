"""``stage=dataset``: episode stores -> per-shard LeRobot datasets -> one merged dataset.

Every shard of ``stage=demos`` must have finished (the manifest says so). Each shard's store is
exported to ``<out>/shards/shard-<k>`` unless an export of the same episodes is there already,
so a re-run after a failure redoes only what is missing. The shard datasets are then merged
with lerobot's ``aggregate_datasets`` into ``<out>/merged`` (built aside, checked, renamed).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from pathlib import Path
from typing import Any

from factory.errors import StoreError
from factory.stages import StageContext

log = logging.getLogger(__name__)

_SHARD = re.compile(r"^(\d+)-of-(\d+)$")


def finished_shards(manifest: dict[str, Any]) -> int:
    """The shard count of ``stage=demos``, after checking that every shard finished.

    Raises:
        StoreError: demos never ran, shard layouts are mixed, or a shard is missing or
            unfinished (the message names them and how to re-run).
    """
    entry = manifest.get("stages", {}).get("demos")
    if not entry or not entry.get("shards"):
        raise StoreError("no finished stage=demos in this run: run stage=demos first")
    counts: dict[int, dict[int, str]] = {}
    for name, info in entry["shards"].items():
        m = _SHARD.match(name)
        if m:
            counts.setdefault(int(m.group(2)), {})[int(m.group(1))] = info.get("status", "")
    if len(counts) != 1:
        raise StoreError(
            f"stage=demos ran with different shard counts {sorted(counts)}: re-run it with one "
            "shard.count"
        )
    ((n, done),) = counts.items()
    bad = [k for k in range(n) if done.get(k) != "done"]
    if bad:
        states = {k: done.get(k, "missing") for k in bad}
        raise StoreError(
            f"stage=demos shard(s) {states} of {n} have not finished: re-run them "
            f"(python -m factory stage=demos shard.index=K shard.count={n})"
        )
    return n


def run(ctx: StageContext) -> dict[str, Any]:
    """Exports each demos shard to LeRobot and merges them; returns a summary."""
    from factory import __version__
    from factory.dataset.lerobot_export import FACTORY_META, export_store, merge_datasets
    from factory.demos.episodes import EpisodeStore
    from factory.store import Shard

    store = ctx.require_store()
    cfg = ctx.cfg.dataset
    n = finished_shards(store.read_manifest())
    out = Path(cfg.out) if cfg.out else store.root / "dataset"
    shard_dirs = []
    exported = 0
    for k in range(n):
        path = store.episodes_shard(Shard(k, n))
        if not path.is_dir():
            raise StoreError(
                f"{path} is missing although shard {k}-of-{n} of stage=demos finished: re-run "
                f"python -m factory stage=demos shard.index={k} shard.count={n} force=true"
            )
        episodes = EpisodeStore(path)
        ids = episodes.episode_ids()
        digest = hashlib.sha256("\n".join(ids).encode()).hexdigest()
        dest = out / "shards" / f"shard-{k}"
        meta_path = dest / FACTORY_META
        if meta_path.is_file() and json.loads(meta_path.read_text()).get("digest") == digest:
            shard_dirs.append(dest)
            continue
        log.info("dataset: exporting shard %d-of-%d (%d episodes)", k, n, len(ids))
        export_store(
            episodes,
            dest,
            f"{cfg.repo_id}-shard{k}",
            store.root,
            cfg.vcodec,
            __version__,
            {"digest": digest},
        )
        exported += 1
        shard_dirs.append(dest)
    merged = merge_datasets(shard_dirs, out / "merged", cfg.repo_id, __version__)
    log.info(
        "dataset: %d episodes from %d shard(s) in %s", len(merged["episodes"]), n, out / "merged"
    )
    return {
        "shards": n,
        "exported": exported,
        "episodes": len(merged["episodes"]),
        "path": str(out / "merged"),
    }
