"""Request understanding: rooms named by owner or purpose, whole homes and their programs,
style and condition words, and requests in Spanish, French, German and Chinese."""

from __future__ import annotations

import pytest

from factory.scenes.homes import MAX_HOME_ROOMS
from factory.scenes.request import parse_request, room_types_in, style_of
from factory.scenes.rooms import ROOM_TYPES

_FLAT = ("bedroom", "living room", "kitchen", "bathroom")
_FAMILY = ("bedroom", "children's room", "living room", "kitchen", "dining room", "bathroom")

TABLE: list[tuple[str, str | tuple[str, ...]]] = [
    # rooms named by their owner
    ("a child's room", "children's room"),
    ("a princess's room", "children's room"),
    ("a pink princess room with a canopy bed", "children's room"),
    ("a fairy-tale princess bedroom", "bedroom"),  # a style, not an owner
    ("the kids' bedroom", "children's room"),
    ("a kid's room full of toys", "children's room"),
    ("a children's bedroom", "children's room"),
    ("a prince's room", "children's room"),
    ("a room for a 6-year-old", "children's room"),
    ("a 15-year-old's bedroom", "bedroom"),
    ("a 5 year old's room", "children's room"),
    ("a baby's room", "nursery"),
    ("a nursery with a rocking chair", "nursery"),
    ("a room for the newborn", "nursery"),
    ("a teenager's bedroom with posters", "bedroom"),
    ("a teen room", "bedroom"),
    ("a teenage girl's room", "bedroom"),
    ("a guest room", "guest room"),
    ("the guest bedroom", "guest room"),
    ("a master bedroom", "bedroom"),
    ("a master suite", "bedroom"),
    ("a student's room", "bedroom"),
    ("a dorm room for a student", "bedroom"),
    ("a teacher's room", "office"),
    # rooms named by their purpose
    ("a home office", "office"),
    ("a study with a desk", "office"),
    ("a small studio", "studio"),
    ("an artist's studio", "art studio"),
    ("a den with a big tv", "game den"),
    ("a playroom", "playroom"),
    ("a laundry", "laundry room"),
    ("a laundry room with a dryer", "laundry room"),
    ("a pantry with shelves of jars", "pantry"),
    ("a library", "library"),
    ("a reading room", "library"),
    ("a mudroom", "mudroom"),
    ("a walk-in closet", "walk-in closet"),
    ("a home gym", "gym"),
    ("a home bar", "home bar"),
    ("a wine cellar", "wine cellar"),
    ("a storage room", "storage room"),
    ("a powder room", "bathroom"),
    ("an en-suite", "bathroom"),
    ("a sunroom", "sunroom"),
    ("a media room", "game den"),
    ("a breakfast nook", "dining room"),
    ("a classroom", "classroom"),
    ("a staff room", "break room"),
    # plain English requests that worked before
    ("a cozy bedroom with a reading nook", "bedroom"),
    ("cyberpunk game den", "game den"),
    ("a kitchen where the robot picks up a mug", "kitchen"),
    ("an industrial garage workshop", "workshop"),
    ("a retro cafe", "cafe"),
    ("a scandinavian home gym", "gym"),
    ("a boho children's room", "children's room"),
    ("a futuristic meeting room", "meeting room"),
    ("a victorian library", "library"),
    # room words that are not rooms here
    ("a gym with a bath towel", "gym"),
    ("a living room with a flat screen tv", "living room"),
    ("a kitchen in a small apartment", "kitchen"),
    ("the bedroom of a villa", "bedroom"),
    ("a bedroom that feels like home", "bedroom"),
    ("a kitchen table with a mug", "kitchen"),
    # whole homes
    ("a house", _FLAT),
    ("an apartment", _FLAT),
    ("a flat", _FLAT),
    ("a cozy loft", _FLAT),
    ("a family home", _FAMILY),
    (
        "a family house with two kids' rooms",
        ("bedroom", "children's room", "children's room", *_FAMILY[2:]),
    ),
    (
        "a family apartment with a nursery",
        ("bedroom", "children's room", "nursery", *_FAMILY[2:]),
    ),
    (
        "a villa",
        ("bedroom", "bedroom", "living room", "kitchen", "dining room", "bathroom", "bathroom"),
    ),
    (
        "a mansion",
        ("bedroom",) * 3 + ("living room", "kitchen", "dining room", "library", "bathroom"),
    ),
    ("a four-room apartment", _FLAT),
    ("a three-room flat", ("bedroom", "kitchen", "bathroom")),
    (
        "a six-room house",
        ("bedroom", "bedroom", "living room", "kitchen", "dining room", "bathroom"),
    ),
    ("a studio apartment", ("studio", "bathroom")),
    ("a flat with two bedrooms", ("bedroom", *_FLAT)),
    ("a 3-bedroom house", ("bedroom", "bedroom", *_FLAT)),
    ("a student apartment with one bedroom", _FLAT),
    (
        "a house with a garage and a home office",
        ("bedroom", "garage", "office", "living room", "kitchen", "bathroom"),
    ),
    ("a two-bedroom apartment with a study", ("bedroom", "bedroom", "office", *_FLAT[1:])),
    ("a cottage with a pantry", ("bedroom", "pantry", "living room", "kitchen", "bathroom")),
    (
        "a penthouse with a home bar",
        ("bedroom", "bedroom", "home bar", *_FAMILY[2:], "bathroom"),
    ),
    # Spanish
    ("una cocina con una taza", "kitchen"),
    ("un dormitorio acogedor", "bedroom"),
    ("una sala de estar moderna", "living room"),
    ("un cuarto de baño", "bathroom"),
    ("una habitación infantil", "children's room"),
    ("una casa con dos dormitorios", ("bedroom", *_FLAT)),
    ("un piso de tres habitaciones", ("bedroom", "bedroom", *_FLAT)),
    ("la habitación de una princesa", "children's room"),
    ("una casa familiar", _FAMILY),
    # French
    ("une cuisine moderne avec une table", "kitchen"),
    ("une chambre d'enfant", "children's room"),
    ("un salon avec un canapé", "living room"),
    ("une salle de bain", "bathroom"),
    ("un appartement avec deux chambres", ("bedroom", *_FLAT)),
    ("une maison de quatre pièces", _FLAT),
    ("une chambre pour un bébé", "nursery"),
    # German
    ("eine Küche mit einer Tasse", "kitchen"),
    ("ein gemütliches Schlafzimmer", "bedroom"),
    ("ein Wohnzimmer mit Sofa", "living room"),
    ("ein Kinderzimmer", "children's room"),
    ("ein Büro mit Schreibtisch", "office"),
    ("ein Haus mit zwei Schlafzimmern", ("bedroom", *_FLAT)),
    ("ein Einfamilienhaus", _FAMILY),
    ("ein Zimmer für ein Baby", "nursery"),
    # Chinese
    ("厨房", "kitchen"),
    ("一间卧室", "bedroom"),
    ("一个现代的客厅", "living room"),
    ("儿童房", "children's room"),
    ("书房", "office"),
    ("浴室", "bathroom"),
    ("一个有两个卧室的公寓", ("bedroom", *_FLAT)),
    ("公主的房间", "children's room"),
    ("青少年的卧室", "bedroom"),
]


@pytest.mark.parametrize(("request_text", "expected"), TABLE, ids=[t for t, _ in TABLE])
def test_request_table(request_text: str, expected: str | tuple[str, ...]) -> None:
    parsed = parse_request(request_text)
    rooms = (expected,) if isinstance(expected, str) else expected
    assert parsed.room_types == rooms, parsed
    assert all(t in ROOM_TYPES for t in parsed.room_types)
    assert bool(parsed.home) == isinstance(expected, tuple)
    assert parsed.names_a_room and not parsed.unknown and not parsed.warnings
    assert room_types_in(request_text) == list(rooms)


def test_the_table_is_large_and_varied() -> None:
    assert len(TABLE) >= 60
    singles = {e for _, e in TABLE if isinstance(e, str)}
    assert len(singles) >= 15
    assert sum(isinstance(e, tuple) for _, e in TABLE) >= 15
    assert max(len(e) for _, e in TABLE if isinstance(e, tuple)) <= MAX_HOME_ROOMS


def test_approximated_room_types_carry_a_note() -> None:
    parsed = parse_request("a veterinary clinic")
    assert parsed.room_types == ("exam room",)
    assert parsed.notes and "veterinary" in parsed.notes[0] and "by meaning" in parsed.notes[0]
    assert not parse_request("a kitchen").notes


@pytest.mark.parametrize(
    ("request_text", "style", "conditions", "materials"),
    [
        ("a rusty dusty industrial garage", "industrial", ("rust", "dust"), ("rusty metal",)),
        ("a luxurious golden bathroom", "", ("luxury", "gold"), ("brass", "marble", "fabric")),
        ("a muddy worn mudroom", "", ("mud", "wear"), ()),
        ("an old oak library", "", ("wear",), ("oak",)),
        ("a five-year-old's room", "", (), ()),  # "old" of an age is no condition
        ("a 5 year old's dusty room", "", ("dust",), ()),
        ("a scratched walnut desk in a gothic office", "gothic", ("scratches",), ("walnut",)),
        (
            "a spotless modern kitchen with velvet chairs",
            "modern",
            ("clean", "luxury"),
            ("fabric",),
        ),
        ("ein rostiges Badezimmer", "", ("rust",), ("rusty metal",)),
        ("una cocina polvorienta", "", ("dust",), ()),
        ("une chambre dorée", "", ("gold",), ("brass",)),
        ("一个豪华的客厅", "", ("luxury",), ("brass", "marble", "fabric")),
    ],
)
def test_style_and_condition_words(
    request_text: str, style: str, conditions: tuple[str, ...], materials: tuple[str, ...]
) -> None:
    parsed = parse_request(request_text)
    assert parsed.style == style == style_of(request_text)
    assert parsed.conditions == conditions
    assert parsed.materials == materials
    summary = parsed.summary()
    assert summary.get("conditions", []) == list(conditions)


@pytest.mark.parametrize(
    "request_text",
    [
        "recoge la taza y ponla en el cuenco",
        "prends la tasse et mets-la dans le bol",
        "nimm die Tasse und stell sie in die Schüssel",
        "pick up the mug and put it in the bowl",
    ],
)
def test_tasks_are_read_in_every_language(request_text: str) -> None:
    task = parse_request(request_text).task
    assert task is not None and (task.pick, task.target) == ("mug", "bowl")


def test_unknown_words_are_flagged() -> None:
    parsed = parse_request("una cucina moderna con un tavolo")  # Italian
    assert parsed.room_types == ("living room",) and not parsed.names_a_room
    assert parsed.unknown == ("cucina", "tavolo")
    assert any("'cucina'" in w and "'tavolo'" in w for w in parsed.warnings)
    chinese = parse_request("一个厨房有一只猫")
    assert chinese.room_types == ("kitchen",) and chinese.language == "zh"
    assert chinese.unknown and "猫" in "".join(chinese.unknown)
    assert chinese.warnings and "Chinese" in chinese.warnings[0]


def test_english_requests_keep_their_text() -> None:
    for text in ("a dimly lit bedroom", "a salon", "a den", "a bedroom with a chaise longue"):
        parsed = parse_request(text)
        assert parsed.english == text and parsed.language == "en" and not parsed.translated
        assert not parsed.unknown
    mixed = parse_request("a bedroom with a taza")
    assert mixed.english == "a bedroom with a mug" and mixed.translated == (("taza", "mug"),)
