"""``stage=report``: writes ``<run_dir>/report.html`` from the run directory's files.

Cheap enough to run after every stage (reading JSON, a few thumbnails and GIFs), so it keeps no
stamps: each run writes the page anew, atomically. It ignores sharding (it reads every shard's
files); run it once, after the other stages.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from factory.context import StageContext
from factory.errors import ConfigError
from factory.report.collect import VIEWS, collect_run
from factory.report.media import MediaSink
from factory.report.page import build_page
from factory.store import atomic_write_text

log = logging.getLogger(__name__)

REPORT_FILE = "report.html"


def check_config(cfg: Any) -> None:
    """Raises :class:`ConfigError` for report options that cannot work."""
    if cfg.gifs < 0 or cfg.eval_videos < 0 or cfg.max_scenes < 0:
        raise ConfigError(
            "report.gifs, report.eval_videos and report.max_scenes must be >= 0 "
            f"(got {cfg.gifs}, {cfg.eval_videos}, {cfg.max_scenes})"
        )
    if not cfg.gif_fps > 0 or cfg.gif_size < 16 or cfg.thumb_width < 16:
        raise ConfigError(
            "report.gif_fps must be > 0 and report.gif_size, report.thumb_width >= 16 px "
            f"(got {cfg.gif_fps}, {cfg.gif_size}, {cfg.thumb_width})"
        )
    bad = [v for v in cfg.views if v not in VIEWS]
    if bad:
        raise ConfigError(f"report.views {bad} unknown: choose from {list(VIEWS)}")


def run(ctx: StageContext) -> dict[str, Any]:
    """Writes the run report.

    Returns:
        ``{"sections": [...], "images": n, "notes": n, "bytes": n, "produced": [...]}``.
    """
    cfg = ctx.cfg.report
    check_config(cfg)
    store = ctx.require_store()
    t0 = time.perf_counter()
    data = collect_run(store.root)
    built = build_page(data, cfg, MediaSink(store.root, cfg.embed))
    path = atomic_write_text(store.root / REPORT_FILE, built.html)
    size = path.stat().st_size
    log.info(
        "report: %s (%.1f MB, sections %s, %d images) in %.1f s",
        path,
        size / 1e6,
        ", ".join(built.sections) or "none",
        built.images,
        time.perf_counter() - t0,
    )
    return {
        "sections": built.sections,
        "images": built.images,
        "notes": len(built.notes),
        "bytes": size,
        "produced": [{"what": "report", "count": 1, "path": str(path.absolute())}],
    }
