"""Runs one stage: logging to stderr and ``run_dir/logs``, manifest status, timing."""

from __future__ import annotations

import dataclasses
import logging
import time
from typing import Any

from factory.errors import StoreError
from factory.stages import CREATES_RUN, StageContext, resolve

log = logging.getLogger("factory")

_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def setup_logging(level: str) -> None:
    """Logs to stderr at ``level`` (idempotent)."""
    root = logging.getLogger()
    if not any(getattr(h, "_factory", False) for h in root.handlers):
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter(_FORMAT, "%H:%M:%S"))
        handler._factory = True  # type: ignore[attr-defined]
        root.addHandler(handler)
    root.setLevel(level.upper())


def run_stage(name: str, ctx: StageContext) -> dict[str, Any]:
    """Runs stage ``name`` with ``ctx``; records its status in the manifest if there is a run.

    Returns:
        the stage's summary dict.
    """
    fn = resolve(name)
    store = ctx.store if name == "list" else ctx.require_store()
    if store is None or name in ("list", "all"):
        return fn(dataclasses.replace(ctx, cfg=dataclasses.replace(ctx.cfg, stage=name)))
    if name not in CREATES_RUN and not store.root.is_dir():
        raise StoreError(
            f"run_dir {store.root} does not exist: start the run with stage=ingest or stage=all"
        )
    from omegaconf import OmegaConf

    config: dict[str, Any] = OmegaConf.to_container(  # type: ignore[assignment]
        OmegaConf.structured(ctx.cfg)
    )
    store.logs_dir.mkdir(parents=True, exist_ok=True)
    file_handler = logging.FileHandler(store.logs_dir / f"{name}-{ctx.shard.name}.log")
    file_handler.setFormatter(logging.Formatter(_FORMAT))
    logging.getLogger().addHandler(file_handler)
    t0 = time.perf_counter()
    store.record_stage(name, ctx.shard, "running", config)
    try:
        log.info("stage %s: shard %s, run_dir %s", name, ctx.shard.name, store.root)
        result = fn(dataclasses.replace(ctx, cfg=dataclasses.replace(ctx.cfg, stage=name)))
    except BaseException as e:
        store.record_stage(
            name,
            ctx.shard,
            "failed",
            config,
            error=f"{type(e).__name__}: {e}",
            seconds=time.perf_counter() - t0,
        )
        raise
    finally:
        logging.getLogger().removeHandler(file_handler)
        file_handler.close()
    seconds = time.perf_counter() - t0
    store.record_stage(name, ctx.shard, "done", config, seconds=seconds, result=result)
    log.info("stage %s done in %.1f s: %s", name, seconds, result)
    return result


def run_items(what: str, items: list[str], fn: Any, progress: bool = True) -> dict[str, Any]:
    """Applies ``fn(item) -> "done" | "skipped"`` to every item, with a progress bar.

    A :class:`~factory.errors.FactoryError` on one item is logged and the others go on; at the
    end, any failure raises one error naming how many failed and the first reason. Items done
    before a failure stay done (their outputs are complete, written atomically).

    Returns:
        ``{"done": n, "skipped": n, "total": n}``.
    """
    from tqdm import tqdm

    from factory.errors import FactoryError, StageFailed

    counts = {"done": 0, "skipped": 0}
    failures: list[tuple[str, str]] = []
    for item in tqdm(items, desc=what, unit="item", disable=not progress or None):
        try:
            counts[fn(item)] += 1
        except FactoryError as e:
            log.error("%s %s failed: %s", what, item, e)
            failures.append((item, str(e)))
    if failures:
        item, reason = failures[0]
        reason = reason if item in reason else f"{item}: {reason}"
        raise StageFailed(
            f"{what}: {len(failures)} of {len(items)} item(s) failed; first: {reason}"
        )
    return {**counts, "total": len(items)}
