"""Room-type knowledge for the heuristic scene agent.

``ROOM_TYPES`` is a dict, room type -> :class:`RoomType`: typical size, floor and wall
materials, the furniture to place (with counts and placement rules: see
:mod:`.room_program`), what goes on which surfaces, aliases and describing words. The
knowledge is data: ``factory/data/rooms/room_types.yaml``, read and checked by
:mod:`.room_data` when this module is imported (a bad entry raises
:class:`~factory.errors.RoomDataError`).
"""

from __future__ import annotations

from factory.scenes.room_data import load_room_types
from factory.scenes.room_program import Item, RoomType

__all__ = ["ROOM_TYPES", "Item", "RoomType", "room_type_of"]

ROOM_TYPES: dict[str, RoomType] = load_room_types()
"""Room type -> knowledge; at least 50 types."""


def room_type_of(text: str) -> str:
    """The room type named in ``text`` (aliases included, the longest name wins);
    ``living room`` if none."""
    low = text.lower()
    best, best_len = "", 0
    for name, rt in ROOM_TYPES.items():
        for phrase in (name, *rt.aliases):
            if len(phrase) > best_len and phrase in low:
                best, best_len = name, len(phrase)
    return best or "living room"
