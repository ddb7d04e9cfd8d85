"""Reads and checks the room-type data file (``factory/data/rooms/room_types.yaml``).

:func:`load_room_types` turns each entry into a :class:`~.room_program.RoomType`; a bad entry
raises :class:`~factory.errors.RoomDataError` naming the room type, the field and what is
allowed. The file's own header documents the fields.
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from factory.errors import RoomDataError
from factory.scenes.room_program import DEFAULT_FILLERS, KEYED_RULES, RULES, Item, RoomType

ROOM_FIELDS: tuple[str, ...] = ("size", "floors", "walls", "items", "aliases", "fillers", "words")
"""The fields of a room type (the first four are required)."""
REQUIRED_FIELDS: tuple[str, ...] = ROOM_FIELDS[:4]
ITEM_FIELDS: tuple[str, ...] = ("text", "count", "rule", "key", "height", "p")
"""The fields of an item (``text`` is required)."""


def _fail(room: str, fld: str, problem: str, allowed: str) -> RoomDataError:
    return RoomDataError(f"room type {room!r}: {fld}: {problem}; allowed: {allowed}")


def _strings(room: str, fld: str, value: Any, required: bool) -> tuple[str, ...]:
    ok = isinstance(value, list) and all(isinstance(v, str) and v.strip() for v in value)
    if not ok or (required and not value):
        raise _fail(room, fld, f"got {value!r}", "a list of non-empty strings")
    return tuple(value)


def _size(room: str, value: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    try:
        (w0, w1), (l0, l1) = ((float(a), float(b)) for a, b in value)
    except (TypeError, ValueError):
        raise _fail(
            room,
            "size",
            f"got {value!r}",
            "[[min width, max width], [min length, max length]] in metres",
        ) from None
    if not (0 < w0 <= w1 and 0 < l0 <= l1):
        raise _fail(room, "size", f"got {value!r}", "0 < min <= max in both pairs")
    return (w0, w1), (l0, l1)


def _count(room: str, where: str, value: Any) -> tuple[int, int]:
    ok = (
        isinstance(value, list)
        and len(value) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        and 0 <= value[0] <= value[1]
    )
    if not ok:
        raise _fail(room, f"{where}.count", f"got {value!r}", "[min, max], 0 <= min <= max")
    return value[0], value[1]


def _number(room: str, where: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
        raise _fail(room, where, f"got {value!r}", f"a number in [{lo}, {hi}]")
    return float(value)


def _item(room: str, i: int, raw: Any, keys: set[str]) -> Item:
    where = f"items[{i}]"
    if not isinstance(raw, Mapping) or not isinstance(raw.get("text"), str):
        raise _fail(room, where, f"got {raw!r}", "a mapping with a 'text' string")
    extra = sorted(set(raw) - set(ITEM_FIELDS))
    if extra:
        raise _fail(room, f"{where}.{extra[0]}", "unknown field", ", ".join(ITEM_FIELDS))
    rule = raw.get("rule", "wall")
    kind, _, key = str(rule).partition(":")
    allowed_rules = ", ".join([*RULES, *(f"{k}:<key>" for k in KEYED_RULES)])
    if not ((kind in RULES and not key) or (kind in KEYED_RULES and key)):
        raise _fail(room, f"{where}.rule", f"got {rule!r}", allowed_rules)
    if kind in KEYED_RULES and key not in keys:
        raise _fail(room, f"{where}.rule", f"no item has key {key!r}", ", ".join(sorted(keys)))
    return Item(
        text=raw["text"],
        count=_count(room, where, raw.get("count", [1, 1])),
        rule=str(rule),
        key=str(raw.get("key", "")),
        height=_number(room, f"{where}.height", raw.get("height", 1.3), 0.0, 3.0),
        p=_number(room, f"{where}.p", raw.get("p", 1.0), 0.0, 1.0),
    )


def room_type_from(name: str, raw: Any) -> RoomType:
    """One room type from its data entry.

    Raises:
        RoomDataError: a field is missing, unknown or out of range.
    """
    if not isinstance(raw, Mapping):
        raise _fail(name, "(entry)", f"got {raw!r}", "a mapping of " + ", ".join(ROOM_FIELDS))
    for fld in REQUIRED_FIELDS:
        if fld not in raw:
            raise _fail(name, fld, "missing", ", ".join(ROOM_FIELDS))
    extra = sorted(set(raw) - set(ROOM_FIELDS))
    if extra:
        raise _fail(name, extra[0], "unknown field", ", ".join(ROOM_FIELDS))
    items_raw = raw["items"]
    if not isinstance(items_raw, list) or not items_raw:
        raise _fail(name, "items", f"got {items_raw!r}", "a non-empty list of items")
    keys: list[str] = [
        str(it["key"]) for it in items_raw if isinstance(it, Mapping) and it.get("key")
    ]
    doubled = sorted({k for k in keys if keys.count(k) > 1})
    if doubled:
        raise _fail(name, "items.key", f"key {doubled[0]!r} used twice", "one item per key")
    return RoomType(
        size=_size(name, raw["size"]),
        floors=_strings(name, "floors", raw["floors"], True),
        walls=_strings(name, "walls", raw["walls"], True),
        items=tuple(_item(name, i, it, set(keys)) for i, it in enumerate(items_raw)),
        aliases=_strings(name, "aliases", raw.get("aliases", []), False),
        fillers=_strings(name, "fillers", raw.get("fillers", list(DEFAULT_FILLERS)), True),
        words=_strings(name, "words", raw.get("words", []), False),
    )


def _check_names(types: dict[str, RoomType]) -> None:
    """No alias is another room type's name or alias (each name means one room type)."""
    owner: dict[str, str] = {name: name for name in types}
    for name, rt in types.items():
        for alias in rt.aliases:
            other = owner.setdefault(alias, name)
            if other != name or alias == name:
                raise _fail(
                    name, "aliases", f"{alias!r} already names {other!r}", "names of no other type"
                )


def parse_room_types(data: Any) -> dict[str, RoomType]:
    """Room types from the parsed data file (a mapping, room type name -> entry).

    Raises:
        RoomDataError: the data is not such a mapping, or an entry is invalid.
    """
    if not isinstance(data, Mapping) or not data:
        raise RoomDataError(f"room types: expected a mapping of room type -> entry, got {data!r}")
    types: dict[str, RoomType] = {}
    for name, raw in data.items():
        if not isinstance(name, str) or not name.strip() or name != name.lower():
            raise RoomDataError(f"room type {name!r}: the name must be a lower-case string")
        types[name] = room_type_from(name, raw)
    _check_names(types)
    return types


def load_room_types(path: Path | None = None) -> dict[str, RoomType]:
    """The room types of ``path`` (default: the packaged ``data/rooms/room_types.yaml``).

    Raises:
        RoomDataError: the file holds an invalid entry.
    """
    if path is None:
        text = resources.files("factory").joinpath("data/rooms/room_types.yaml").read_text()
    else:
        text = Path(path).read_text()
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    return parse_room_types(yaml.load(text, Loader=loader))
