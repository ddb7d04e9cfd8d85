"""``stage=dataset``: episode stores -> per-shard LeRobot datasets -> one merged dataset.

In a SLURM array (``shard.count`` > 1) each task exports only its own demos shard to
``<out>/shards/shard-<k>``. Without shards, every shard of ``stage=demos`` must have finished
(the manifest says so); each shard's store is exported unless an export of the same episodes
with the same codec is there already, so a re-run after a failure redoes only what is missing.
The shard datasets are then merged with lerobot's ``aggregate_datasets`` into ``<out>/merged``
(built aside, checked, renamed).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from pathlib import Path
from typing import Any

from factory.errors import ConfigError, StoreError
from factory.stages import StageContext

log = logging.getLogger(__name__)

_SHARD = re.compile(r"^(\d+)-of-(\d+)$")
VCODECS = ("h264", "hevc", "libsvtav1")
PRESETS = (
    "ultrafast",
    "superfast",
    "veryfast",
    "faster",
    "fast",
    "medium",
    "slow",
    "slower",
    "veryslow",
)


def check_config(cfg: Any) -> None:
    """Raises :class:`ConfigError` naming a bad ``dataset.*`` value."""
    if cfg.vcodec not in VCODECS:
        raise ConfigError(f"dataset.vcodec must be one of {', '.join(VCODECS)}, got {cfg.vcodec!r}")
    if not 0 <= cfg.crf <= 63:
        raise ConfigError(f"dataset.crf must be in 0..63 (h264: 0..51), got {cfg.crf}")
    if cfg.preset not in PRESETS:
        raise ConfigError(f"dataset.preset must be one of {', '.join(PRESETS)}, got {cfg.preset!r}")


def _demos_shards(manifest: dict[str, Any]) -> tuple[int, dict[int, str]]:
    """The shard count of ``stage=demos`` and each shard's status."""
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
    return n, done


def finished_shards(manifest: dict[str, Any]) -> int:
    """The shard count of ``stage=demos``, after checking that every shard finished.

    Raises:
        StoreError: demos never ran, shard layouts are mixed, or a shard is missing or
            unfinished (the message names them and how to re-run).
    """
    n, done = _demos_shards(manifest)
    bad = [k for k in range(n) if done.get(k) != "done"]
    if bad:
        states = {k: done.get(k, "missing") for k in bad}
        raise StoreError(
            f"stage=demos shard(s) {states} of {n} have not finished: re-run them "
            f"(python -m factory stage=demos shard.index=K shard.count={n})"
        )
    return n


def _export_shard(ctx: StageContext, k: int, n: int, out: Path) -> tuple[Path, bool]:
    """Exports demos shard ``k`` of ``n`` to ``<out>/shards/shard-<k>`` unless an export of the
    same episodes with the same codec is there; returns the folder and whether it exported."""
    from factory import __version__
    from factory.dataset.lerobot_export import FACTORY_META, export_store
    from factory.dataset.video import rgb_codec
    from factory.demos.episodes import EpisodeStore
    from factory.store import Shard

    store = ctx.require_store()
    cfg = ctx.cfg.dataset
    rgb = rgb_codec(cfg.vcodec, cfg.crf, cfg.preset)
    path = store.episodes_shard(Shard(k, n))
    if not path.is_dir():
        raise StoreError(
            f"{path} is missing although shard {k}-of-{n} of stage=demos finished: re-run "
            f"python -m factory stage=demos shard.index={k} shard.count={n} force=true"
        )
    episodes = EpisodeStore(path)
    ids = episodes.episode_ids()
    # the episodes and how they are encoded: a new codec setting re-exports
    key = "\n".join([*ids, json.dumps(rgb.__dict__, sort_keys=True)])
    digest = hashlib.sha256(key.encode()).hexdigest()
    dest = out / "shards" / f"shard-{k}"
    meta_path = dest / FACTORY_META
    if meta_path.is_file() and json.loads(meta_path.read_text()).get("digest") == digest:
        return dest, False
    log.info("dataset: exporting shard %d-of-%d (%d episodes)", k, n, len(ids))
    export_store(
        episodes,
        dest,
        f"{cfg.repo_id}-shard{k}",
        store.root,
        rgb,
        __version__,
        {"digest": digest},
    )
    return dest, True


def run(ctx: StageContext) -> dict[str, Any]:
    """``stage=dataset``; returns a summary.

    With ``shard.count`` > 1 (a SLURM array task) it exports only demos shard
    ``shard.index`` (the demos must have run with the same ``shard.count``). Without shards it
    exports every demos shard not exported yet and merges them all into ``<out>/merged``.
    """
    from factory import __version__
    from factory.dataset.lerobot_export import merge_datasets

    store = ctx.require_store()
    cfg = ctx.cfg.dataset
    check_config(cfg)
    out = Path(cfg.out) if cfg.out else store.root / "dataset"
    if ctx.shard.count > 1:
        k, n = ctx.shard.index, ctx.shard.count
        demos_n, done = _demos_shards(store.read_manifest())
        if demos_n != n:
            raise ConfigError(
                f"stage=demos ran as {demos_n} shard(s), this is shard {k} of {n}: export with "
                f"shard.count={demos_n}, or without shard.* to export and merge every shard"
            )
        if done.get(k) != "done":
            raise StoreError(
                f"stage=demos shard {k}-of-{n} has not finished ({done.get(k, 'missing')}): "
                f"re-run python -m factory stage=demos shard.index={k} shard.count={n}"
            )
        dest, did = _export_shard(ctx, k, n, out)
        return {"shard": k, "shards": n, "exported": int(did), "path": str(dest)}
    n = finished_shards(store.read_manifest())
    shard_dirs = []
    exported = 0
    for k in range(n):
        dest, did = _export_shard(ctx, k, n, out)
        exported += int(did)
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
