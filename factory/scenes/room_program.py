"""What a room type is made of: :class:`Item` (something to place, how many, where) and
:class:`RoomType` (size, materials, items, names and describing words).

Placement rules (:data:`RULES`, and the keyed ones of :data:`KEYED_RULES`):

* ``wall``: on the floor, back against a wall; ``corner``: against a wall near a corner;
* ``free``: on the floor, anywhere with clearance; ``center``: near the room centre;
* ``near:<key>``: on the floor next to the object placed as ``<key>``, back to the same wall;
* ``around:<key>``: around a table, facing it (chairs);
* ``mount``: on a wall at ``height`` (bottom, m), static;
* ``on:<key>``: on a support surface of ``<key>`` (tops, shelf boards, seats);
* ``in:<key>``: stored inside ``<key>``, on a surface behind its door or in its drawer (an
  articulated asset's interiors; nothing is placed where ``<key>`` has none). Placed last (after
  the fillers and the route check), so that a room type's other draws do not change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

RULES: tuple[str, ...] = ("wall", "corner", "free", "center", "mount")
"""Placement rules that name no other item."""
KEYED_RULES: tuple[str, ...] = ("near", "around", "on", "in")
"""Placement rules written ``<rule>:<key>``, ``<key>`` being another item's key."""
DEFAULT_FILLERS: tuple[str, ...] = ("potted plant", "floor lamp", "trash can")
"""Small objects that fill free surfaces when a room type names none."""


@dataclass(frozen=True)
class Item:
    """Something to place: asset ``text``, how many, where, and the key to refer to it."""

    text: str
    count: tuple[int, int] = (1, 1)
    rule: str = "wall"
    key: str = ""
    height: float = 1.3
    p: float = 1.0


@dataclass(frozen=True)
class RoomType:
    """Typical size (width, length, m), materials, furniture and small objects.

    Attributes:
        size: ((min width, max width), (min length, max length)), m.
        floors: floor materials, one drawn per room.
        walls: wall materials, one drawn per room.
        items: what to place, in order.
        aliases: other names of the room type.
        fillers: small objects for free surfaces.
        words: words that describe the room (read by :mod:`.room_meaning`).
    """

    size: tuple[tuple[float, float], tuple[float, float]]
    floors: tuple[str, ...]
    walls: tuple[str, ...]
    items: tuple[Item, ...]
    aliases: tuple[str, ...] = ()
    fillers: tuple[str, ...] = field(default=DEFAULT_FILLERS)
    words: tuple[str, ...] = ()
