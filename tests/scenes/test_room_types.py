"""Room types: the data file's programs are well-formed, requests name the 60 room types (in
English and in the other languages read), and rooms no name matches go to the nearest room
type by meaning."""

from __future__ import annotations

import logging

import pytest

from factory.errors import RoomDataError
from factory.scenes.request import DEFAULT_ROOM, parse_request
from factory.scenes.room_data import parse_room_types
from factory.scenes.room_meaning import THRESHOLD, nearest_room_type
from factory.scenes.room_program import KEYED_RULES, RULES
from factory.scenes.rooms import ROOM_TYPES

NEW_TYPES = """waiting room, exam room, patient room, dental office, pharmacy, grocery store,
clothing store, bakery, restaurant, pub, hotel room, lobby, lecture hall, laboratory,
computer lab, art studio, workshop, music room, home theater, yoga studio, japanese room,
sunroom, attic, basement, pantry, walk-in closet, mudroom, playroom, guest room, server room,
storage room, utility room, hair salon, spa room, locker room, break room, craft room,
sewing room, wine cellar, reception"""


def test_at_least_fifty_room_types_with_the_new_ones() -> None:
    new = [t.strip() for t in NEW_TYPES.replace("\n", " ").split(",")]
    assert len(new) == 40 and not set(new) - set(ROOM_TYPES)
    assert len(ROOM_TYPES) >= 50


@pytest.mark.parametrize("name", sorted(ROOM_TYPES))
def test_room_program_is_well_formed(name: str) -> None:
    rt = ROOM_TYPES[name]
    (w0, w1), (l0, l1) = rt.size
    assert 1.5 <= w0 <= w1 <= 12 and 1.5 <= l0 <= l1 <= 12
    assert rt.floors and rt.walls and rt.fillers and rt.words
    keys = {it.key for it in rt.items if it.key}
    floor = [it for it in rt.items if it.rule in RULES and it.rule != "mount"]
    assert floor, "no furniture on the floor"
    assert len(rt.items) >= 5
    for it in rt.items:
        kind, _, key = it.rule.partition(":")
        assert (kind in RULES and not key) or (kind in KEYED_RULES and key in keys), it
        assert 0 <= it.count[0] <= it.count[1] and 0 <= it.p <= 1 and it.text.strip()
    supports = {it.rule.partition(":")[2] for it in rt.items if it.rule.startswith("on:")}
    assert supports <= keys


def test_every_name_means_one_room_type() -> None:
    names = [n for n, rt in ROOM_TYPES.items() for n in (n, *rt.aliases)]
    assert len(names) == len(set(names))


def _entry(**over: object) -> dict[str, object]:
    entry: dict[str, object] = {
        "size": [[3, 4], [3, 4]],
        "floors": ["oak"],
        "walls": ["paint"],
        "items": [{"text": "desk", "key": "desk"}, {"text": "mug", "rule": "on:desk"}],
    }
    entry.update(over)
    return entry


@pytest.mark.parametrize(
    ("entry", "words"),
    [
        (
            _entry(items=[{"text": "desk", "rule": "ceiling"}]),
            ["items[0].rule", "wall", "on:<key>"],
        ),
        (_entry(items=[{"text": "mug", "rule": "on:desk"}]), ["items[0].rule", "'desk'"]),
        (_entry(items=[{"text": "desk", "count": [3, 1]}]), ["items[0].count", "min <= max"]),
        (_entry(items=[{"text": "desk", "colour": "red"}]), ["items[0].colour", "text, count"]),
        (_entry(size=[[4, 3], [3, 4]]), ["size", "min <= max"]),
        (_entry(floors=[]), ["floors", "non-empty"]),
        (_entry(smell="fresh"), ["smell", "unknown field", "size, floors"]),
        ({"size": [[3, 4], [3, 4]]}, ["floors", "missing"]),
    ],
)
def test_bad_entries_name_the_room_the_field_and_what_is_allowed(
    entry: dict[str, object], words: list[str]
) -> None:
    with pytest.raises(RoomDataError) as e:
        parse_room_types({"den of errors": entry})
    assert "'den of errors'" in str(e.value)
    assert all(w in str(e.value) for w in words), str(e.value)


def test_an_alias_names_one_room_type_only() -> None:
    with pytest.raises(RoomDataError, match="'study' already names 'office'"):
        parse_room_types(
            {"office": _entry(aliases=["study"]), "library": _entry(aliases=["study"])}
        )
    with pytest.raises(RoomDataError, match="'office' already names 'office'"):
        parse_room_types({"office": _entry(), "library": _entry(aliases=["office"])})


REQUESTS: list[tuple[str, str]] = [
    # the examples
    ("a clinic's waiting room", "waiting room"),
    ("a patient's room", "patient room"),
    ("a traditional Japanese room", "japanese room"),
    ("an artist's studio", "art studio"),
    ("a garage workshop", "workshop"),
    ("a bakery kitchen", "bakery"),
    # names and aliases of the new room types
    ("a doctor's exam room", "exam room"),
    ("a hospital room with a window", "patient room"),
    ("a dentist's office", "dental office"),
    ("a small drugstore", "pharmacy"),
    ("a supermarket aisle", "grocery store"),
    ("a fashion boutique", "clothing store"),
    ("an italian restaurant", "restaurant"),
    ("a cozy irish pub", "pub"),
    ("a hotel suite", "hotel room"),
    ("a grand hotel lobby", "lobby"),
    ("a university lecture hall", "lecture hall"),
    ("a chemistry lab", "laboratory"),
    ("a school computer lab", "computer lab"),
    ("a recording studio", "music room"),
    ("a home cinema", "home theater"),
    ("a yoga studio", "yoga studio"),
    ("a washitsu", "japanese room"),
    ("a tatami room", "japanese room"),
    ("a conservatory full of plants", "sunroom"),
    ("a dusty attic", "attic"),
    ("an unfinished basement", "basement"),
    ("a walk-in pantry", "pantry"),
    ("a dressing room", "walk-in closet"),
    ("a boot room", "mudroom"),
    ("a playroom", "playroom"),
    ("the guest bedroom", "guest room"),
    ("a small data center", "server room"),
    ("a stockroom", "storage room"),
    ("a janitor's closet", "utility room"),
    ("a barbershop", "hair salon"),
    ("a day spa", "spa room"),
    ("a gym locker room", "locker room"),
    ("an office break room", "break room"),
    ("a craft room", "craft room"),
    ("a sewing room", "sewing room"),
    ("a wine cellar", "wine cellar"),
    ("a reception area", "reception"),
    # the old types still read
    ("a cozy bedroom", "bedroom"),
    ("a home office", "office"),
    # other languages
    ("una sala de espera", "waiting room"),
    ("una panadería", "bakery"),
    ("une pharmacie", "pharmacy"),
    ("un grenier poussiéreux", "attic"),
    ("ein Friseursalon", "hair salon"),
    ("ein Krankenzimmer", "patient room"),
    ("ein Weinkeller", "wine cellar"),
    ("一间和室", "japanese room"),
    ("面包店", "bakery"),
    ("候诊室", "waiting room"),
]


@pytest.mark.parametrize(("text", "expected"), REQUESTS, ids=[t for t, _ in REQUESTS])
def test_requests_name_their_room_type(text: str, expected: str) -> None:
    parsed = parse_request(text)
    assert parsed.room_types == (expected,), parsed
    assert parsed.names_a_room and not parsed.warnings


MEANINGS: list[tuple[str, str]] = [
    ("a veterinary clinic", "exam room"),
    ("a doctor's surgery", "exam room"),
    ("a nail salon", "hair salon"),
    ("a recording booth", "music room"),
    ("a carpentry shop", "workshop"),
    ("a greenhouse", "sunroom"),
    ("a nursing station", "patient room"),
    ("a museum gallery", "art studio"),
    ("a tailor's", "sewing room"),
]


@pytest.mark.parametrize(("text", "expected"), MEANINGS, ids=[t for t, _ in MEANINGS])
def test_unknown_rooms_go_to_the_nearest_type_by_meaning(
    text: str, expected: str, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.INFO, logger="factory.scenes.room_meaning"):
        parsed = parse_request(text + " ")  # a new text: parse_request caches
    assert parsed.rooms == () and parsed.guess is not None
    assert parsed.room_types == (expected,) and parsed.guess.score >= THRESHOLD
    assert parsed.names_a_room and not parsed.warnings
    assert any(f"-> {expected} (score" in r.getMessage() for r in caplog.records)
    assert any("by meaning" in n for n in parsed.notes)


@pytest.mark.parametrize(
    "text", ["pick up the mug and put it in the bowl", "a cyberpunk scene", "xyzzy", "a forest"]
)
def test_requests_far_from_every_room_keep_the_default(text: str) -> None:
    parsed = parse_request(text)
    assert parsed.guess is None and parsed.room_types == (DEFAULT_ROOM,)
    assert any("no known room type" in w for w in parsed.warnings)


def test_a_low_score_is_logged_and_the_default_kept(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="factory.scenes.room_meaning"):
        assert nearest_room_type("a spaceship") is None
    assert any("default kept" in r.getMessage() for r in caplog.records)
