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
import itertools
import json
import logging
import os
import re
import time
from pathlib import Path
from typing import Any

from factory.context import StageContext
from factory.errors import ConfigError, StoreError

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
    if cfg.workers < 1:
        raise ConfigError(f"dataset.workers must be >= 1, got {cfg.workers}")
    if cfg.video_file_mb < 1:
        raise ConfigError(f"dataset.video_file_mb must be >= 1, got {cfg.video_file_mb}")


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


def _export_part(args: tuple[Any, ...]) -> None:
    """One worker process of a parallel shard export (top level: picklable)."""
    from factory.dataset.lerobot_export import export_store
    from factory.demos.record.episodes import EpisodeStore

    store_path, dest, repo_id, run_dir, rgb, version, video_file_mb, ids, cpu = args
    if cpu is not None:
        # one core per part: its encoder threads stay beside their producer
        os.sched_setaffinity(0, {cpu})
    export_store(
        EpisodeStore(store_path),
        dest,
        repo_id,
        run_dir,
        rgb,
        version,
        video_file_mb=video_file_mb,
        episode_ids=ids,
    )


def _export_shard(ctx: StageContext, k: int, n: int, out: Path) -> tuple[Path, dict[str, Any]]:
    """Exports demos shard ``k`` of ``n`` to ``<out>/shards/shard-<k>`` unless an export of the
    same episodes with the same codec is there.

    With ``dataset.workers`` > 1 the shard's episodes are split into that many consecutive
    parts, written by as many processes, and joined with lerobot's aggregator; the result is
    the same dataset (episode order included).

    Returns:
        the folder, and ``{"exported": 0|1, "frames": int, "seconds": float}`` of this call.
    """
    from factory import __version__
    from factory.dataset.lerobot_export import (
        EXPORT_SCHEMA_VERSION,
        FACTORY_META,
        export_store,
        merge_datasets,
    )
    from factory.dataset.video import rgb_codec
    from factory.demos.record.episodes import EpisodeStore
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
    # the episodes, how they are encoded and the export's format: a new codec setting or a
    # newer format (e.g. a new feature) re-exports
    key = "\n".join(
        [*ids, json.dumps(rgb.__dict__, sort_keys=True), f"export-v{EXPORT_SCHEMA_VERSION}"]
    )
    digest = hashlib.sha256(key.encode()).hexdigest()
    dest = out / "shards" / f"shard-{k}"
    meta_path = dest / FACTORY_META
    if meta_path.is_file() and json.loads(meta_path.read_text()).get("digest") == digest:
        return dest, {"exported": 0, "frames": 0, "seconds": 0.0}
    repo_id = f"{cfg.repo_id}-shard{k}"
    workers = max(1, min(cfg.workers, len(ids)))
    log.info(
        "dataset: exporting shard %d-of-%d (%d episodes, %d process(es))", k, n, len(ids), workers
    )
    t0 = time.perf_counter()
    if workers == 1:
        meta = export_store(
            episodes,
            dest,
            repo_id,
            store.root,
            rgb,
            __version__,
            {"digest": digest},
            video_file_mb=cfg.video_file_mb,
        )
    else:
        import multiprocessing
        import shutil
        from concurrent.futures import ProcessPoolExecutor

        parts_dir = dest.with_name(f".parts-{dest.name}")
        shutil.rmtree(parts_dir, ignore_errors=True)
        bounds = [round(j * len(ids) / workers) for j in range(workers + 1)]
        parts = [parts_dir / f"part-{j}" for j in range(workers)]
        cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
        pin = len(cpus) >= workers
        jobs = [
            (
                path,
                parts[j],
                repo_id,
                store.root,
                rgb,
                __version__,
                cfg.video_file_mb,
                ids[a:b],
                cpus[j] if pin else None,
            )
            for j, (a, b) in enumerate(itertools.pairwise(bounds))
        ]
        try:
            # fork where there is one: the workers inherit the imported lerobot (seconds);
            # zarr resets its I/O thread in forked children itself
            methods = multiprocessing.get_all_start_methods()
            context = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
            with ProcessPoolExecutor(workers, mp_context=context) as pool:
                list(pool.map(_export_part, jobs))
            log.info("dataset: %d parts written in %.1f s", workers, time.perf_counter() - t0)
            meta = merge_datasets(
                parts,
                dest,
                repo_id,
                __version__,
                video_file_mb=cfg.video_file_mb,
                extra_meta={"digest": digest, "shards": [], "parts": workers},
            )
        finally:
            shutil.rmtree(parts_dir, ignore_errors=True)
    frames = sum(e["n_frames"] for e in meta["episodes"])
    seconds = time.perf_counter() - t0
    log.info("dataset: shard %d-of-%d: %d frames in %.1f s", k, n, frames, seconds)
    return dest, {"exported": 1, "frames": frames, "seconds": round(seconds, 3)}


def _import_lerobot() -> None:
    """Imports lerobot (torch, datasets: seconds, once per process), after the cheap checks."""
    t0 = time.perf_counter()
    import lerobot.datasets.lerobot_dataset  # noqa: F401

    log.info("dataset: lerobot imported in %.1f s", time.perf_counter() - t0)


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
        _import_lerobot()
        dest, done_now = _export_shard(ctx, k, n, out)
        return {
            "shard": k,
            "shards": n,
            "exported": done_now["exported"],
            "path": str(dest),
            "export_frames": done_now["frames"],
            "export_seconds": done_now["seconds"],
        }
    n = finished_shards(store.read_manifest())
    _import_lerobot()
    shard_dirs = []
    total = {"exported": 0, "frames": 0, "seconds": 0.0}
    for k in range(n):
        dest, done_now = _export_shard(ctx, k, n, out)
        total = {key: total[key] + done_now[key] for key in total}
        shard_dirs.append(dest)
    t0 = time.perf_counter()
    merged = merge_datasets(
        shard_dirs, out / "merged", cfg.repo_id, __version__, video_file_mb=cfg.video_file_mb
    )
    merge_seconds = time.perf_counter() - t0
    log.info(
        "dataset: %d episodes from %d shard(s) in %s", len(merged["episodes"]), n, out / "merged"
    )
    return {
        "shards": n,
        "exported": total["exported"],
        "episodes": len(merged["episodes"]),
        "path": str(out / "merged"),
        "export_frames": total["frames"],
        "export_seconds": round(total["seconds"], 3),
        "merge_seconds": round(merge_seconds, 3),
    }
