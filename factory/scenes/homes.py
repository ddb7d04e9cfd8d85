"""Whole homes: which words ask for one ("a flat", "a family home", "a villa") and its rooms.

``HOMES`` is a literal dict, home word -> :class:`HomeProgram` (the bedrooms and the common
rooms a home of that kind has). :func:`find_home` reads the home word of a request, telling a
home ("a house with a garden") from a home word that only qualifies something else ("a house
plant", "a flat screen", "the kitchen of an apartment", "a home office").
:func:`home_rooms` merges the program with the rooms the request names ("a flat with two
bedrooms and a study") and with a room count ("a four-room apartment").
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

from factory.scenes.room_mentions import NUMBERS, RoomMention, number

MAX_HOME_ROOMS = 8
"""The most rooms one home gets."""
MAX_SAME_ROOMS = 3
"""The most rooms of one type a count asks for ("five bedrooms" gives three)."""


@dataclass(frozen=True)
class HomeProgram:
    """The rooms of a home: ``sleeping`` rooms come first, then what the request names, then
    the ``common`` rooms."""

    sleeping: tuple[str, ...]
    common: tuple[str, ...]


_FLAT = HomeProgram(("bedroom",), ("living room", "kitchen", "bathroom"))
_STUDIO = HomeProgram((), ("studio", "bathroom"))
_FAMILY = HomeProgram(
    ("bedroom", "children's room"), ("living room", "kitchen", "dining room", "bathroom")
)
_VILLA = HomeProgram(
    ("bedroom", "bedroom"), ("living room", "kitchen", "dining room", "bathroom", "bathroom")
)
_MANSION = HomeProgram(
    ("bedroom", "bedroom", "bedroom"),
    ("living room", "kitchen", "dining room", "library", "bathroom"),
)

HOMES: dict[str, HomeProgram] = {
    "apartment": _FLAT,
    "flat": _FLAT,
    "condo": _FLAT,
    "condominium": _FLAT,
    "house": _FLAT,
    "home": _FLAT,
    "townhouse": _FLAT,
    "town house": _FLAT,
    "row house": _FLAT,
    "cottage": _FLAT,
    "bungalow": _FLAT,
    "cabin": _FLAT,
    "chalet": _FLAT,
    "duplex": _FLAT,
    "loft": _FLAT,
    "residence": _FLAT,
    "studio apartment": _STUDIO,
    "studio flat": _STUDIO,
    "bedsit": _STUDIO,
    "efficiency apartment": _STUDIO,
    "family home": _FAMILY,
    "family house": _FAMILY,
    "family apartment": _FAMILY,
    "family flat": _FAMILY,
    "villa": _VILLA,
    "penthouse": _VILLA,
    "mansion": _MANSION,
    "manor": _MANSION,
}
"""Home word -> its room program."""

OPEN_PLAN_WORDS: tuple[str, ...] = (
    "open-plan",
    "open plan",
    "open-concept",
    "open concept",
    "open space",
    "open living",
    "loft",
)
"""Words that ask for an open plan: the day rooms of the home are one open space."""
OPEN_PLAN_ROOMS: frozenset[str] = frozenset({"living room", "kitchen", "dining room", "studio"})
"""The room types an open plan joins into one space (zones of it): no wall between them but
short stubs at the ends of the wall they share."""


def is_open_plan(text: str) -> bool:
    """Whether an (English) request asks for an open plan (:data:`OPEN_PLAN_WORDS`)."""
    low = text.lower()
    return any(re.search(rf"\b{re.escape(w)}\b", low) for w in OPEN_PLAN_WORDS)


ROOMS_BY_COUNT: tuple[str, ...] = (
    "bedroom",
    "kitchen",
    "bathroom",
    "living room",
    "bedroom",
    "dining room",
    "office",
    "bedroom",
)
"""The rooms of an "N-room" home, first needed first (one room: a studio)."""

_ORDER = ("living room", "kitchen", "dining room", "office", "bathroom")
_SLEEPING = frozenset({"bedroom", "children's room", "nursery", "guest room"})

_NOT_HOME_AFTER = frozenset(
    {
        "screen",
        "screens",
        "surface",
        "surfaces",
        "pack",
        "roof",
        "party",
        "music",
        "keys",
        "key",
        "building",
        "block",
        "number",
        "rules",
        "warming",
        "cat",
        "dog",
        "paint",
        "top",
        "iron",
        "file",
        "sheet",
        "weave",
        "tire",
        "tyre",
    }
)
"""Words after a home word that make it a kind of thing ("a flat screen", "a house party")."""
_NOT_HOME_BEFORE = frozenset(
    {"at", "like", "nursing", "care", "retirement", "funeral", "doll", "coffee", "tree"}
)
"""Words before "home"/"house" that make it something else ("at home", "a doll house")."""
_CONTEXT = re.compile(
    r"^\s*(?:in|of|inside|within|at|from)\s+(?:(?:a|an|the|my|our|his|her|their|this)\s+)?"
    r"(?:[\w-]+\s+){0,3}$"
)
_N_ROOMS = re.compile(rf"(?<![\w-])(?P<n>\d{{1,2}}|{'|'.join(NUMBERS)})[\s-]+rooms?(?:ed)?(?!\w)")


@dataclass(frozen=True)
class HomeMatch:
    """A home word in the request: the word, where it is, and the room count if one is given
    ("a four-room apartment": 4)."""

    word: str
    start: int
    end: int
    rooms: int | None = None


@cache
def _home_re(word: str) -> re.Pattern[str]:
    return re.compile(rf"(?<![\w-]){re.escape(word)}s?(?![\w-])")


def _never(word: str) -> bool:
    return False


def _names_the_home(
    low: str, start: int, end: int, rooms: list[RoomMention], is_object: Callable[[str], bool]
) -> bool:
    words_before = low[:start].split()
    if words_before and words_before[-1] in _NOT_HOME_BEFORE:
        return False
    if any(r.start <= start < r.end or start <= r.start < end for r in rooms):
        return False  # inside a room's name ("home office"); or over one ("studio apartment")
    if any(re.fullmatch(r"[\s-]*", low[end : r.start]) for r in rooms if r.start >= end):
        return False  # "an apartment kitchen", "a loft bedroom": one room
    nxt = re.match(r"\s*([\w']+)", low[end:])
    if nxt is not None and (nxt.group(1) in _NOT_HOME_AFTER or is_object(nxt.group(1))):
        return False  # "a house plant", "a flat screen", "a loft bed"
    before = [r for r in rooms if r.end <= start and not r.weak]
    return not (len(before) == 1 and _CONTEXT.match(low[before[0].end : start]))


def find_home(
    text: str, rooms: list[RoomMention], is_object: Callable[[str], bool] = _never
) -> HomeMatch | None:
    """The home a request asks for, or ``None`` for a single room.

    Args:
        text: the (English) request.
        rooms: the rooms it names (:func:`~.room_mentions.find_rooms`), to tell "a home
            office" or "the kitchen of a flat" (one room) from "a flat with a kitchen".
        is_object: whether a word names an object ("a loft bed" is a bed, not a loft).
    """
    low = text.lower()
    for word in sorted(HOMES, key=len, reverse=True):
        if word.split()[0] not in low:
            continue
        for m in _home_re(word).finditer(low):
            inside = [r for r in rooms if not (r.end <= m.start() or m.end() <= r.start)]
            if inside and all(len(r.phrase) < len(m.group(0)) for r in inside):
                rest = [r for r in rooms if r not in inside]  # "studio apartment" beats "studio"
            else:
                rest = rooms
            if _names_the_home(low, m.start(), m.end(), rest, is_object):
                n = _N_ROOMS.search(low)
                count = None if n is None else number(n.group("n"))
                return HomeMatch(word, m.start(), m.end(), count)
    return None


def home_rooms(home: HomeMatch, named: list[RoomMention]) -> list[str]:
    """The room types of a home: its program merged with the rooms the request names.

    Named rooms come in the order written, each as often as its count says (at most
    :data:`MAX_SAME_ROOMS`); the program adds what is missing (bedrooms first, the common
    rooms last) unless the count of that type was given. An "N-room" home gets N rooms.
    """
    mid: list[str] = []
    counted: set[str] = set()
    for r in named:
        if r.room_type == "studio":
            continue  # a studio is a whole flat, not one of its rooms
        if r.count is not None:
            counted.add(r.room_type)
            n = max(1, min(r.count, MAX_SAME_ROOMS))
            mid += [r.room_type] * max(0, n - mid.count(r.room_type))
        elif r.room_type not in mid:
            mid.append(r.room_type)
    if home.rooms is not None:
        return _by_count(home.rooms, mid)
    program = HOMES[home.word]
    have = Counter(mid)
    front: list[str] = []
    back: list[str] = []
    for part, out in ((program.sleeping, front), (program.common, back)):
        for t in part:
            if t in counted:
                continue
            if have[t] > 0:
                have[t] -= 1
            else:
                out.append(t)
    return (front + mid + back)[:MAX_HOME_ROOMS]


def _by_count(n: int, mid: list[str]) -> list[str]:
    n = max(1, min(n, MAX_HOME_ROOMS))
    if n <= 2 and not mid:
        return ["studio", "bathroom"][:n]
    have = Counter(mid)
    added: list[str] = []
    for t in ROOMS_BY_COUNT:
        if len(mid) + len(added) >= n:
            break
        if have[t] > 0:
            have[t] -= 1
        else:
            added.append(t)
    front = [t for t in added if t in _SLEEPING]
    back = sorted((t for t in added if t not in _SLEEPING), key=_ORDER.index)
    return (front + mid + back)[:MAX_HOME_ROOMS]
