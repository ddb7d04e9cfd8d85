"""Request understanding: task instructions, styles and the room types a request names."""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass

from factory.scenes.rooms import ROOM_TYPES, room_type_of

log = logging.getLogger(__name__)

STYLE_WORDS = (
    "mid-century",
    "cyberpunk",
    "fairy-tale",
    "princess",
    "scandinavian",
    "industrial",
    "rustic",
    "farmhouse",
    "modern",
    "minimalist",
    "victorian",
    "japanese",
    "boho",
    "art deco",
    "coastal",
    "gothic",
    "retro",
    "futuristic",
)


@dataclass
class TaskSpec:
    """A pick-and-place task read from text: what to pick and where to put it."""

    pick: str
    target: str
    relation: str = "in"
    instruction: str = ""


def parse_task(text: str) -> TaskSpec | None:
    """Reads "pick up the mug and put it in the bowl" style instructions."""
    m = re.search(
        r"(?:pick(?:s)?(?: up)?|grab(?:s)?|move(?:s)?|take(?:s)?)\s+(?:the|a|an)\s+([a-z ]+?)"
        r"\s+(?:and\s+(?:put|place|drop)s?\s+it\s+|from\s+the\s+[a-z ]+?\s+)?"
        r"(in|into|on|onto|to)\s+(?:the|a|an)\s+([a-z ]+)",
        text.lower(),
    )
    if not m:
        return None
    return TaskSpec(
        pick=m.group(1).strip(),
        target=m.group(3).strip().rstrip("."),
        relation=m.group(2),
        instruction=text,
    )


def style_of(text: str) -> str:
    low = text.lower()
    return next((s for s in STYLE_WORDS if s in low), "")


NUMBERS = {"one": 1, "two": 2, "three": 3, "four": 4, "single": 1, "double": 2}

MULTI_ROOM_WORDS = ("apartment", "house", "flat", "condo", "townhouse")
_MULTI_RE = re.compile(r"\b(" + "|".join(MULTI_ROOM_WORDS) + r")\b")


def room_types_in(request: str) -> list[str]:
    """The room types a request asks for: several for an apartment or house, else one."""
    from factory.scenes.rooms import ROOM_TYPES as RT

    low = request.lower()
    found: list[tuple[int, str]] = []
    for name, rt in RT.items():
        if name == "studio":
            continue
        for phrase in (name, *rt.aliases):
            i = low.find(phrase)
            if i >= 0 and not any(n == name for _, n in found):
                found.append((i, name))
    mentioned = [n for _, n in sorted(found)]
    if _MULTI_RE.search(low):
        rooms = []
        for name in mentioned:  # "two bedrooms", "2-bedroom"
            m = re.search(rf"\b({'|'.join(NUMBERS)}|\d)[\s-]*{re.escape(name)}", low)
            n = (
                1
                if m is None
                else NUMBERS.get(m.group(1), int(m.group(1)) if m.group(1).isdigit() else 1)
            )
            rooms += [name] * max(1, min(n, 3))
        for extra in ("living room", "kitchen", "bathroom"):
            if extra not in rooms:
                rooms.append(extra)
        if "bedroom" not in rooms and "studio" not in low:
            rooms.insert(0, "bedroom")
        return rooms[:6]
    return [room_type_of(request)]


def names_a_room(request: str) -> bool:
    low = request.lower()
    return bool(_MULTI_RE.search(low)) or any(
        phrase in low for name, rt in ROOM_TYPES.items() for phrase in (name, *rt.aliases)
    )
