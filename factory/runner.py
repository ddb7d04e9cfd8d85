"""Runs one stage: logging to stderr and ``run_dir/logs``, manifest status, timing."""

from __future__ import annotations

import dataclasses
import logging
import time
from typing import Any

from factory.context import StageContext
from factory.errors import ConfigError, StoreError
from factory.stages import CREATES_RUN, check_stage, resolve

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


def run_all(ctx: StageContext) -> dict[str, Any]:
    """``stage=all``: runs ``all.stages`` in order; stops at the first failure."""
    for name in ctx.cfg.all.stages:
        check_stage(name)
        if name in ("all", "list"):
            raise ConfigError(f"all.stages may not contain {name!r}")
    results = {}
    for name in ctx.cfg.all.stages:
        results[name] = run_stage(name, ctx)
    return results
