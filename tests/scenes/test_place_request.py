"""Put-away requests ("put the mug in the drawer", "put the mug in the microwave") are read for
``task=place_inside``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from factory.errors import FactoryError
from factory.scenes.brain_steps import task_kind
from factory.scenes.part_read import check_part_request
from factory.scenes.request import parse_any_task, parse_request, request_task

CASES = [
    ("put the mug in the drawer", "mug", "", "base_cabinet", "kitchen"),
    (
        "a kitchen where the robot puts the mug away in the drawer of the base cabinet",
        "mug",
        "",
        "base_cabinet",
        "kitchen",
    ),
    ("put the cup in the top drawer", "cup", "top", "base_cabinet", "kitchen"),
    (
        "a bedroom where the robot puts the book in the nightstand drawer",
        "book",
        "",
        "bedside_cabinet",
        "bedroom",
    ),
    ("put the phone in the drawer of the nightstand", "phone", "", "bedside_cabinet", "bedroom"),
    (
        "put the pill bottle in the drawer of the bedside table",
        "pill_bottle",
        "",
        "bedside_cabinet",
        "bedroom",
    ),
    ("put the mug in the top drawer of the dresser", "mug", "top", "drawer_chest", "bedroom"),
    (
        "put the candle in the drawer of the chest of drawers",
        "candle",
        "",
        "drawer_chest",
        "bedroom",
    ),
    # no drawer's object named: the first drawer container the request's room holds
    (
        "a bedroom where the robot puts the mug in the drawer",
        "mug",
        "",
        "bedside_cabinet",
        "bedroom",
    ),
]


DOOR_CASES = [
    ("put the mug in the microwave", "mug", "microwave_oven", "kitchen"),
    ("put the bottle in the fridge", "bottle", "upright_fridge", "kitchen"),
    ("put the cup in the cabinet", "cup", "base_cabinet", "kitchen"),
    ("put the cup in the cupboard", "cup", "base_cabinet", "kitchen"),
    ("put the mug away in the refrigerator", "mug", "upright_fridge", "kitchen"),
    ("put the mug in the nightstand", "mug", "bedside_cabinet", "bedroom"),
    # a cabinet not said which: the first door cabinet of the request's room
    ("a bedroom where the robot puts the cup in the cabinet", "cup", "bedside_cabinet", "bedroom"),
]


@pytest.mark.parametrize(("text", "item", "category", "room"), DOOR_CASES)
def test_put_behind_a_door_requests_are_place_inside(
    text: str, item: str, category: str, room: str
) -> None:
    """ "put the mug in the microwave": the role ``door`` implied, the object's category the
    container's; the kitchen or bedroom it belongs in."""
    request = parse_request(text)
    spec = request.task
    assert spec is not None
    assert task_kind(spec.__dict__) == "place_inside"
    assert (spec.item, spec.role, spec.category) == (item, "door", category)  # type: ignore[union-attr]
    assert request.room_types == (room,)
    check_part_request(spec, request.room_types)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "text", ["put the mug in the bowl", "put the mug in the oven", "put the mug on the table"]
)
def test_a_place_target_without_a_door_interior_is_no_put_away(text: str) -> None:
    spec = parse_any_task(text)
    assert spec is None or task_kind(spec.__dict__) != "place_inside", spec


def test_a_bad_put_behind_a_door_request_lists_the_choices() -> None:
    text = "put the spaceship in the microwave"
    spec = parse_any_task(text)
    assert spec is not None
    with pytest.raises(FactoryError, match="objects to put away: apple"):
        check_part_request(spec, parse_request(text).room_types)  # type: ignore[arg-type]


@pytest.mark.parametrize(("text", "item", "qualifier", "category", "room"), CASES)
def test_put_away_requests_are_place_inside(
    text: str, item: str, qualifier: str, category: str, room: str
) -> None:
    request = parse_request(text)
    spec = request.task
    assert spec is not None
    assert task_kind(spec.__dict__) == "place_inside"
    assert (spec.item, spec.qualifier, spec.category) == (item, qualifier, category)  # type: ignore[union-attr]
    assert request.room_types == (room,)
    check_part_request(spec, request.room_types)  # type: ignore[arg-type]


def test_pick_and_place_request_unchanged() -> None:
    spec = parse_any_task("a kitchen where the robot picks up a mug and puts it in the bowl")
    assert spec is not None
    assert task_kind(spec.__dict__) == "pick_place"
    assert (spec.pick, spec.target) == ("mug", "bowl")  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("put the mug in the fridge drawer", "drawers: base cabinet, bedside cabinet"),
        ("put the book in the wardrobe drawer", "drawers: base cabinet, bedside cabinet"),
        ("a kitchen where the robot puts the mug in the dresser drawer", "ask for it in a bedroom"),
        ("put the spaceship in the drawer", "objects to put away: apple"),
    ],
)
def test_bad_put_away_requests_list_the_choices(text: str, words: str) -> None:
    spec = parse_any_task(text)
    assert spec is not None
    with pytest.raises(FactoryError, match=words):
        check_part_request(spec, parse_request(text).room_types)  # type: ignore[arg-type]


@pytest.mark.slow
def test_generated_scene_is_place_inside(tmp_path: Path) -> None:
    """One kitchen for "put the mug in the drawer" (about 30 s on 2 cores)."""
    run = tmp_path / "run"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "factory",
            "stage=generate",
            f"run_dir={run}",
            "sim.backend=cpu",
            "generate.prompts=[put the mug in the drawer]",
            "generate.scenes_per_prompt=1",
        ],
        check=True,
        capture_output=True,
    )
    (scene,) = run.glob("scenes/*/scene.json")
    data = json.loads(scene.read_text())
    assert data["task"] == {"kind": "place_inside", "instruction": "put the mug in the drawer"}
    assert any(o.get("task_role") == "pick" and o["category"] == "mug" for o in data["objects"])


@pytest.mark.parametrize(
    ("request_text", "category"),
    [("a cosy bedroom", "bedside_cabinet"), ("a small kitchen", "base_cabinet")],
)
def test_a_separate_task_takes_the_drawer_of_the_requests_room(
    request_text: str, category: str
) -> None:
    """``generate.task`` "put the mug in the drawer" with a room request: the drawer's object
    is the first drawer container that room holds."""
    spec = request_task(request_text, "put the mug in the drawer")
    assert spec is not None and spec.category == category  # type: ignore[union-attr]
    check_part_request(spec, parse_request(request_text).room_types)  # type: ignore[arg-type]
