"""The rule-based visual critic: structured suggestions for the agent.

Checks: task objects missing or unmarked; expected companions (chairs at a table, a lamp on
a nightstand, books on a shelf, a TV on a TV stand); sparse regions of the floor to fill with
background objects; blocked doors; objects outside their room; a room much emptier than its
type's usual furniture. Every suggestion names a tool call that would address it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.scenes.footprint import overlaps

COMPANIONS: dict[str, tuple[str, str, str]] = {
    # support category -> (companion text, placement, rule)
    "dining_table": ("chair", "floor", "around"),
    "desk": ("office chair", "floor", "around"),
    "conference_table": ("office chair", "floor", "around"),
    "nightstand": ("table lamp", "on_top", ""),
    "bookshelf": ("book", "on_top", ""),
    "tv_stand": ("tv", "on_top", ""),
    "sofa": ("cushion", "on_top", ""),
    "bed": ("nightstand", "floor", "near"),
}
"""What a piece of furniture usually comes with."""

SPARSE_CELL = 1.0


def visual_critic(state: Any, min_objects: int = 25) -> dict[str, Any]:
    """Suggestions for the scene in ``state`` (a :class:`~.placement.SceneState`).

    Returns:
        ``{"satisfied": bool, "suggestions": [{"issue", "detail", "call": {tool, args}}]}``.
    """
    scene = state.scene
    suggestions: list[dict[str, Any]] = []
    by_support: dict[str, list[Any]] = {}
    for o in scene.objects:
        if o.placement.support_id:
            by_support.setdefault(o.placement.support_id, []).append(o)
    # task objects
    if scene.task is not None or any(o.task_role for o in scene.objects):
        roles = {o.task_role for o in scene.objects if o.task_role}
        for role in ("pick", "place_target"):
            if role not in roles:
                suggestions.append(
                    {
                        "issue": "missing task object",
                        "detail": role,
                        "call": {
                            "tool": "place_objects",
                            "args": {"placement": "on_top", "task_role": role},
                        },
                    }
                )
    # companions
    for o in scene.objects:
        rule = COMPANIONS.get(o.category)
        if rule is None:
            continue
        text, placement, how = rule
        near = [
            x
            for x in scene.objects
            if x.category.replace("_", " ") == text
            or (text == "chair" and x.category in ("chair", "office_chair"))
        ]
        has = (
            any(x.placement.support_id == o.id for x in near)
            if placement == "on_top"
            else any(
                np.hypot(x.position.x - o.position.x, x.position.y - o.position.y)
                < max(o.dimensions.width, o.dimensions.length)
                for x in near
            )
        )
        if not has:
            suggestions.append(
                {
                    "issue": "missing companion",
                    "detail": f"{text} for {o.id}",
                    "call": {
                        "tool": "place_objects",
                        "args": {
                            "text": text,
                            "placement": placement,
                            "rule": how or "wall",
                            "target": o.id,
                        },
                    },
                }
            )
    # blocked doors and objects outside rooms
    for room in scene.rooms:
        for zone in state.door_zones(room):
            for o in scene.objects:
                if o.placement.kind == "floor" and overlaps(state.footprint(o), zone):
                    suggestions.append(
                        {
                            "issue": "blocked door",
                            "detail": o.id,
                            "call": {
                                "tool": "move_object",
                                "args": {"object_id": o.id, "rule": "free"},
                            },
                        }
                    )
        x0, y0, x1, y1 = state.interior(room)
        for o in scene.objects:
            if o.room_id == room.id and not (
                x0 - 0.05 <= o.position.x <= x1 + 0.05 and y0 - 0.05 <= o.position.y <= y1 + 0.05
            ):
                suggestions.append(
                    {
                        "issue": "outside room",
                        "detail": o.id,
                        "call": {"tool": "remove_object", "args": {"object_id": o.id}},
                    }
                )
        # sparse floor cells
        floor = [
            state.footprint(o)
            for o in scene.objects
            if o.room_id == room.id and o.placement.kind == "floor"
        ]
        empty = 0
        for cx in np.arange(x0 + SPARSE_CELL / 2, x1, SPARSE_CELL):
            for cy in np.arange(y0 + SPARSE_CELL / 2, y1, SPARSE_CELL):
                if all(np.hypot(f.x - cx, f.y - cy) > SPARSE_CELL * 1.2 for f in floor):
                    empty += 1
        if empty >= 3:
            suggestions.append(
                {
                    "issue": "sparse area",
                    "detail": f"{empty} empty m² in {room.id}",
                    "call": {
                        "tool": "place_objects",
                        "args": {"text": "potted plant", "placement": "floor", "rule": "corner"},
                    },
                }
            )
    if len(scene.objects) < min_objects:
        suggestions.append(
            {
                "issue": "sparse room",
                "detail": f"{len(scene.objects)} objects (< {min_objects})",
                "call": {"tool": "place_objects", "args": {"text": "book", "placement": "on_top"}},
            }
        )
    return {"satisfied": not suggestions, "suggestions": suggestions}
