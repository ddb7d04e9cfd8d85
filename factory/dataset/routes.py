"""The navigation routes of episodes in ``meta/factory.json``: written by the export, read back.

An episode of a task whose robot drives its base (:attr:`~factory.tasks.base.Task.drives_base`)
records the route it drove (``EpisodeInfo.route``,
:meth:`factory.tasks.mobile_pick_place.plan.MobilePlanner.route_record`): the route check's base
poses it drove to (``pick_pose``, ``place_pose``: x, y m, yaw rad, world frame), their indices
in the check's pose lists (best first) and the check's summary (pose counts, grid cell, lattice
headings, footprint radius, carry front). The export copies it into the episode's entry
(:func:`route_entry`); :func:`episode_routes` reads them back by dataset episode index.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from factory.dataset.layout import meta_layout, meta_task
from factory.errors import StoreError
from factory.tasks import tasks

ROUTE_KEY = "route"
"""Key of an episode's route in its ``meta/factory.json`` entry."""
ROUTE_POSES = ("pick_pose", "place_pose")
"""The route's base poses (x, y m, yaw rad, world frame)."""


def route_entry(info: Any) -> dict[str, Any]:
    """An episode's ``route`` for ``meta/factory.json``: a JSON-ready copy of
    ``EpisodeInfo.route``.

    Raises:
        StoreError: a route without its base poses (re-record the episode).
    """
    route = json.loads(json.dumps(dict(info.route)))
    for key in ROUTE_POSES:
        pose = route.get(key)
        if not isinstance(pose, list) or len(pose) != 3:
            raise StoreError(
                f"episode {info.episode_id!r}: its route has no {key} (x, y, yaw): {pose!r} "
                f"(re-record the episode with stage=demos task={info.task})"
            )
    return dict(route)


def episode_routes(root: str | Path) -> dict[int, dict[str, Any]]:
    """The navigation route of every episode of a dataset whose robot drives its base, by
    dataset episode index (the ``episode_index`` of ``LeRobotDataset``'s frames and of
    ``meta/episodes``).

    Args:
        root: the dataset folder (``LeRobotDataset.root``).

    Raises:
        StoreError: not a factory dataset, one whose robot does not drive, or exported before
            routes were (names the fix).
    """
    path = Path(root) / "meta" / "factory.json"
    if not path.is_file():
        raise StoreError(f"{root} has no meta/factory.json: export it with stage=dataset")
    meta = json.loads(path.read_text())
    if not meta_task(meta).drives_base:
        driving = " or ".join(f"task={t.name}" for t in tasks() if t.drives_base)
        raise StoreError(
            f"{root} holds {meta_layout(meta)}-base episodes, which have no route: routes are "
            f"recorded by stage=demos {driving}"
        )
    out: dict[int, dict[str, Any]] = {}
    for ep in meta["episodes"]:
        if ROUTE_KEY not in ep:
            raise StoreError(
                f"{root}: episode {ep.get('episode_id')!r} has no route in meta/factory.json "
                "(exported before routes were): re-export with stage=dataset force=true"
            )
        out[int(ep["episode_index"])] = dict(ep[ROUTE_KEY])
    return out
