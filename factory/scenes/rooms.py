"""Room-type knowledge for the heuristic scene agent.

``ROOM_TYPES`` is a literal dict, room type -> :class:`RoomType`: typical size, floor and wall
materials, the furniture to place (with counts and placement rules) and what goes on which
surfaces. Placement rules:

* ``wall``: on the floor, back against a wall; ``corner``: against a wall near a corner;
* ``free``: on the floor, anywhere with clearance; ``center``: near the room centre;
* ``near:<key>``: on the floor next to the object placed as ``<key>``, back to the same wall;
* ``around:<key>``: around a table, facing it (chairs);
* ``mount``: on a wall at ``height`` (bottom, m), static;
* ``on:<key>``: on a support surface of ``<key>`` (tops, shelf boards, seats).
"""

from __future__ import annotations

from dataclasses import dataclass, field


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
    """Typical size (width, length, m), materials, furniture and small objects."""

    size: tuple[tuple[float, float], tuple[float, float]]
    floors: tuple[str, ...]
    walls: tuple[str, ...]
    items: tuple[Item, ...]
    aliases: tuple[str, ...] = ()
    fillers: tuple[str, ...] = field(default=("potted plant", "floor lamp", "trash can"))


_DECOR = ("vase", "small plant", "candle", "picture frame", "book")
_KITCHEN_SMALL = (
    "mug",
    "bowl",
    "plate",
    "bottle",
    "jar",
    "cup",
    "apple",
    "orange",
    "banana",
    "can",
    "cutting board",
    "kettle",
)
_OFFICE_SMALL = ("book", "mug", "pen", "laptop", "keyboard", "picture frame", "small plant")


def _shelf(key: str = "shelf", n: tuple[int, int] = (1, 2)) -> tuple[Item, ...]:
    return (
        Item("bookshelf", n, "wall", key),
        Item("book", (8, 14), f"on:{key}"),
        Item("vase", (0, 1), f"on:{key}"),
        Item("small plant", (0, 1), f"on:{key}"),
    )


ROOM_TYPES: dict[str, RoomType] = {
    "bedroom": RoomType(
        ((3.6, 4.6), (3.8, 5.0)),
        ("oak", "carpet", "laminate"),
        ("plaster",),
        (
            Item("bed", rule="wall", key="bed"),
            Item("nightstand", (2, 2), "near:bed", "ns"),
            Item("table lamp", (1, 2), "on:ns"),
            Item("book", (1, 3), "on:ns"),
            Item("picture frame", (0, 1), "on:ns"),
            Item("wardrobe", rule="wall", key="wardrobe"),
            Item("dresser", rule="wall", key="dresser"),
            Item("vase", (1, 1), "on:dresser"),
            Item("picture frame", (1, 2), "on:dresser"),
            Item("candle", (1, 2), "on:dresser"),
            Item("cushion", (2, 3), "on:bed"),
            Item("book", (1, 2), "on:dresser"),
            Item("desk", rule="wall", key="desk", p=0.7),
            Item("chair", (1, 1), "around:desk"),
            Item("laptop", (1, 1), "on:desk"),
            Item("mug", (1, 1), "on:desk"),
            Item("pen", (1, 2), "on:desk"),
            Item("small plant", (0, 1), "on:desk"),
            Item("clock", (0, 1), "mount", height=1.9),
            *_shelf(n=(1, 1)),
            Item("painting", (1, 2), "mount", height=1.3),
            Item("mirror", (0, 1), "mount", height=1.0),
            Item("floor lamp", (1, 1), "corner"),
            Item("potted plant", (1, 1), "corner"),
            Item("armchair", (0, 1), "corner"),
        ),
        aliases=("master bedroom", "guest room", "bed room"),
    ),
    "kitchen": RoomType(
        ((3.5, 4.5), (3.8, 5.0)),
        ("tile", "stone"),
        ("paint",),
        (
            Item("kitchen cabinet", (3, 5), "wall", "counter"),
            Item("refrigerator", rule="wall"),
            Item("oven", rule="wall", key="oven"),
            Item("dishwasher", (0, 1), "wall"),
            Item("microwave", (1, 1), "on:counter"),
            Item("kitchen island", (0, 1), "center", "island"),
            Item("dining table", (1, 1), "center", "table"),
            Item("chair", (2, 4), "around:table"),
            *(Item(t, (1, 3), "on:counter") for t in _KITCHEN_SMALL),
            *(Item(t, (1, 2), "on:table") for t in ("bowl", "plate", "mug", "apple", "bottle")),
            *(Item(t, (0, 2), "on:island") for t in ("bowl", "orange", "cutting board", "jar")),
            Item("clock", (1, 1), "mount", height=1.8),
            Item("trash can", (1, 1), "corner"),
            Item("wall shelf", (0, 1), "mount", "wshelf", height=1.5),
            Item("jar", (1, 3), "on:wshelf"),
        ),
        aliases=("kitchenette", "galley"),
    ),
    "living room": RoomType(
        ((4.0, 5.5), (4.5, 6.0)),
        ("oak", "walnut", "carpet"),
        ("plaster",),
        (
            Item("sofa", rule="wall", key="sofa"),
            Item("coffee table", rule="center", key="coffee"),
            Item("armchair", (1, 2), "free", "arm"),
            Item("tv stand", rule="wall", key="tvs"),
            Item("tv", (1, 1), "on:tvs"),
            Item("speaker", (0, 2), "on:tvs"),
            Item("game console", (0, 1), "on:tvs"),
            Item("remote", (1, 1), "on:coffee"),
            Item("vase", (1, 1), "on:coffee"),
            Item("book", (1, 2), "on:coffee"),
            Item("mug", (0, 1), "on:coffee"),
            Item("candle", (1, 2), "on:coffee"),
            Item("picture frame", (1, 1), "on:side"),
            Item("book", (1, 3), "on:tvs"),
            Item("side table", (1, 2), "near:sofa", "side"),
            Item("table lamp", (1, 1), "on:side"),
            Item("cushion", (2, 3), "on:sofa"),
            *_shelf(),
            Item("painting", (1, 3), "mount", height=1.4),
            Item("clock", (0, 1), "mount", height=1.9),
            Item("floor lamp", (1, 2), "corner"),
            Item("potted plant", (1, 2), "corner"),
            Item("piano", (0, 1), "wall", p=0.3),
            Item("ottoman", (0, 1), "free"),
        ),
        aliases=("lounge", "family room", "sitting room"),
    ),
    "dining room": RoomType(
        ((3.5, 4.5), (4.0, 5.5)),
        ("oak", "parquet"),
        ("plaster",),
        (
            Item("dining table", rule="center", key="table"),
            Item("chair", (4, 6), "around:table"),
            Item("sideboard", rule="wall", key="side"),
            Item("bowl", (1, 2), "on:table"),
            Item("plate", (2, 4), "on:table"),
            Item("glass", (2, 4), "on:table"),
            Item("bottle", (1, 1), "on:table"),
            Item("candle", (1, 2), "on:table"),
            Item("vase", (1, 2), "on:side"),
            Item("plate", (1, 3), "on:side"),
            Item("painting", (1, 2), "mount", height=1.4),
            Item("potted plant", (1, 2), "corner"),
            Item("cabinet", (0, 1), "wall", "cab"),
            Item("glass", (1, 3), "on:cab"),
        ),
    ),
    "bathroom": RoomType(
        ((2.2, 3.2), (2.5, 3.5)),
        ("tile", "marble"),
        ("tile",),
        (
            Item("bathtub", rule="wall"),
            Item("toilet", rule="wall"),
            Item("sink", rule="wall", key="sink"),
            Item("mirror", (1, 1), "mount", height=1.1),
            Item("soap dispenser", (1, 1), "on:sink"),
            Item("towel", (1, 2), "on:sink"),
            Item("cabinet", (0, 1), "wall", "cab"),
            Item("towel", (1, 3), "on:cab"),
            Item("tissue box", (0, 1), "on:cab"),
            Item("trash can", (1, 1), "corner"),
            Item("washing machine", (0, 1), "wall"),
            Item("radiator", (0, 1), "mount", height=0.2),
        ),
        aliases=("bath", "washroom"),
        fillers=("small plant", "towel"),
    ),
    "restroom": RoomType(
        ((2.5, 3.5), (3.0, 4.5)),
        ("tile",),
        ("tile",),
        (
            Item("toilet", (2, 3), "wall"),
            Item("urinal", (1, 3), "mount", height=0.5),
            Item("sink", (2, 2), "wall", "sink"),
            Item("soap dispenser", (1, 2), "on:sink"),
            Item("mirror", (1, 2), "mount", height=1.1),
            Item("hand dryer", (1, 1), "mount", height=1.1),
            Item("trash can", (1, 2), "corner"),
        ),
        aliases=("public restroom", "toilet room", "wc"),
    ),
    "office": RoomType(
        ((3.5, 5.0), (4.0, 6.0)),
        ("carpet", "laminate"),
        ("paint",),
        (
            Item("desk", (1, 2), "wall", "desk"),
            Item("office chair", (1, 2), "around:desk"),
            Item("monitor", (1, 2), "on:desk"),
            Item("keyboard", (1, 1), "on:desk"),
            *(Item(t, (0, 2), "on:desk") for t in _OFFICE_SMALL),
            Item("computer tower", (0, 1), "near:desk"),
            Item("filing cabinet", (1, 2), "wall", "files"),
            Item("printer", (1, 1), "on:files"),
            *_shelf(),
            Item("whiteboard", (0, 1), "mount", height=0.9),
            Item("clock", (1, 1), "mount", height=1.9),
            Item("potted plant", (1, 2), "corner"),
            Item("trash can", (1, 1), "corner"),
            Item("armchair", (0, 1), "corner"),
        ),
        aliases=("study", "home office", "workspace"),
    ),
    "meeting room": RoomType(
        ((4.5, 6.0), (5.0, 7.0)),
        ("carpet",),
        ("paint",),
        (
            Item("conference table", rule="center", key="table"),
            Item("office chair", (6, 8), "around:table"),
            Item("laptop", (1, 3), "on:table"),
            Item("mug", (2, 4), "on:table"),
            Item("bottle", (1, 3), "on:table"),
            Item("book", (1, 2), "on:table"),
            Item("whiteboard", (1, 1), "mount", height=0.9),
            Item("tv", (0, 1), "mount", height=1.2),
            Item("sideboard", (1, 1), "wall", "side"),
            Item("glass", (2, 4), "on:side"),
            Item("potted plant", (1, 2), "corner"),
            Item("clock", (1, 1), "mount", height=2.0),
        ),
        aliases=("conference room", "boardroom"),
    ),
    "classroom": RoomType(
        ((6.0, 8.0), (6.0, 8.0)),
        ("vinyl", "laminate"),
        ("paint",),
        (
            Item("whiteboard", (1, 1), "mount", height=0.9),
            Item("desk", (1, 1), "wall", "teacher"),
            Item("office chair", (1, 1), "around:teacher"),
            Item("school desk", (6, 12), "free", "sd"),
            Item("chair", (6, 12), "free"),
            Item("book", (4, 10), "on:sd"),
            Item("pen", (2, 6), "on:sd"),
            *_shelf(n=(1, 2)),
            Item("clock", (1, 1), "mount", height=2.0),
            Item("locker", (0, 3), "wall"),
            Item("trash can", (1, 1), "corner"),
        ),
        aliases=("school room", "lecture room"),
    ),
    "children's room": RoomType(
        ((3.2, 4.2), (3.5, 4.5)),
        ("carpet", "laminate"),
        ("paint",),
        (
            Item("bed", rule="wall", key="bed"),
            Item("toy box", rule="wall", key="toys"),
            Item("teddy bear", (1, 2), "on:bed"),
            Item("ball", (1, 2), "free"),
            Item("toy block", (3, 6), "on:toys"),
            Item("desk", (0, 1), "wall", "desk"),
            Item("chair", (1, 1), "around:desk"),
            Item("book", (1, 3), "on:desk"),
            *_shelf(n=(1, 1)),
            Item("teddy bear", (1, 2), "on:shelf"),
            Item("nightstand", (1, 1), "near:bed", "ns"),
            Item("table lamp", (1, 1), "on:ns"),
            Item("painting", (1, 2), "mount", height=1.2),
            Item("crib", (0, 1), "wall", p=0.3),
            Item("rug", (0, 0), "center"),
        ),
        aliases=("kids room", "nursery", "playroom", "child's room"),
    ),
    "gym": RoomType(
        ((6.0, 8.0), (6.0, 9.0)),
        ("rubber",),
        ("concrete",),
        (
            Item("treadmill", (2, 3), "wall"),
            Item("exercise bike", (2, 3), "wall"),
            Item("bench", (1, 2), "free", "bench"),
            Item("dumbbell", (4, 8), "free"),
            Item("yoga mat", (2, 3), "free"),
            Item("punching bag", (0, 1), "corner"),
            Item("mirror", (1, 2), "mount", height=0.6),
            Item("locker", (2, 4), "wall"),
            Item("ball", (1, 3), "free"),
            Item("bottle", (1, 2), "on:bench"),
            Item("towel", (1, 2), "on:bench"),
            Item("clock", (1, 1), "mount", height=2.2),
        ),
        aliases=("fitness room", "home gym", "workout room"),
    ),
    "game den": RoomType(
        ((4.0, 5.5), (4.5, 6.0)),
        ("carpet", "walnut"),
        ("paint",),
        (
            Item("pool table", (0, 1), "center", "pool"),
            Item("arcade machine", (1, 2), "wall"),
            Item("sofa", rule="wall", key="sofa"),
            Item("tv stand", rule="wall", key="tvs"),
            Item("tv", (1, 1), "on:tvs"),
            Item("game console", (1, 2), "on:tvs"),
            Item("speaker", (1, 2), "on:tvs"),
            Item("coffee table", (1, 1), "free", "coffee"),
            Item("remote", (1, 2), "on:coffee"),
            Item("can", (1, 3), "on:coffee"),
            Item("bar stool", (1, 3), "free"),
            Item("cushion", (1, 3), "on:sofa"),
            Item("painting", (1, 2), "mount", height=1.4),
            Item("floor lamp", (1, 1), "corner"),
            *_shelf(n=(1, 1)),
        ),
        aliases=("game room", "games room", "rec room", "man cave"),
    ),
    "library": RoomType(
        ((4.5, 6.0), (5.0, 7.0)),
        ("walnut", "carpet"),
        ("plaster",),
        (
            *_shelf(n=(3, 5)),
            Item("desk", (1, 2), "free", "desk"),
            Item("chair", (1, 2), "around:desk"),
            Item("table lamp", (1, 2), "on:desk"),
            Item("book", (2, 4), "on:desk"),
            Item("armchair", (1, 2), "corner"),
            Item("side table", (1, 1), "free", "side"),
            Item("book", (1, 2), "on:side"),
            Item("floor lamp", (1, 2), "corner"),
        ),
        aliases=("reading room", "study library"),
    ),
    "laundry room": RoomType(
        ((2.5, 3.5), (2.5, 3.5)),
        ("tile",),
        ("paint",),
        (
            Item("washing machine", (1, 2), "wall", "wm"),
            Item("cabinet", (1, 2), "wall", "cab"),
            Item("basket", (1, 2), "free"),
            Item("towel", (2, 4), "on:cab"),
            Item("bottle", (1, 3), "on:wm"),
            Item("sink", (0, 1), "wall"),
            Item("wall shelf", (1, 1), "mount", "wshelf", height=1.5),
            Item("towel", (1, 2), "on:wshelf"),
        ),
        aliases=("utility room", "laundry"),
    ),
    "hallway": RoomType(
        ((1.8, 2.4), (4.0, 6.0)),
        ("oak", "tile"),
        ("plaster",),
        (
            Item("console table", (1, 1), "wall", "console"),
            Item("shoe rack", (1, 1), "wall"),
            Item("coat rack", (1, 1), "corner"),
            Item("mirror", (1, 1), "mount", height=1.0),
            Item("vase", (1, 1), "on:console"),
            Item("picture frame", (1, 2), "on:console"),
            Item("painting", (1, 2), "mount", height=1.4),
            Item("bench", (0, 1), "wall"),
        ),
        aliases=("corridor", "entryway", "foyer"),
    ),
    "garage": RoomType(
        ((5.0, 6.5), (5.5, 7.0)),
        ("concrete",),
        ("concrete",),
        (
            Item("workbench", (1, 2), "wall", "wb"),
            Item("crate", (2, 5), "free"),
            Item("cardboard box", (3, 6), "free"),
            Item("cabinet", (1, 2), "wall", "cab"),
            Item("bottle", (1, 3), "on:wb"),
            Item("can", (1, 3), "on:cab"),
            Item("wall shelf", (1, 2), "mount", "wshelf", height=1.4),
            Item("cardboard box", (1, 2), "on:wshelf"),
            Item("bucket", (0, 1), "free"),
        ),
        aliases=("workshop", "shed"),
    ),
    "nursery": RoomType(
        ((3.0, 4.0), (3.0, 4.0)),
        ("carpet",),
        ("paint",),
        (
            Item("crib", (1, 1), "wall", "crib"),
            Item("dresser", (1, 1), "wall", "dresser"),
            Item("teddy bear", (1, 3), "on:dresser"),
            Item("armchair", (1, 1), "corner"),
            Item("toy box", (1, 1), "wall", "toys"),
            Item("toy block", (2, 5), "on:toys"),
            Item("painting", (1, 2), "mount", height=1.3),
            Item("floor lamp", (1, 1), "corner"),
        ),
        aliases=("baby room",),
    ),
    "studio": RoomType(
        ((5.0, 6.5), (5.0, 7.0)),
        ("oak", "laminate"),
        ("plaster",),
        (
            Item("bed", rule="wall", key="bed"),
            Item("sofa", rule="wall", key="sofa"),
            Item("coffee table", rule="free", key="coffee"),
            Item("kitchen cabinet", (2, 3), "wall", "counter"),
            Item("refrigerator", rule="wall"),
            Item("dining table", (1, 1), "free", "table"),
            Item("chair", (2, 2), "around:table"),
            Item("mug", (1, 2), "on:table"),
            Item("bowl", (1, 2), "on:counter"),
            Item("plate", (1, 2), "on:counter"),
            Item("remote", (1, 1), "on:coffee"),
            Item("cushion", (1, 2), "on:sofa"),
            Item("nightstand", (1, 1), "near:bed", "ns"),
            Item("table lamp", (1, 1), "on:ns"),
            Item("painting", (1, 2), "mount", height=1.4),
            Item("potted plant", (1, 1), "corner"),
        ),
        aliases=("studio apartment", "loft", "apartment"),
    ),
    "cafe": RoomType(
        ((6.0, 8.0), (6.0, 8.0)),
        ("tile", "oak"),
        ("brick",),
        (
            Item("side table", (4, 6), "free", "t"),
            Item("chair", (8, 12), "free"),
            Item("mug", (3, 6), "on:t"),
            Item("plate", (2, 4), "on:t"),
            Item("kitchen cabinet", (2, 3), "wall", "counter"),
            Item("bottle", (2, 4), "on:counter"),
            Item("cup", (2, 4), "on:counter"),
            Item("potted plant", (2, 3), "corner"),
            Item("painting", (1, 3), "mount", height=1.5),
        ),
        aliases=("coffee shop", "restaurant", "bistro"),
    ),
    "home bar": RoomType(
        ((3.5, 5.0), (4.0, 5.5)),
        ("walnut",),
        ("brick",),
        (
            Item("kitchen island", (1, 1), "center", "bar"),
            Item("bar stool", (3, 4), "free"),
            Item("bottle", (3, 6), "on:bar"),
            Item("glass", (3, 6), "on:bar"),
            Item("cabinet", (1, 2), "wall", "cab"),
            Item("bottle", (2, 5), "on:cab"),
            Item("sofa", (0, 1), "wall"),
            Item("painting", (1, 2), "mount", height=1.5),
        ),
        aliases=("bar", "pub", "lounge bar"),
    ),
}
"""Room type -> knowledge; at least 20 types."""


def room_type_of(text: str) -> str:
    """The room type named in ``text`` (aliases included); ``living room`` if none."""
    low = text.lower()
    best, pos = "", -1
    for name, rt in ROOM_TYPES.items():
        for phrase in (name, *rt.aliases):
            i = low.find(phrase)
            if i >= 0 and (len(phrase) > len(best)):
                best, pos = name, i
    return best or ("living room" if pos < 0 else best)
