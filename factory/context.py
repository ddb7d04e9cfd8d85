"""What every stage function gets and uses: the :class:`StageContext` and :func:`run_items`.

Stage modules import this (not :mod:`factory.runner`, which runs them), so the import graph
stays one-way: ``runner -> stages (registry) -> context``; stage modules -> ``context``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from factory.config import FactoryConfig
from factory.errors import ConfigError
from factory.store import RunStore, Shard

log = logging.getLogger("factory")


@dataclass
class StageContext:
    """What a stage gets: the typed config, the run store and this process's shard."""

    cfg: FactoryConfig
    store: RunStore | None
    shard: Shard

    def require_store(self) -> RunStore:
        if self.store is None:
            raise ConfigError(f"stage {self.cfg.stage!r} needs a run directory: pass run_dir=PATH")
        return self.store


def run_items(what: str, items: list[str], fn: Any, progress: bool = True) -> dict[str, Any]:
    """Applies ``fn(item) -> "done" | "skipped"`` to every item, with a progress bar.

    A :class:`~factory.errors.FactoryError` on one item is logged and the others go on; at the
    end, any failure raises one error naming how many failed and the first reason. Items done
    before a failure stay done (their outputs are complete, written atomically).

    Returns:
        ``{"done": n, "skipped": n, "total": n}``.
    """
    from tqdm import tqdm

    from factory.console import terminal
    from factory.errors import FactoryError, StageFailed

    counts = {"done": 0, "skipped": 0}
    failures: list[tuple[str, str]] = []
    bar = tqdm(items, desc=what, unit="item", disable=not progress or None, file=terminal())
    for item in bar:
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
