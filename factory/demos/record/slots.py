"""Episode slots of ``stage=demos``: their seeds and ids, the work items that hold them, the
stage's settings a worker gets, and the statistics an item returns.

Task-agnostic: the stage, the CPU item path and the GPU pipeline use them, and so do the task
packages' recording hooks (:class:`~factory.demos.record.scene.DemoScene`).
"""

from __future__ import annotations

import hashlib
from collections import Counter
from dataclasses import dataclass
from typing import Any

from factory.config import DemosConfig

__all__ = [
    "StageEnv",
    "WorkItem",
    "episode_id",
    "episode_seed",
    "item_stats",
    "slots_by_scene",
]


def episode_seed(root: int, scene_id: str, slot: int, attempt: int) -> int:
    """A stable per-episode seed (independent of shard layout, workers and order)."""
    digest = hashlib.sha256(f"{root}/{scene_id}/{slot}/{attempt}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def episode_id(scene_id: str, slot: int) -> str:
    """The id episode slot ``slot`` of a scene is stored under (``<scene_id>-ep<slot>``)."""
    return f"{scene_id}-ep{slot:03d}"


@dataclass(frozen=True)
class WorkItem:
    """A scene and the episode slots to fill in it."""

    scene_id: str
    slots: tuple[int, ...]


def slots_by_scene(items: list[WorkItem]) -> dict[str, list[int]]:
    """The slots of ``items`` per scene, scenes in their first item's order (the GPU
    pipeline takes a scene's slots together)."""
    by_scene: dict[str, list[int]] = {}
    for it in items:
        by_scene.setdefault(it.scene_id, []).extend(it.slots)
    return by_scene


@dataclass(frozen=True)
class StageEnv:
    """What a worker needs besides the item (picklable).

    Attributes:
        run_dir: the run directory.
        store_path: the shard's episode store (``episodes/shard-<k>.zarr``).
        demos: the ``demos.*`` settings.
        task: the registered task (:func:`factory.tasks.get_task`).
        seed: the run's root seed (:func:`episode_seed`).
        nthread: simulation threads of a CPU batch.
    """

    run_dir: str
    store_path: str
    demos: DemosConfig
    task: str
    seed: int
    nthread: int


def item_stats(scene_id: str, **extra: Any) -> dict[str, Any]:
    """A fresh statistics dict of one work item (what :func:`factory.demos.stage.run` sums):
    new episodes, failures by reason, the scene's error, planning seconds per episode and per
    segment, simulation and rendering seconds, frames; then ``extra``."""
    return {
        "scene_id": scene_id,
        "new": 0,
        "failures": Counter(),
        "error": None,
        "plan": [],
        "segments": [],
        "simulate": 0.0,
        "render": 0.0,
        "frames": 0,
        **extra,
    }
