"""The fixed pick-and-place task's feasibility critic: can a scene host its episodes?

Run on every scene made for the task by ``stage=generate``'s last step (another attempt with
another seed when it fails: :mod:`factory.scenes.finish`) and by ``stage=validate``
(``validate.checks.task``). It asks what ``stage=demos`` will ask: the task objects are there
(:func:`~factory.tasks.pick_place.objects.task_objects`), the robot has a free base spot next
to the support (:func:`~factory.tasks.pick_place.plan.setup_scene`, with the clearing it
does), and the episodes' sampler (:func:`~factory.tasks.pick_place.objects.randomize`) puts
the pick object and the target within the arm's reach for at least :data:`SHARE` of
:data:`SEEDS` seeds.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import TaskError
from factory.schema import Scene

__all__ = ["NO_BASE_SPOT", "NO_ROOM", "NO_TASK_OBJECTS", "REASONS", "SEEDS", "SHARE", "feasibility"]

SEEDS = 10
"""Placements tried (seeds of the episodes' sampler)."""
SHARE = 0.5
"""Least share of them that must place the task objects within reach."""

NO_TASK_OBJECTS = "no_task_objects"
NO_BASE_SPOT = "no_base_spot"
NO_ROOM = "no_room"
REASONS = (NO_TASK_OBJECTS, NO_BASE_SPOT, NO_ROOM)
"""Why a scene cannot host the task (``reason``; ``""``: it can)."""


def feasibility(
    scene: Scene, assets_root: str | Path | None, seeds: int = SEEDS, share: float = SHARE
) -> dict[str, Any]:
    """Whether ``scene`` can host the fixed pick-and-place task.

    Args:
        scene: a scene made for the task (its objects carry the task roles).
        assets_root: the run's assets folder.
        seeds: placements tried.
        share: least share of them that must succeed.

    Returns:
        ``{"reason": "" | one of REASONS, "detail": str, "placed": n, "seeds": seeds,
        "cleared": [ids taken out for the base spot or as look-alikes], "seconds": s}``.
    """
    from factory.tasks.pick_place.objects import Workspace, initial_state, randomize, task_objects
    from factory.tasks.pick_place.plan import setup_scene

    t0 = time.perf_counter()

    def verdict(reason: str, detail: str, **more: Any) -> dict[str, Any]:
        return {
            "reason": reason,
            "detail": detail,
            **more,
            "seconds": round(time.perf_counter() - t0, 2),
        }

    try:
        task_objects(scene)
    except TaskError as e:
        return verdict(NO_TASK_OBJECTS, str(e))
    try:
        setup = setup_scene(scene, assets_root, freeze_beyond=0.0)
    except TaskError as e:
        return verdict(NO_BASE_SPOT, str(e))
    qpos = initial_state(setup.model, setup.robot)
    ws, placed = Workspace(), 0
    for s in range(seeds):
        try:
            randomize(
                setup.model,
                qpos,
                setup.scene,
                setup.objects,
                setup.placement,
                ws,
                np.random.default_rng(s),
            )
            placed += 1
        except TaskError:
            pass
    ok = placed >= share * seeds
    detail = (
        f"the sampler placed {setup.objects.pick.id!r} and {setup.objects.target.id!r} on "
        f"{setup.objects.support.id!r} within reach for {placed} of {seeds} seeds"
    )
    return verdict(
        "" if ok else NO_ROOM, detail, placed=placed, seeds=seeds, cleared=list(setup.cleared)
    )
