"""Placement constraints read from text: "a lamp on the nightstand", "a tv stand facing the
sofa", "a plant in the corner", "a painting on the wall", "a chair next to the desk".

The object's own words come first; the constraint phrase names a rule and, where it refers to
another object ("the desk"), the id of the first object of that category in the scene.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Constraint:
    """What a text placement request asks for."""

    text: str
    placement: str = "floor"
    rule: str = "wall"
    target: str | None = None
    target_text: str | None = None


_PATTERNS: tuple[tuple[str, str, str], ...] = (
    (r"\s(?:mounted\s+)?on\s+the\s+wall\b", "wall", "mount"),
    (r"\s(?:hanging\s+)?above\s+the\s+(?P<t>.+)$", "wall", "mount"),
    (r"\sagainst\s+(?:a|the)\s+wall\b", "floor", "wall"),
    (r"\sin\s+(?:a|the)\s+corner\b", "floor", "corner"),
    (r"\sin\s+the\s+(?:middle|center|centre)\b", "floor", "center"),
    (r"\sfacing\s+(?:the|a|an)\s+(?P<t>.+)$", "floor", "facing"),
    (r"\saround\s+(?:the|a|an)\s+(?P<t>.+)$", "floor", "around"),
    (r"\s(?:next\s+to|beside|near|by)\s+(?:the|a|an)\s+(?P<t>.+)$", "floor", "near"),
    (r"\s(?:on\s+top\s+of|on|onto|inside|in|into)\s+(?:the|a|an)\s+(?P<t>.+)$", "on_top", ""),
)


def parse_constraint(text: str, scene: Any) -> Constraint:
    """Splits a placement request into the object text and its constraint.

    ``scene`` resolves "the <thing>" to an object id (first object whose category matches).
    Unknown references leave ``target`` empty (the caller reports it).
    """
    from factory.assets import resolve

    low = " " + text.strip().lower()
    for pattern, placement, rule in _PATTERNS:
        m = re.search(pattern, low)
        if not m:
            continue
        obj_text = low[: m.start()].strip() or text
        ref = m.groupdict().get("t")
        target = None
        if ref:
            ref = ref.strip().rstrip(".")
            category = resolve(ref).spec.category
            target = next((o.id for o in scene.objects if o.category == category), None)
            if target is None:
                target = next((o.id for o in scene.objects if o.id == ref.replace(" ", "_")), None)
        return Constraint(obj_text, placement, rule or "wall", target, ref)
    return Constraint(text.strip())
