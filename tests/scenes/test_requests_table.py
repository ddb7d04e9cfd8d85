"""The request table (``requests_table.yaml``): each request's rooms, task and look words, as
:func:`~factory.scenes.request.parse_request` reads them (the parse only, no scene)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from factory.scenes.brain_steps import task_kind
from factory.scenes.request import parse_request

ROWS: list[dict[str, Any]] = yaml.safe_load(
    (Path(__file__).parent / "requests_table.yaml").read_text(encoding="utf-8")
)["requests"]


def test_the_table_is_large_and_varied() -> None:
    assert len(ROWS) >= 120
    kinds = {r["task"] for r in ROWS}
    assert {"pick_place", "mobile_pick_place", "none"} <= kinds


@pytest.mark.parametrize("row", ROWS, ids=[r["request"][:60] for r in ROWS])
def test_request_is_read_as_the_table_says(row: dict[str, Any]) -> None:
    parsed = parse_request(row["request"])
    assert list(parsed.room_types) == row["rooms"]
    task = parsed.task
    kind = "none" if task is None else task_kind(task.__dict__)
    assert kind == row["task"]
    if task is not None:
        assert (task.pick, task.target, task.source) == (row["pick"], row["target"], row["source"])
    assert list(parsed.colours) == row.get("colours", [])
    assert list(parsed.materials) == row.get("materials", [])
    assert list(parsed.conditions) == row.get("conditions", [])
