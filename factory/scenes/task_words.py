"""The words of a task request, as data: which verbs pick, which say the robot travels, which
prepositions name a destination, which words name a support; which words name a moving part
and which one (:mod:`.part_read`; the verbs that open or close are the tasks' own,
:attr:`factory.tasks.base.Task.request_verbs`).

:func:`factory.scenes.task_read.read_task` reads a request with these tables; the rules that
use them are written there. A request is the mobile task (the base drives) only when the
robot must travel:

* a travel verb (:data:`TRAVEL_VERBS`: "carry", "bring", "deliver", "fetch", ...) moves it;
* or a destination phrase (:data:`DESTINATION_PREPOSITIONS`: "to", "onto", "over to", ...)
  names a support that is not the one it is picked from (:data:`SUPPORT_WORDS`: "the desk",
  "the shelf"), or a room;
* or the place is in another room than the rest of the request names ("... on the shelf in
  the hallway" in a living room).

"picks up the mug from the table and puts it in the bowl" names the pick support ("from the
table") and nothing else: the fixed task, both on the table.
"""

from __future__ import annotations

_TRAVEL: tuple[str, ...] = (
    "carry",
    "carries",
    "bring",
    "brings",
    "deliver",
    "delivers",
    "fetch",
    "fetches",
    "transport",
    "transports",
    "relocate",
    "relocates",
)

PICK_VERBS: tuple[str, ...] = (
    "pick up",
    "picks up",
    "picked up",
    "pick",
    "picks",
    "grab",
    "grabs",
    "take",
    "takes",
    "lift",
    "lifts",
    "move",
    "moves",
    *_TRAVEL,
)
"""Verbs that start a task: "<verb> the <object> ..." (longest tried first)."""

PLACE_VERBS: tuple[str, ...] = (
    "put",
    "puts",
    "place",
    "places",
    "drop",
    "drops",
    "set",
    "sets",
    "leave",
    "leaves",
    "stack",
    "stacks",
    "carry",
    "carries",
    "bring",
    "brings",
    "take",
    "takes",
    "move",
    "moves",
    "deliver",
    "delivers",
)
"""Verbs of the second clause: "... and <verb> it in the bowl"."""

TRAVEL_VERBS: frozenset[str] = frozenset(_TRAVEL)
"""Verbs that say the robot takes the object somewhere else: always the mobile task."""

RELATIONS: dict[str, str] = {
    "back into": "in",
    "back in": "in",
    "back onto": "on",
    "back on": "on",
    "back to": "on",
    "over to": "on",
    "across to": "on",
    "on top of": "on",
    "inside": "in",
    "into": "in",
    "in": "in",
    "onto": "on",
    "on": "on",
    "to": "on",
}
"""Place prepositions -> the task's relation (``in`` a container, ``on`` a surface)."""

DESTINATION_PREPOSITIONS: frozenset[str] = frozenset(
    {"to", "onto", "over to", "across to", "back to", "back onto"}
)
"""Prepositions that name a destination: with a support other than the pick support, or a
room, the robot travels."""

SUPPORT_WORDS: tuple[str, ...] = (
    "table",
    "desk",
    "shelf",
    "shelves",
    "bookshelf",
    "bookcase",
    "counter",
    "countertop",
    "island",
    "cabinet",
    "dresser",
    "nightstand",
    "bedside table",
    "sideboard",
    "workbench",
    "bench",
    "cart",
    "trolley",
    "stand",
    "console",
    "chest",
    "vanity",
)
"""Last words of floor furniture that holds things: a destination support, not a container
on the table ("to the desk", "onto the shelf")."""

ARTICLES: tuple[str, ...] = (
    "the",
    "a",
    "an",
    "some",
    "this",
    "that",
    "my",
    "our",
    "its",
    "his",
    "her",
)
"""Words dropped before an object or support name."""

PLACE_ENDS: tuple[str, ...] = (
    "in the",
    "in a",
    "in my",
    "in our",
    "of the",
    "at the",
    "near the",
    "next to",
    "by the",
    "beside",
    "across the",
    "which",
    "that",
    "so",
    "where",
    "while",
    "and",
    "then",
    "with",
    "for",
)
"""Words that end a support's name ("the desk in the study": the desk, then its room)."""

PART_ROLES: dict[str, str] = {
    "door": "door",
    "doors": "door",
    "drawer": "drawer",
    "drawers": "drawer",
}
"""Words that name a moving part -> its role word (as
:data:`factory.tasks.articulated.parts.ROLE_WORDS` labels parts)."""

PART_QUALIFIERS: dict[str, str] = {
    "top": "top",
    "upper": "top",
    "uppermost": "top",
    "middle": "middle",
    "bottom": "bottom",
    "lower": "bottom",
    "lowest": "bottom",
    "left": "left",
    "right": "right",
}
"""Words that say which of several parts -> the qualifier of the parts' labels (drawers by
height, doors left or right seen from the front)."""

DRAWER_CONTAINERS: tuple[str, ...] = ("base_cabinet", "bedside_cabinet", "drawer_chest")
"""The articulated categories whose drawers a "put the mug in the drawer" request may name
(``task=place_inside`` takes a drawer under a top to stand the object on: a kitchen's base
cabinet, a bedroom's nightstand and dresser); a request naming none takes the first that its
room holds (:func:`~.part_read.in_rooms`)."""

DOOR_CONTAINERS: tuple[str, ...] = (
    "microwave_oven",
    "upright_fridge",
    "base_cabinet",
    "bedside_cabinet",
    "wall_cabinet",
    "two_door_sideboard",
    "double_door_cupboard",
    "built_in_wardrobe",
)
"""The articulated categories a "put the mug in the microwave" request may name: a door with
an interior support behind it (the cavity's floor, a fridge's or a cabinet's shelves and
floor) and a top to stand the object on (``task=place_inside``)."""

CABINET_WORDS: tuple[str, ...] = ("cabinet", "cabinets", "cupboard", "cupboards")
"""Words that name a cabinet without saying which ("put the cup in the cabinet"): the first of
:data:`DOOR_CABINETS` that the request's rooms hold (:func:`~.part_read.in_rooms`)."""

DOOR_CABINETS: tuple[str, ...] = ("base_cabinet", "bedside_cabinet", "wall_cabinet")
"""The cabinets :data:`CABINET_WORDS` stand for, in the order tried (a kitchen's base
cabinet, a bedroom's nightstand)."""

STOW_OBJECTS: tuple[str, ...] = (
    "mug",
    "cup",
    "can",
    "apple",
    "orange",
    "jar",
    "pill_bottle",
    "candle",
)
"""Small objects the put-away messages suggest (catalogue categories the gripper takes from a
counter or a nightstand's top: the task's usual kitchen picks; in a bedroom a pill bottle fits
a nightstand's drawer, a candle a dresser's)."""

__all__ = [
    "ARTICLES",
    "CABINET_WORDS",
    "DESTINATION_PREPOSITIONS",
    "DOOR_CABINETS",
    "DOOR_CONTAINERS",
    "DRAWER_CONTAINERS",
    "PART_QUALIFIERS",
    "PART_ROLES",
    "PICK_VERBS",
    "PLACE_ENDS",
    "PLACE_VERBS",
    "RELATIONS",
    "STOW_OBJECTS",
    "SUPPORT_WORDS",
    "TRAVEL_VERBS",
]
