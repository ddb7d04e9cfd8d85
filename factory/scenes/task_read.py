"""Reads the pick-and-place task of an (English) request: what to pick, where from, where to
put it, and whether the robot must travel to do so.

The rules, with the word tables of :mod:`.task_words`:

1. "<pick verb> the X [from the A [in the R]] [and <place verb> it] <preposition> the Y
   [in the R']": X is the object, A the support it is picked from (``source``, where named),
   Y the place target, R' the room of the place where named.
2. The robot travels (``travel``: the mobile task) when a travel verb moves X ("carry",
   "bring", "deliver", ...); or a destination preposition ("to", "onto", ...) names a
   support (:data:`~.task_words.SUPPORT_WORDS`) other than A; or Y is a room ("to the
   kitchen": Y becomes that room's first support furniture); or the place's room differs from
   the pick support's room or from another room the request names.
3. Otherwise the task is the fixed one: X on A (or on the largest table when no A is named)
   and Y on the same support, within the arm's reach.

The reading is deterministic: the same text gives the same :class:`TaskSpec`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

from factory.scenes.room_mentions import find_rooms
from factory.scenes.task_words import (
    ARTICLES,
    DESTINATION_PREPOSITIONS,
    PICK_VERBS,
    PLACE_ENDS,
    PLACE_VERBS,
    RELATIONS,
    SUPPORT_WORDS,
    TRAVEL_VERBS,
)

__all__ = ["TaskSpec", "read_task"]


@dataclass
class TaskSpec:
    """A pick-and-place task read from text: what to pick and where to put it.

    Attributes:
        pick: the object to pick ("mug").
        target: the place target: a container or surface near the pick ("bowl"), or for a
            travelling task the support it goes onto ("desk").
        relation: ``in`` or ``on``.
        instruction: the request text.
        source: the support named by "from the <source>" (where the object starts); ``""``
            when the text names no start.
        travel: the robot must drive to put it there (the mobile task's requests).
        place_room: the room type the place is named in ("the desk in the study": office),
            ``""`` if none.
    """

    pick: str
    target: str
    relation: str = "in"
    instruction: str = ""
    source: str = ""
    travel: bool = False
    place_room: str = ""


def _alt(words: tuple[str, ...] | list[str]) -> str:
    return "|".join(re.escape(w) for w in sorted(words, key=len, reverse=True))


_NAME = r"[^\W\d_][\w'-]*(?:\s+[^\W\d_][\w'-]*)*?"


@cache
def _pattern() -> re.Pattern[str]:
    arts = rf"(?:(?:{_alt(ARTICLES)})\s+)?"
    return re.compile(
        rf"\b(?P<verb>{_alt(PICK_VERBS)})\s+{arts}(?P<pick>{_NAME})\s+(?:up\s+)?"
        rf"(?:(?:from|off)\s+(?:of\s+)?{arts}(?P<source>{_NAME})"
        rf"(?:\s+in\s+{arts}(?P<source_room>{_NAME}))?\s*,?\s+)?"
        rf"(?:(?:and\s+)?(?:then\s+)?(?P<verb2>{_alt(PLACE_VERBS)})\s+(?:it|them)\s+)?"
        rf"(?P<rel>{_alt(list(RELATIONS))})\s+{arts}(?P<rest>[^,.;!?]+)"
    )


@cache
def _end_pattern() -> re.Pattern[str]:
    return re.compile(rf"\s+(?:{_alt(PLACE_ENDS)})\b")


def _strip(name: str) -> str:
    words = name.strip().rstrip(".").split()
    while words and words[0] in ARTICLES:
        words = words[1:]
    while words and words[-1] in ("in", "on", "inside"):  # Chinese 碗里: "bowl in"
        words = words[:-1]
    return " ".join(words)


def _room_of(phrase: str) -> str:
    """The room type a phrase is, when the whole phrase names a room ("" otherwise)."""
    if not phrase:
        return ""
    rooms = [r for r in find_rooms(f"the {phrase}") if not r.weak]
    whole = [r for r in rooms if r.phrase.strip().lower().endswith(phrase.split()[-1])]
    return whole[0].room_type if whole and len(phrase.split()) <= 3 else ""


def _is_support(name: str) -> bool:
    return any(name == w or name.endswith(f" {w}") for w in SUPPORT_WORDS)


def _room_support(room_type: str) -> str:
    """The first support furniture of a room type ("to the kitchen": the kitchen island)."""
    from factory.scenes.rooms import ROOM_TYPES

    rt = ROOM_TYPES.get(room_type)
    for item in rt.items if rt is not None else ():
        if not item.rule.startswith("on:") and _is_support(item.text.lower()):
            return item.text.lower()
    return "table"


def _split_place(rest: str) -> tuple[str, str]:
    """(target, its room type) of the words after the preposition: "desk in the study"."""
    m = _end_pattern().search(rest)
    if m is None:
        return _strip(rest), ""
    target, after = rest[: m.start()], rest[m.start() :].strip()
    room = ""
    if re.match(r"in\s+(?:the|a|my|our)\s+", after):
        tail = re.sub(r"^in\s+(?:the|a|my|our)\s+", "", after)
        n = _end_pattern().search(tail)
        room = _room_of(_strip(tail[: n.start()] if n else tail))
    return _strip(target), room


def _other_rooms(text: str, place_room: str) -> bool:
    """Another room than ``place_room`` is named in the text."""
    return any(r.room_type != place_room for r in find_rooms(text) if not r.weak)


def read_task(text: str) -> TaskSpec | None:
    """Reads "pick up the mug from the table and put it in the bowl" style instructions
    (English: a foreign request is read through its English reading).

    Args:
        text: the request.

    Returns:
        the task, or None when the text asks for none.
    """
    low = text.lower().replace("\u2019", "'")
    m = _pattern().search(low)
    if m is None:
        return None
    pick = _strip(m.group("pick"))
    source = _strip(m.group("source") or "")
    source_room = _room_of(_strip(m.group("source_room") or ""))
    rel = m.group("rel")
    target, place_room = _split_place(m.group("rest"))
    if not pick or not target:
        return None
    target_room = _room_of(target)
    if target_room:  # "bring the mug to the kitchen"
        place_room, target = target_room, _room_support(target_room)
    verbs = {m.group("verb").split()[0], (m.group("verb2") or "")}
    travel = (
        bool(verbs & TRAVEL_VERBS)
        or bool(target_room)
        or (rel in DESTINATION_PREPOSITIONS and _is_support(target) and target != source)
        or bool(place_room and source_room and place_room != source_room)
        or bool(place_room and _other_rooms(low[: m.start()], place_room))
    )
    return TaskSpec(
        pick=pick,
        target=target,
        relation=RELATIONS[rel],
        instruction=text,
        source=source,
        travel=travel,
        place_room=place_room,
    )
