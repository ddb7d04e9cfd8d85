"""Reads an open or close request: which part (door, drawer) of which object the robot moves.

The rules, with the word tables of :mod:`.task_words` and the asset catalogue's names:

1. "<verb> the [Q] <role> [of the X]" or "<verb> the [Q] X <role>": the verb is one a
   registered task answers to (:attr:`factory.tasks.base.Task.request_verbs`: "open",
   "opens", "shut", ...; the task then claims the request by it), the role word names the
   part (:data:`~.task_words.PART_ROLES`: ``door``, ``drawer``), Q its qualifier
   (:data:`~.task_words.PART_QUALIFIERS`: top / middle / bottom, left / right) and X the
   object, read against the catalogue's category names and synonyms (the longest phrase
   wins: "chest of drawers" is a ``dresser``).
2. The object's *openable* category is the category itself when it is articulated, else its
   catalogue ``articulated_as`` (a ``refrigerator`` stands for the ``upright_fridge``, a
   ``nightstand`` for the ``bedside_cabinet``); a named object that has neither
   ("the garage door", "the oven door") has none, and generating a scene for it is an error
   (:func:`check_part_request`) listing the objects that open.
3. Without an object ("a kitchen where the robot opens the top drawer") any part of that role
   in the room will do (:mod:`factory.tasks.articulated.parts`).
4. "<place verb> the P [away] in the [Q] drawer [of the X]" or "... in the [Q] X drawer": put
   P away in a drawer (``item`` is P's catalogue category); the drawer's object is one of
   :data:`~.task_words.DRAWER_CONTAINERS` (when none is named, the first of them that the
   request's rooms hold, :func:`in_rooms`: a base cabinet in a kitchen, a bedside cabinet in
   a bedroom), checked by :func:`check_part_request`. A place target that is no drawer ("puts
   it in the bowl") is pick-and-place (:mod:`.task_read`).
5. "<place verb> the P [away] in the [Q] X" where X opens by a door with an interior behind
   it (:data:`~.task_words.DOOR_CONTAINERS`: "put the mug in the microwave", "put the bottle
   in the fridge"): put P away behind X's door (``role`` ``door``, the role implied). X a
   cabinet not said which ("put the cup in the cabinet", "the cupboard":
   :data:`~.task_words.CABINET_WORDS`) is the first of :data:`~.task_words.DOOR_CABINETS`
   that the request's rooms hold (a base cabinet in a kitchen, :func:`in_rooms`). Any other X
   ("put the mug in the bowl") is no part task.

The reading is deterministic and English (a foreign request is read through its English
reading, :mod:`.translate`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from functools import cache

from factory.errors import ConfigError
from factory.scenes.task_words import (
    ARTICLES,
    CABINET_WORDS,
    DOOR_CABINETS,
    DOOR_CONTAINERS,
    DRAWER_CONTAINERS,
    PART_QUALIFIERS,
    PART_ROLES,
    PLACE_VERBS,
    STOW_OBJECTS,
)

__all__ = [
    "PartSpec",
    "catalogue_category",
    "check_part_request",
    "in_rooms",
    "openable_category",
    "openable_names",
    "part_rooms",
    "read_part_task",
    "request_verbs",
]


@dataclass(frozen=True)
class PartSpec:
    """An open or close task read from text: the part of an articulated object to move.

    Attributes:
        verb: the verb as written ("opens", "shut"): the task whose ``request_verbs`` hold it
            claims the request.
        role: the part's role word, ``door`` or ``drawer``.
        qualifier: ``top``, ``middle``, ``bottom``, ``left`` or ``right``; ``""`` if none.
        category: the openable catalogue category of the named object (``upright_fridge``);
            ``""`` when the text names no object, or one that does not open.
        named: the object's words as written ("fridge"); ``""`` when none.
        named_category: the catalogue category those words name (``refrigerator``); ``""``
            when the catalogue has none.
        instruction: the request text.
        item: what a "put the mug in the drawer" request puts away, its catalogue category
            (``mug``); ``""`` for an open or close request.
        item_named: the words naming it as written; ``""`` when none.
    """

    verb: str
    role: str
    qualifier: str = ""
    category: str = ""
    named: str = ""
    named_category: str = ""
    instruction: str = ""
    item: str = ""
    item_named: str = ""


def _alt(words: tuple[str, ...] | list[str]) -> str:
    return "|".join(re.escape(w) for w in sorted(words, key=len, reverse=True))


@cache
def request_verbs() -> tuple[str, ...]:
    """Every registered task's request verbs (:attr:`factory.tasks.base.Task.request_verbs`)."""
    from factory.tasks import tasks

    return tuple(dict.fromkeys(v for t in tasks() for v in t.request_verbs))


@cache
def _pattern() -> re.Pattern[str]:
    verbs = _alt(list(request_verbs()))
    roles = _alt(list(PART_ROLES))
    words = r"[a-z][\w'-]*"
    return re.compile(
        rf"\b(?P<verb>{verbs})\s+(?P<pre>(?:{words}\s+){{0,4}}?)(?P<role>{roles})\b"
        rf"(?:\s+(?:of|on|in)\s+(?P<post>{words}(?:\s+{words}){{0,4}}))?"
    )


@cache
def _stow_pattern() -> re.Pattern[str]:
    verbs = _alt(list(PLACE_VERBS))
    words = r"[a-z][\w'-]*"
    return re.compile(
        rf"\b(?P<verb>{verbs})\s+(?P<pick>{words}(?:\s+{words}){{0,3}}?)\s+(?:away\s+)?"
        rf"(?:in|into|inside)\s+(?P<pre>(?:{words}\s+){{0,4}}?)(?P<role>drawer)s?\b"
        rf"(?:\s+(?:of|on|in)\s+(?P<post>{words}(?:\s+{words}){{0,4}}))?"
    )


@cache
def _door_stow_pattern() -> re.Pattern[str]:
    verbs = _alt(list(PLACE_VERBS))
    words = r"[a-z][\w'-]*"
    return re.compile(
        rf"\b(?P<verb>{verbs})\s+(?P<pick>{words}(?:\s+{words}){{0,3}}?)\s+(?:away\s+)?"
        rf"(?:in|into|inside)\s+(?P<post>{words}(?:\s+{words}){{0,4}})"
    )


def _door_stow(low: str, text: str) -> PartSpec | None:
    """Rule 5 (module docstring): a put-away request whose place target opens by a door with
    an interior, or None."""
    for m in _door_stow_pattern().finditer(low):
        post = _ENDS.sub("", m.group("post"))
        named = _clean(post)
        named_category = catalogue_category(named) if named else ""
        category = openable_category(named_category)
        if category not in DOOR_CONTAINERS:
            if not set(named.split()) & set(CABINET_WORDS):
                continue
            category = DOOR_CABINETS[0]
        item_named = _clean(m.group("pick"))
        return PartSpec(
            verb=m.group("verb"),
            role="door",
            qualifier=next((PART_QUALIFIERS[w] for w in post.split() if w in PART_QUALIFIERS), ""),
            category=category,
            named=named,
            named_category=named_category,
            instruction=text,
            item=catalogue_category(item_named) if item_named else "",
            item_named=item_named,
        )
    return None


_ENDS = re.compile(r"\s+(?:in|on|at|near|by|so|and|then|with|for|that|which|where|while)\s.*$")


@cache
def _phrases() -> dict[str, str]:
    """Catalogue phrase (a category's name, spaces for underscores, or a synonym; lower case)
    -> its category; the first category to use a phrase keeps it."""
    from factory.assets.catalog import CATEGORIES

    out: dict[str, str] = {}
    for name, cat in CATEGORIES.items():
        for phrase in (name.replace("_", " "), *cat.synonyms):
            key = phrase.lower().replace("-", " ").strip()
            if key and key not in PART_ROLES:
                out.setdefault(key, name)
    return out


def catalogue_category(words: str) -> str:
    """The catalogue category of the longest catalogue phrase in ``words`` (a plural "s"
    allowed), ``""`` if none."""
    text = f" {words.replace('-', ' ')} "
    for phrase in sorted(_phrases(), key=len, reverse=True):
        if re.search(rf"\s{re.escape(phrase)}s?\s", text):
            return _phrases()[phrase]
    return ""


def openable_category(category: str) -> str:
    """The articulated category that ``category`` stands for: itself when articulated, else
    its catalogue ``articulated_as``; ``""`` when it has neither (or is unknown)."""
    from factory.assets.catalog import CATEGORIES

    cat = CATEGORIES.get(category)
    if cat is None:
        return ""
    return category if cat.articulated else cat.articulated_as


def part_rooms(category: str) -> tuple[str, ...]:
    """The room types that hold an openable ``category``: the catalogue ``rooms`` of the
    categories that stand for it (the rigid ones whose ``articulated_as`` it is) and its own,
    in catalogue order."""
    from factory.assets.catalog import CATEGORIES

    rooms: list[str] = []
    for name, cat in CATEGORIES.items():
        if name == category or cat.articulated_as == category:
            rooms += [r for r in cat.rooms if r not in rooms]
    return tuple(rooms)


def openable_names() -> list[str]:
    """What a request may call the objects that open: "refrigerator (upright_fridge)", one per
    catalogue category that is articulated or stands for one, sorted."""
    from factory.assets.catalog import CATEGORIES

    out = []
    for name in CATEGORIES:
        target = openable_category(name)
        if target:
            spoken = name.replace("_", " ")
            out.append(spoken if target == name else f"{spoken} ({target})")
    return sorted(out)


def _clean(words: str) -> str:
    """Object words without articles and qualifiers ("the top" -> "")."""
    drop = {*ARTICLES, *PART_QUALIFIERS}
    return " ".join(w for w in words.split() if w not in drop)


def read_part_task(text: str) -> PartSpec | None:
    """Reads "open the fridge door", "close the top drawer of the nightstand" style requests
    (English; the rules: the module docstring).

    Args:
        text: the request.

    Returns:
        the part task, or None when the text asks to open or close no door or drawer.
    """
    low = text.lower().replace("\u2019", "'")
    stow = _stow_pattern().search(low)
    if stow is None:
        door = _door_stow(low, text)
        if door is not None:
            return door
    m = stow or _pattern().search(low)
    if m is None:
        return None
    pre = m.group("pre") or ""
    post = _ENDS.sub("", m.group("post") or "")
    qualifier = next((PART_QUALIFIERS[w] for w in pre.split() if w in PART_QUALIFIERS), "")
    named = _clean(post) or _clean(pre)
    named_category = catalogue_category(named) if named else ""
    item_named = _clean(stow.group("pick")) if stow else ""
    category = openable_category(named_category)
    if stow and not named:
        category = DRAWER_CONTAINERS[0]
    return PartSpec(
        verb=m.group("verb"),
        role=PART_ROLES[m.group("role")],
        qualifier=qualifier,
        category=category,
        named=named,
        named_category=named_category,
        instruction=text,
        item=catalogue_category(item_named) if item_named else "",
        item_named=item_named,
    )


def in_rooms(spec: PartSpec, room_types: tuple[str, ...]) -> PartSpec:
    """A put-away request that names no drawer's object read in its rooms: its ``category``
    is the first of :data:`~.task_words.DRAWER_CONTAINERS` that one of ``room_types`` holds
    (:func:`part_rooms`: "a bedroom where the robot puts the mug in the drawer" takes a
    ``bedside_cabinet``'s); one that names a cabinet without saying which ("put the cup in
    the cabinet") the first such of :data:`~.task_words.DOOR_CABINETS`; any other spec, or
    rooms that hold none of them, unchanged.

    Args:
        spec: the request's part task (:func:`read_part_task`).
        room_types: the rooms the request builds.
    """
    generic = spec.role == "door" and openable_category(spec.named_category) != spec.category
    if not spec.item_named or (spec.named and not generic):
        return spec
    for category in DOOR_CABINETS if generic else DRAWER_CONTAINERS:
        if set(part_rooms(category)) & set(room_types):
            return replace(spec, category=category)
    return spec


def check_part_request(spec: PartSpec, room_types: tuple[str, ...]) -> None:
    """Refuses a part task that no generated scene can hold.

    Args:
        spec: the request's part task.
        room_types: the rooms the request builds.

    Raises:
        ConfigError: the named object is not in the catalogue, does not open, or belongs in
            none of ``room_types``; a put-away request's object is not in the catalogue, or
            its drawer's object is none of :data:`~.task_words.DRAWER_CONTAINERS` (a door's:
            :data:`~.task_words.DOOR_CONTAINERS`; the message lists the valid choices).
    """
    if spec.item_named and not spec.item:
        raise ConfigError(
            f"request {spec.instruction!r}: the catalogue has no {spec.item_named!r}; "
            f"objects to put away: {', '.join(sorted(o.replace('_', ' ') for o in STOW_OBJECTS))}"
        )
    choices = DOOR_CONTAINERS if spec.role == "door" else DRAWER_CONTAINERS
    if spec.item_named and spec.named and spec.category not in choices:
        raise ConfigError(
            f"request {spec.instruction!r}: no {spec.role} of {spec.named!r} to put things "
            f"{'behind' if spec.role == 'door' else 'in'}; {spec.role}s: "
            f"{', '.join(n.replace('_', ' ') for n in choices)}"
        )
    if spec.named and not spec.category:
        what = (
            f"the catalogue has no {spec.named!r}"
            if not spec.named_category
            else f"{spec.named!r} ({spec.named_category}) has no door or drawer that opens"
        )
        raise ConfigError(
            f"request {spec.instruction!r}: {what}; objects that open: "
            f"{', '.join(openable_names())}"
        )
    rooms = part_rooms(spec.category) if spec.category else ()
    if rooms and not set(rooms) & set(room_types):
        raise ConfigError(
            f"request {spec.instruction!r}: a {' and '.join(room_types)} holds no "
            f"{spec.named} ({spec.category}); ask for it in a {' or a '.join(rooms)}"
        )
