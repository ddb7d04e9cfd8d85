"""The rooms an (English) request names, where, and how many of each.

Three ways to name a room are read, most specific first:

1. its owner: "a child's room", "the kids' bedroom", "a room for a teenager", "a 7-year-old's
   room" (:data:`~.room_words.OWNERS`);
2. a room type's name or alias (:data:`~.rooms.ROOM_TYPES`) or a purpose word ("home office",
   "den", "pantry": :data:`~.room_words.ROOM_WORDS`), singular or plural;
3. the same words used as an object's kind ("a bar stool", "a kitchen table") are *weak*
   mentions: they count only when nothing else names a room.

A number just before a mention is its count ("two bedrooms", "a 3-bedroom house").
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache

from factory.scenes.room_words import CHILD_AGE, OBJECT_HEADS, OWNER_ROOMS, OWNERS, ROOM_WORDS
from factory.scenes.rooms import ROOM_TYPES

NUMBERS: dict[str, int] = {
    "one": 1,
    "single": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
    "ten": 10,
    "eleven": 11,
    "twelve": 12,
}
"""Number words read as counts and ages (digits are read as well)."""

_HOME_ALIASES = frozenset({"apartment", "loft", "studio apartment"})
"""Aliases of ``ROOM_TYPES`` that name a whole home instead (read by :mod:`.homes`)."""


@dataclass(frozen=True)
class RoomMention:
    """One room named in the request.

    Attributes:
        room_type: a key of :data:`~factory.scenes.rooms.ROOM_TYPES`.
        phrase: the words that named it, as written.
        start: where they start in the (lower-case) text.
        end: where they end.
        count: the number written before it ("two bedrooms": 2), ``None`` if none.
        note: why the type is only the closest one ("no pantry type: ..."), else ``""``.
        weak: the words name an object's kind ("a bar stool"), not a room.
    """

    room_type: str
    phrase: str
    start: int
    end: int
    count: int | None = None
    note: str = ""
    weak: bool = False


def _phrases() -> dict[str, tuple[str, str]]:
    """Phrase -> (room type, note): type names first, then purpose words, then aliases."""
    table: dict[str, tuple[str, str]] = {name: (name, "") for name in ROOM_TYPES}
    for phrase, word in ROOM_WORDS.items():
        table.setdefault(phrase, (word.room_type, word.note))
    for name, rt in ROOM_TYPES.items():
        for alias in rt.aliases:
            if alias not in _HOME_ALIASES:
                table.setdefault(alias, (name, ""))
    return table


PHRASES: dict[str, tuple[str, str]] = _phrases()
"""Every phrase that names a room type -> (room type, note)."""


@cache
def _phrase_re(phrase: str) -> re.Pattern[str]:
    forms = [re.escape(phrase) + "(?:s|es)?"]
    if phrase.endswith("y"):
        forms.append(re.escape(phrase[:-1]) + "ies")
    return re.compile(rf"(?<!\w)(?:{'|'.join(forms)})(?!\w)")


def _alternation(words: list[str]) -> str:
    return "|".join(re.escape(w) for w in sorted(words, key=len, reverse=True))


_NUM = rf"(?:\d{{1,2}}|{_alternation(list(NUMBERS))})"
_OWNER = rf"(?:(?P<age>{_NUM})[\s-]+years?[\s-]+olds?|(?P<owner>{_alternation(list(OWNERS))}))"
_ROOM = rf"(?P<room>(?:{_alternation(list(OWNER_ROOMS))})(?:s|es)?)"
_FILL = r"(?:(?:a|an|the|my|our|his|her|their|two|three|four|twin|little|young|small|\d+)\s+)*"
_OWNER_FIRST = re.compile(
    rf"(?<![\w-]){_OWNER}(?P<poss>'s|s'|')?(?:[\s-]+(?:themed|style|styled))?\s+"
    rf"(?:(?:own|little|small|shared|cozy|cosy)\s+)?{_ROOM}(?!\w)"
)
_ROOM_FIRST = re.compile(rf"(?<![\w-]){_ROOM}\s+(?:for|of)\s+{_FILL}{_OWNER}(?!\w)")
_COUNT = re.compile(rf"(?<![\w-])(?P<n>{_NUM})[\s-]+(?:[a-z]+\s+)?$")


def number(word: str) -> int:
    """The value of a number word or of digits ("three": 3, "12": 12)."""
    return int(word) if word.isdigit() else NUMBERS[word]


def _owner_type(m: re.Match[str]) -> str | None:
    """The room type an owner match names, ``None`` when the words are a style instead."""
    if m.group("age"):
        age = number(m.group("age"))
        return "nursery" if age <= 2 else "children's room" if age <= CHILD_AGE else "bedroom"
    owner = OWNERS[m.group("owner")]
    bare = m.re is _OWNER_FIRST and not m.group("poss")
    if owner.possessive_only and bare and m.group("room").startswith("bed"):
        return None  # "a princess bedroom": a bedroom in the princess style
    return owner.room_type


def _count_before(text: str, start: int) -> int | None:
    m = _COUNT.search(text[max(0, start - 24) : start])
    return None if m is None else number(m.group("n"))


def _mask(text: str, start: int, end: int) -> str:
    return text[:start] + " " * (end - start) + text[end:]


def find_rooms(text: str) -> list[RoomMention]:
    """The rooms named in ``text`` (English, any case), in the order they are written.

    Overlapping phrases are read once, the more specific (owner, then longer) first. Weak
    mentions are dropped when a room is named otherwise.
    """
    low = text.lower().replace("\u2019", "'").replace("\u2018", "'")
    masked = low
    found: list[RoomMention] = []
    for rx in (_OWNER_FIRST, _ROOM_FIRST):
        for m in rx.finditer(low):
            room_type = _owner_type(m)
            if room_type is None or masked[m.start() : m.end()] != m.group(0):
                continue  # a style word, or read already
            found.append(
                RoomMention(
                    room_type, m.group(0), m.start(), m.end(), _count_before(low, m.start())
                )
            )
            masked = _mask(masked, m.start(), m.end())
    for phrase in sorted(PHRASES, key=len, reverse=True):
        if phrase not in masked and phrase[:-1] not in masked:
            continue
        room_type, note = PHRASES[phrase]
        for m in _phrase_re(phrase).finditer(masked):
            after = masked[m.end() :].split(maxsplit=1)
            weak = bool(after) and after[0].strip(".,;:!?") in OBJECT_HEADS
            found.append(
                RoomMention(
                    room_type,
                    m.group(0),
                    m.start(),
                    m.end(),
                    _count_before(low, m.start()),
                    note,
                    weak,
                )
            )
            masked = _mask(masked, m.start(), m.end())
    strong = [r for r in found if not r.weak]
    return sorted(strong or found, key=lambda r: r.start)
