"""Requests to open or close a part ("open the fridge door"): the part, the object's category
and room read from the catalogue, the task that claims them, and the errors for objects that
do not open or do not belong in the room."""

from __future__ import annotations

import pytest

from factory.errors import ConfigError
from factory.scenes.brain import task_kind
from factory.scenes.part_read import PartSpec, check_part_request, read_part_task
from factory.scenes.request import parse_request, parse_task


@pytest.mark.parametrize(
    ("text", "kind", "role", "qualifier", "category", "room"),
    [
        ("open the fridge door", "open", "door", "", "upright_fridge", "kitchen"),
        (
            "a kitchen where the robot opens the top drawer",
            "open",
            "drawer",
            "top",
            "",
            "kitchen",
        ),
        ("close the microwave door", "close", "door", "", "microwave_oven", "kitchen"),
        ("open the wardrobe door", "open", "door", "", "built_in_wardrobe", "bedroom"),
        (
            "open the top drawer of the nightstand",
            "open",
            "drawer",
            "top",
            "bedside_cabinet",
            "bedroom",
        ),
        (
            "open the top drawer of the bedside cabinet",
            "open",
            "drawer",
            "top",
            "bedside_cabinet",
            "bedroom",
        ),
        (
            "shut the bottom drawer of the chest of drawers",
            "close",
            "drawer",
            "bottom",
            "drawer_chest",
            "bedroom",
        ),
        (
            "a kitchen where the robot closes the refrigerator door",
            "close",
            "door",
            "",
            "upright_fridge",
            "kitchen",
        ),
    ],
)
def test_part_requests_are_read(
    text: str, kind: str, role: str, qualifier: str, category: str, room: str
) -> None:
    parsed = parse_request(text)
    spec = parsed.task
    assert isinstance(spec, PartSpec), spec
    assert (spec.role, spec.qualifier, spec.category) == (role, qualifier, category)
    assert spec.instruction == text
    assert parsed.room_types == (room,)
    assert not parsed.warnings
    assert task_kind(spec.__dict__) == kind
    check_part_request(spec, parsed.room_types)  # no error


def test_pick_and_place_requests_are_unchanged() -> None:
    text = "a kitchen where the robot picks up a mug and puts it in the bowl"
    assert read_part_task(text) is None
    spec = parse_request(text).task
    assert spec == parse_task(text)
    assert spec is not None and task_kind(spec.__dict__) == "pick_place"
    assert read_part_task("bring the mug to the desk in the study") is None


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("open the garage door", r"the catalogue has no 'garage'; objects that open: .*fridge"),
        ("open the oven door", r"'oven' \(oven\) has no door or drawer that opens; objects"),
        (
            "a bathroom where the robot opens the fridge door",
            r"a bathroom holds no fridge \(upright_fridge\); ask for it in a kitchen",
        ),
        (
            "a kitchen where the robot opens the wardrobe door",
            r"a kitchen holds no wardrobe \(built_in_wardrobe\); ask for it in a bedroom",
        ),
    ],
)
def test_bad_part_requests_name_the_valid_choices(text: str, match: str) -> None:
    parsed = parse_request(text)
    spec = parsed.task
    assert isinstance(spec, PartSpec)
    with pytest.raises(ConfigError, match=match):
        check_part_request(spec, parsed.room_types)


def test_no_part_no_part_task() -> None:
    assert read_part_task("open the window") is None  # no door or drawer named
    assert read_part_task("a kitchen with an open shelf") is None
