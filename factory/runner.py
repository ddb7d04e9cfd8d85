"""Runs one stage: logging to the terminal and ``run_dir/logs``, manifest status, timing, and
the summary table of what it produced.

Quiet by default (:mod:`factory.console`): while a stage runs, descriptor 2 points at its log
file ``run_dir/logs/<stage>-<shard>.log``, which gets every log record and all third-party
output; the terminal gets factory's records, its progress bars and, after the stage, a table
of what was produced and where (:mod:`factory.summary`). ``log_level=DEBUG`` (``-v``) brings
everything back to the terminal.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import time
from collections.abc import Callable
from typing import Any

from factory.console import (
    FILE_ONLY,
    TerminalFilter,
    TerminalHandler,
    is_verbose,
    stderr_to,
    terminal,
)
from factory.context import StageContext
from factory.errors import ConfigError, FactoryError, StoreError
from factory.stages import CREATES_RUN, check_stage, resolve
from factory.summary import Row, format_table, run_rows, show_path, stage_rows

log = logging.getLogger("factory")

_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def setup_logging(level: str) -> None:
    """Logs to the terminal at ``level`` (idempotent; a second call sets the new level).

    Below DEBUG only factory's records (and other loggers' at ERROR and up) reach the terminal
    (:class:`~factory.console.TerminalFilter`); at DEBUG every record does. ``warnings`` become
    log records (``py.warnings``), so they reach the stage log file.
    """
    root = logging.getLogger()
    handler = next((h for h in root.handlers if getattr(h, "_factory", False)), None)
    if handler is None:
        handler = TerminalHandler()
        handler.setFormatter(logging.Formatter(_FORMAT, "%H:%M:%S"))
        handler._factory = True  # type: ignore[attr-defined]
        root.addHandler(handler)
    for f in [f for f in handler.filters if isinstance(f, TerminalFilter)]:
        handler.removeFilter(f)
    if not is_verbose(level):
        handler.addFilter(TerminalFilter())
    root.setLevel(level.upper())
    logging.captureWarnings(True)


def run_stage(name: str, ctx: StageContext) -> dict[str, Any]:
    """Runs stage ``name`` with ``ctx``; records its status in the manifest if there is a run.

    Returns:
        the stage's summary dict.
    """
    store = ctx.store if name == "list" else ctx.require_store()
    if store is None or name in ("list", "all"):
        fn = resolve(name)
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
    log_path = store.logs_dir / f"{name}-{ctx.shard.name}.log"
    file_handler = logging.FileHandler(log_path)
    file_handler.setFormatter(logging.Formatter(_FORMAT))
    logging.getLogger().addHandler(file_handler)
    quiet = not is_verbose(ctx.cfg.log_level)
    t0 = time.perf_counter()
    store.record_stage(name, ctx.shard, "running", config)
    try:
        # third-party output (C libraries, workers, sys.stderr) goes to the log file
        with stderr_to(log_path) if quiet else contextlib.nullcontext():
            log.info("stage %s: shard %s, run_dir %s", name, ctx.shard.name, store.root)
            fn = resolve(name)
            result = fn(dataclasses.replace(ctx, cfg=dataclasses.replace(ctx.cfg, stage=name)))
        seconds = time.perf_counter() - t0
        log.info("stage %s done in %.1f s: %s", name, seconds, result, extra=FILE_ONLY)
    except BaseException as e:
        log.error(
            "stage %s failed after %.1f s: %s: %s",
            name,
            time.perf_counter() - t0,
            type(e).__name__,
            e,
            exc_info=not isinstance(e, FactoryError | KeyboardInterrupt),
            extra=FILE_ONLY,
        )
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
    store.record_stage(name, ctx.shard, "done", config, seconds=seconds, result=result)
    _print_table(
        f"stage {name} done in {seconds:.1f} s:", lambda: stage_rows(name, result, store, ctx.shard)
    )
    return result


def _print_table(title: str, rows: Callable[[], list[Row]]) -> None:
    """Prints the summary table to the terminal; a result it cannot read fails nothing."""
    try:
        text = format_table(title, rows())
    except Exception as e:  # the stage is done and recorded: a table is not worth failing it
        log.warning("no summary table (%s: %s); the result is in the manifest", type(e).__name__, e)
        return
    print(text, file=terminal(), flush=True)


def run_all(ctx: StageContext) -> dict[str, Any]:
    """``stage=all``: runs ``all.stages`` in order; stops at the first failure."""
    for name in ctx.cfg.all.stages:
        check_stage(name)
        if name in ("all", "list"):
            raise ConfigError(f"all.stages may not contain {name!r}")
    results, seconds = {}, {}
    t0 = time.perf_counter()
    for name in ctx.cfg.all.stages:
        t = time.perf_counter()
        results[name] = run_stage(name, ctx)
        seconds[name] = time.perf_counter() - t
    store = ctx.require_store()
    where = show_path(".", store.root)
    title = f"stage=all done in {time.perf_counter() - t0:.1f} s, run_dir {where}:"
    _print_table(title, lambda: run_rows(results, seconds, store, ctx.shard))
    return results
