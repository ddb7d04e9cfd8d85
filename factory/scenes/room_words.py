"""Words that name a room by its owner or its purpose, and the room type each one means.

Literal registries read by :mod:`.room_mentions`:

* ``ROOM_WORDS``: purpose words and everyday names ("home office", "den", "dorm") -> a room
  type of :data:`~factory.scenes.rooms.ROOM_TYPES`, with a note when the project has no such
  room and the closest type stands in for it (the names and aliases of the room types are
  read as well; a room no word names goes to the nearest type by meaning:
  :mod:`.room_meaning`);
* ``OWNERS``: who a room belongs to ("a child's room", "a room for a teenager", "the guest
  bedroom") -> the room type;
* ``OBJECT_HEADS``: nouns after a room word that make it an object's kind ("a bar stool", "a
  kitchen table"), so that the room word is only a weak mention.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RoomWord:
    """A word's room type, and why it is only the closest one (``""`` when exact)."""

    room_type: str
    note: str = ""


@dataclass(frozen=True)
class Owner:
    """An owner's room type.

    Attributes:
        room_type: the room type built for them.
        possessive_only: the word is also a style ("a princess bedroom" is a bedroom in the
            princess style): only "a princess's room" or "a princess room" name the owner.
    """

    room_type: str
    possessive_only: bool = False


ROOM_WORDS: dict[str, RoomWord] = {
    # sleeping
    "bed room": RoomWord("bedroom"),
    "sleeping room": RoomWord("bedroom"),
    "bedchamber": RoomWord("bedroom"),
    "master suite": RoomWord("bedroom"),
    "dorm room": RoomWord("bedroom"),
    "dorm": RoomWord("bedroom"),
    "dormitory": RoomWord("bedroom"),
    "kids room": RoomWord("children's room"),
    "kid room": RoomWord("children's room"),
    "baby room": RoomWord("nursery"),
    "nursery room": RoomWord("nursery"),
    # work and study
    "home office": RoomWord("office"),
    "study": RoomWord("office"),
    "study room": RoomWord("office"),
    "workroom": RoomWord("office"),
    "work room": RoomWord("office"),
    "office space": RoomWord("office"),
    "library": RoomWord("library"),
    "home library": RoomWord("library"),
    # living
    "den": RoomWord("game den"),
    "media room": RoomWord("game den"),
    "tv room": RoomWord("game den"),
    "living area": RoomWord("living room"),
    "front room": RoomWord("living room"),
    "drawing room": RoomWord("living room"),
    "parlor": RoomWord("living room"),
    "parlour": RoomWord("living room"),
    "great room": RoomWord("living room"),
    "common room": RoomWord("living room"),
    "breakfast room": RoomWord("dining room"),
    "breakfast nook": RoomWord("dining room"),
    # service rooms
    "laundry": RoomWord("laundry room"),
    "laundry room": RoomWord("laundry room"),
    "washhouse": RoomWord("laundry room"),
    "entrance hall": RoomWord("hallway"),
    "hall": RoomWord("hallway"),
    # washing
    "en-suite": RoomWord("bathroom"),
    "ensuite": RoomWord("bathroom"),
    "en suite": RoomWord("bathroom"),
    "powder room": RoomWord("bathroom"),
    "shower room": RoomWord("bathroom"),
    "lavatory": RoomWord("restroom"),
    "café": RoomWord("cafe"),
    "dining hall": RoomWord("dining room"),
    # exercise
    "exercise room": RoomWord("gym"),
    "fitness studio": RoomWord("gym"),
}
"""Purpose word -> room type (names and aliases of ``ROOM_TYPES`` are read as well)."""

OWNERS: dict[str, Owner] = {
    "child": Owner("children's room"),
    "children": Owner("children's room"),
    "childrens": Owner("children's room"),
    "kid": Owner("children's room"),
    "kids": Owner("children's room"),
    "boy": Owner("children's room"),
    "boys": Owner("children's room"),
    "girl": Owner("children's room"),
    "girls": Owner("children's room"),
    "toddler": Owner("children's room"),
    "toddlers": Owner("children's room"),
    "son": Owner("children's room"),
    "daughter": Owner("children's room"),
    "twins": Owner("children's room"),
    "princess": Owner("children's room", possessive_only=True),
    "prince": Owner("children's room", possessive_only=True),
    "baby": Owner("nursery"),
    "babies": Owner("nursery"),
    "infant": Owner("nursery"),
    "newborn": Owner("nursery"),
    "teenage girl": Owner("bedroom"),
    "teenage boy": Owner("bedroom"),
    "teenage son": Owner("bedroom"),
    "teenage daughter": Owner("bedroom"),
    "teen girl": Owner("bedroom"),
    "teen boy": Owner("bedroom"),
    "teen": Owner("bedroom"),
    "teens": Owner("bedroom"),
    "teenager": Owner("bedroom"),
    "teenagers": Owner("bedroom"),
    "teenage": Owner("bedroom"),
    "guest": Owner("guest room"),
    "guests": Owner("guest room"),
    "patient": Owner("patient room"),
    "patients": Owner("patient room"),
    "master": Owner("bedroom"),
    "parent": Owner("bedroom"),
    "parents": Owner("bedroom"),
    "student": Owner("bedroom"),
    "students": Owner("bedroom"),
    "grandma": Owner("bedroom"),
    "grandpa": Owner("bedroom"),
    "grandparents": Owner("bedroom"),
    "teacher": Owner("office"),
    "teachers": Owner("meeting room"),
}
"""Owner word -> the room type of "<owner>'s room", "<owner> bedroom", "a room for <owner>"."""

OWNER_ROOMS: tuple[str, ...] = (
    "bedroom",
    "bed room",
    "room",
    "chamber",
    "suite",
    "quarters",
    "dorm room",
    "hideaway",
    "den",
)
"""The nouns an owner word names a room with ("room" and "bedroom" above all)."""

CHILD_AGE = 12
"""Up to this age (years) a room "for a 7-year-old" is a children's room; up to 2, a nursery."""

OBJECT_HEADS: frozenset[str] = frozenset(
    {
        "stool",
        "stools",
        "chair",
        "chairs",
        "table",
        "tables",
        "cabinet",
        "cabinets",
        "island",
        "counter",
        "towel",
        "towels",
        "mat",
        "mats",
        "door",
        "doors",
        "sink",
        "shelf",
        "shelves",
        "lamp",
        "lamps",
        "mirror",
        "rug",
        "tub",
        "robe",
        "scale",
        "bag",
        "equipment",
        "supplies",
        "desk",
        "cart",
        "tools",
        "basket",
        "clock",
    }
)
"""Nouns that turn a room word before them into a kind of object: "a bar stool"."""
