"""Whether the episodes that ``stage=demos`` has left to make fit on the episode store's disk.

A GPU node records about 15,000 RGB-D episodes an hour, several MB each: a 64 GiB disk fills
in the tenth kitchen of ``scripts/bench_demos.py``'s GPU defaults. Rather than failing on a
write minutes later (``No space left on device``), the stage measures what its stored episodes
took so far (the disk's free space at the start less now, over the episodes stored since) and
stops before the next scene when the episodes left would not fit (:class:`DiskRoom`): the
stored ones are kept and a re-run, after freeing space or with a smaller
``demos.episodes_per_scene``, goes on from them.
"""

from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from factory.errors import StoreError

__all__ = ["MIN_MEASURED", "DiskFull", "DiskRoom"]

log = logging.getLogger(__name__)

MIN_MEASURED = 32
"""Episodes stored in this run before their size is projected onto the episodes left (fewer
give too loose a measure to stop a run on)."""
MARGIN = 1.05
"""The projection is raised by this factor (writes in flight, the store's metadata)."""


class DiskFull(StoreError):
    """The episodes left would not fit on the episode store's disk."""


def _free(path: Path) -> int:
    """Free bytes on the disk of ``path`` (its nearest existing parent)."""
    while not path.exists() and path != path.parent:
        path = path.parent
    return shutil.disk_usage(path).free


@dataclass
class DiskRoom:
    """The room on the episode store's disk, measured as the stage stores episodes.

    Args:
        store: the shard's episode store folder (``.../shard-<k>.zarr``; may not exist yet).
        stored: episodes in it at the stage's start.
        to_make: episodes the stage has to make (its open slots at the start).
    """

    store: Path
    stored: int
    to_make: int
    free_at_start: int = field(init=False)

    def __post_init__(self) -> None:
        self.free_at_start = _free(self.store)
        log.info(
            "stage=demos: %d episode(s) to make; %.1f GB free on the episode store's disk (%s)",
            self.to_make,
            self.free_at_start / 1e9,
            self.store.parent,
        )

    def check(self, stored_now: int, made_or_failed: int) -> None:
        """Raises :class:`DiskFull` when the episodes left need more than the free space.

        Args:
            stored_now: episodes in the store now.
            made_or_failed: slots of this stage closed so far (stored or given up), so that
                ``to_make - made_or_failed`` are left.

        Raises:
            DiskFull: the episodes left, at the bytes per episode stored so far (measured once
                :data:`MIN_MEASURED` are), would not fit; the message gives the figures and the
                fixes.
        """
        new = stored_now - self.stored
        left = self.to_make - made_or_failed
        if new < max(1, MIN_MEASURED) or left <= 0:
            return
        free = _free(self.store)
        per_episode = max(0, self.free_at_start - free) / new
        need = per_episode * left * MARGIN
        if need <= free:
            return
        raise DiskFull(
            f"stage=demos stopped before the disk filled: the {left} episode(s) left need about "
            f"{need / 1e9:.1f} GB at the {per_episode / 1e6:.1f} MB an episode of the {new} "
            f"stored in this run, and {free / 1e9:.1f} GB are free on {self.store.parent}; free "
            "space there, point run_dir at a bigger disk, or lower demos.episodes_per_scene, "
            f"and re-run: the {stored_now} stored episode(s) are kept and the run goes on from "
            "them"
        )
