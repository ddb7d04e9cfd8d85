"""Request understanding: the rooms, style, condition words and task a text request names.

:func:`parse_request` reads a request (English, Spanish, French, German or Chinese: see
:mod:`.translate`) into a :class:`ParsedRequest`: the room types to build (one room, or a
whole home's program: :mod:`.homes`), the rooms named by owner or purpose
(:mod:`.room_mentions`), the style, condition and material words (:mod:`.style_words`), the
task (pick-and-place, :mod:`.task_read`, or opening and closing a door or drawer,
:mod:`.part_read`), and notes and warnings on what was approximated or not understood. A
request that names no room but an object that opens ("open the fridge door") builds the
object's room (the catalogue's ``rooms``: a kitchen).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from functools import cache, lru_cache

from factory.scenes.homes import find_home, home_rooms, is_open_plan
from factory.scenes.part_read import PartSpec, in_rooms, part_rooms, read_part_task
from factory.scenes.room_meaning import RoomGuess, nearest_room_type
from factory.scenes.room_mentions import PHRASES, RoomMention, find_rooms
from factory.scenes.style_words import COLOURS, CONDITIONS, STYLE_WORDS, read_style
from factory.scenes.task_read import TaskSpec, read_task
from factory.scenes.translate import translate

log = logging.getLogger(__name__)

DEFAULT_ROOM = "living room"
"""The room built when the request names none."""

__all__ = [
    "DEFAULT_ROOM",
    "STYLE_WORDS",
    "ParsedRequest",
    "PartSpec",
    "TaskSpec",
    "names_a_room",
    "parse_any_task",
    "parse_part_task",
    "parse_request",
    "parse_task",
    "primary_room_type",
    "request_task",
    "room_types_in",
    "style_of",
]


def parse_task(text: str) -> TaskSpec | None:
    """Reads "pick up the mug [from the table] and put it in the bowl" style instructions
    (English; the rules: :mod:`.task_read`)."""
    return read_task(text)


def parse_part_task(text: str) -> PartSpec | None:
    """Reads "open the fridge door", "close the top drawer of the nightstand" style
    instructions (English; the rules: :mod:`.part_read`)."""
    return read_part_task(text)


def parse_any_task(text: str) -> TaskSpec | PartSpec | None:
    """The task an instruction asks for: pick-and-place (:func:`parse_task`) first, else
    opening or closing a part (:func:`parse_part_task`); None if neither."""
    return parse_task(text) or parse_part_task(text)


def request_task(request: str, task: str | None = None) -> TaskSpec | PartSpec | None:
    """The task a scene of ``request`` is made for: ``task`` (``generate.task``, a separate
    instruction) when given, else the request's own (:attr:`ParsedRequest.task`); a put-away
    task's drawer read in the request's rooms either way (:func:`~.part_read.in_rooms`)."""
    if not task:
        return parse_request(request).task
    spec = parse_any_task(task)
    if isinstance(spec, PartSpec):
        return in_rooms(spec, parse_request(request).room_types)
    return spec


@dataclass(frozen=True)
class ParsedRequest:
    """What a request asks for.

    Attributes:
        text: the request as written.
        english: its English reading (``text`` itself for an English request).
        language: ``"en"``, ``"es"``, ``"fr"``, ``"de"`` or ``"zh"``.
        room_types: the rooms to build, in order (keys of
            :data:`~factory.scenes.rooms.ROOM_TYPES`); one for a single room.
        home: the home word ("apartment", "family home", ...), ``""`` for a single room.
        rooms: the rooms the request names, where and how many.
        style: the first design style named, ``""`` if none.
        styles: every design style named.
        conditions: condition kinds named (``rust``, ``dust``, ``mud``, ``wear``, ``gold``,
            ``luxury``, ...: :data:`~.style_words.CONDITIONS`).
        condition_words: the condition words as written (in English).
        materials: materials named or brought by a condition (names of
            :data:`factory.assets.physics.MATERIALS`).
        colours: colour words named (English: :data:`~.style_words.COLOURS`).
        translated: (foreign word, English) for each word translated.
        unknown: words not understood (foreign words no table knows).
        notes: what was approximated and why ("'veterinary clinic': nearest room type by
            meaning: exam room (score 0.85)").
        warnings: what the user should know (words not understood, no room named).
        guess: the room type chosen by meaning when no room word matched (``None`` if none).
        open_plan: the request asks for an open plan ("an open-plan loft"): the home's day
            rooms are zones of one open space (:data:`~.homes.OPEN_PLAN_WORDS`).
    """

    text: str
    english: str
    language: str
    room_types: tuple[str, ...]
    home: str = ""
    rooms: tuple[RoomMention, ...] = ()
    style: str = ""
    styles: tuple[str, ...] = ()
    conditions: tuple[str, ...] = ()
    condition_words: tuple[str, ...] = ()
    materials: tuple[str, ...] = ()
    colours: tuple[str, ...] = ()
    translated: tuple[tuple[str, str], ...] = ()
    unknown: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    guess: RoomGuess | None = None
    open_plan: bool = False

    @property
    def names_a_room(self) -> bool:
        """The request names a room or a home, or a room type is near its words in meaning
        (else :data:`DEFAULT_ROOM` stands in)."""
        return bool(self.home or self.rooms or self.guess)

    @property
    def task(self) -> TaskSpec | PartSpec | None:
        """The task of the request (:func:`parse_any_task`), read from its English reading;
        a put-away request's drawer in the request's rooms (:func:`~.part_read.in_rooms`)."""
        spec = parse_any_task(self.english)
        return in_rooms(spec, self.room_types) if isinstance(spec, PartSpec) else spec

    def summary(self) -> dict[str, object]:
        """A JSON-ready digest for tool results and reports (empty fields left out)."""
        out: dict[str, object] = {
            "language": self.language,
            "room_types": list(self.room_types),
            "home": self.home,
            "style": self.style,
            "conditions": list(self.conditions),
            "materials": list(self.materials),
            "colours": list(self.colours),
            "english": self.english if self.english != self.text else "",
            "translated": [list(w) for w in self.translated],
            "unknown": list(self.unknown),
            "notes": list(self.notes),
            "warnings": list(self.warnings),
        }
        return {k: v for k, v in out.items() if v}


@cache
def _english_vocabulary() -> frozenset[str]:
    """English words the parser or the asset library understands (object, room, style,
    condition and material names), so that they are not reported in a foreign request."""
    from factory.assets.catalog import CATEGORIES
    from factory.assets.physics import ALIASES, MATERIALS

    phrases = [
        *(n.replace("_", " ") for n in CATEGORIES),
        *(s for c in CATEGORIES.values() for s in c.synonyms),
        *PHRASES,
        *STYLE_WORDS,
        *CONDITIONS,
        *COLOURS,
        *MATERIALS,
        *ALIASES,
    ]
    words = {w for p in phrases for w in re.split(r"[\s-]+", p.lower()) if w}
    return frozenset(words | {w + "s" for w in words})


def _known(word: str) -> bool:
    return word in _english_vocabulary()


@cache
def _object_words() -> frozenset[str]:
    """The last word of every object name and synonym of the asset catalog ("bed",
    "plant"), plural forms too."""
    from factory.assets.catalog import CATEGORIES

    phrases = [
        *(n.replace("_", " ") for n in CATEGORIES),
        *(s for c in CATEGORIES.values() for s in c.synonyms),
    ]
    heads = {p.lower().split()[-1] for p in phrases if p.strip()}
    return frozenset(heads | {w + "s" for w in heads})


def _is_object(word: str) -> bool:
    return word in _object_words()


@cache
def _look_words() -> frozenset[str]:
    """Style, condition and material words: they say how a room looks, not what it is."""
    from factory.assets.physics import MATERIALS

    phrases = [*STYLE_WORDS, *CONDITIONS, *MATERIALS]
    return frozenset(w for p in phrases for w in re.split(r"[\s-]+", p.lower()) if w)


def _guess_room(english: str, unknown: tuple[str, ...]) -> RoomGuess | None:
    """The nearest room type by meaning to a request that names no room; object, style and
    untranslated words are left out."""
    skip = {w.lower() for w in unknown}
    return nearest_room_type(english, lambda w: w in skip or _is_object(w) or w in _look_words())


@lru_cache(maxsize=512)
def parse_request(text: str) -> ParsedRequest:
    """Reads a request (cached: the result is frozen).

    Args:
        text: e.g. ``"a dusty child's room"``, ``"a three-bedroom family home"``,
            ``"una cocina con una taza"``.

    Returns:
        the rooms to build, style and condition words, translations, notes and warnings.
    """
    tr = translate(text, _known)
    english = tr.text
    rooms = find_rooms(english)
    home = find_home(english, rooms, _is_object)
    notes = [f"{r.phrase!r}: {r.note}" for r in rooms if r.note]
    part = read_part_task(english)
    part_room = part_rooms(part.category)[:1] if part is not None and part.category else ()
    guess = None if home is not None or rooms or part_room else _guess_room(english, tr.unknown)
    if home is not None:
        named = [r for r in rooms if r.end <= home.start or r.start >= home.end]
        room_types = tuple(home_rooms(home, named))
    elif rooms:
        room_types = (_main_room(rooms).room_type,)
    elif part is not None and part_room:
        room_types = part_room
        notes.append(f"{part.named!r}: no room named; built its room, a {part_room[0]}")
    elif guess is not None:
        room_types = (guess.room_type,)
        notes.append(
            f"{' '.join(guess.words)!r}: no room type of that name; nearest by meaning: "
            f"{guess.room_type} (score {guess.score:.2f})"
        )
    else:
        room_types = (DEFAULT_ROOM,)
    warnings = [tr.warning] if tr.unknown else []
    if home is None and not rooms and guess is None and not part_room:
        warnings.append(
            f"no known room type in {text!r} (another language?); built a {DEFAULT_ROOM}"
        )
    looks = read_style(english)
    parsed = ParsedRequest(
        text=text,
        english=english,
        language=tr.language,
        room_types=room_types,
        home="" if home is None else home.word,
        rooms=tuple(rooms),
        style=looks.style,
        styles=looks.styles,
        conditions=looks.conditions,
        condition_words=looks.condition_words,
        materials=looks.materials,
        colours=looks.colours,
        translated=tr.words,
        unknown=tr.unknown,
        notes=tuple(notes),
        warnings=tuple(warnings),
        guess=guess,
        open_plan=len(room_types) > 1 and is_open_plan(english),
    )
    for note in notes:
        log.info("request %r: %s", text, note)
    return parsed


def _main_room(rooms: list[RoomMention]) -> RoomMention:
    """The room of a single-room request: the longest phrase, the first of equals."""
    return max(rooms, key=lambda r: (len(r.phrase), -r.start))


def room_types_in(request: str) -> list[str]:
    """The room types a request asks for: several for a home, else one."""
    return list(parse_request(request).room_types)


def primary_room_type(request: str) -> str:
    """The first room type a request asks for (names scenes and jobs)."""
    return parse_request(request).room_types[0]


def names_a_room(request: str) -> bool:
    """The request names a room or a home (in any language read)."""
    return parse_request(request).names_a_room


def style_of(text: str) -> str:
    """The first design style a request names (``""`` if none)."""
    return parse_request(text).style
