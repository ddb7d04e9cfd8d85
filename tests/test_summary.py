"""The summary table: rows from every stage's result, the ``produced`` convention, layout."""

from __future__ import annotations

from pathlib import Path

import pytest

from factory.store import RunStore, Shard
from factory.summary import (
    DERIVED,
    Row,
    format_table,
    produced,
    run_rows,
    show_path,
    stage_rows,
)

# What each stage returned in the small profile's main job (manifest.json), and the words of
# its row.
RESULTS = {
    "generate": (
        {"done": 1, "skipped": 0, "total": 1, "scenes": 1},
        "1 scene generated, 1 in the run",
        "scenes/",
    ),
    "ingest": (
        {"done": 0, "skipped": 2, "total": 2, "scenes": 3},
        "0 scenes ingested, 2 up to date, 3 in the run",
        "scenes/",
    ),
    "augment": (
        {"done": 4, "skipped": 0, "total": 4, "kept": 3, "dropped": {"unstable": 1}},
        "3 variants kept, 1 dropped",
        "scenes/",
    ),
    "compile": ({"done": 2, "skipped": 0, "total": 2}, "2 models compiled", "scenes/*/model.xml"),
    "render": ({"done": 1, "skipped": 0, "total": 1}, "1 scene rendered", "scenes/*/renders/"),
    "validate": (
        {
            "done": 1,
            "skipped": 0,
            "total": 1,
            "scenes": 1,
            "collision_pct": 0.0,
            "stability_pct": 100.0,
        },
        "1 scene validated, collision 0.0 %, stability 100.0 %",
        "validate/summary.json",
    ),
    "export": (
        {"done": 2, "skipped": 0, "total": 2, "out": "/x/sage"},
        "2 scenes exported",
        "/x/sage",
    ),
    "demos": (
        {"episodes_stored": 2, "new_successes": 2, "failures": {}, "success_rate": 1.0},
        "2 episodes stored, 2 new, success 100 %",
        "episodes/shard-0.zarr",
    ),
    "dataset": (
        {
            "shards": 1,
            "exported": 1,
            "episodes": 2,
            "path": "runs/small/dataset/merged",
            "export_frames": 479,
            "export_seconds": 1.6,
            "merge_seconds": 0.8,
        },
        "2 episodes, 479 frames exported now",
        "dataset/merged",
    ),
}


@pytest.fixture
def store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> RunStore:
    monkeypatch.chdir(tmp_path)
    return RunStore("runs/small")


def test_every_stage_with_results_is_derived() -> None:
    assert set(RESULTS) == set(DERIVED)


@pytest.mark.parametrize("stage", sorted(RESULTS))
def test_rows_of_each_stage(stage: str, store: RunStore) -> None:
    result, words, path = RESULTS[stage]
    rows = stage_rows(stage, result, store, Shard(0, 1))
    assert rows[0] == Row(stage, words, path if path.startswith("/") else f"runs/small/{path}")
    assert rows[-1].stage == "log" and rows[-1].path == f"runs/small/logs/{stage}-0-of-1.log"


def test_produced_convention_wins_and_singular(store: RunStore) -> None:
    result = {
        "done": 5,
        "produced": [
            {"what": "checkpoints", "count": 1, "path": "train/last", "detail": "loss 0.12"},
            {"what": "policy card", "count": None, "path": "/abs/card.md"},
            {"what": "episodes", "count": 0, "path": ""},
        ],
    }
    (store.root / "train" / "last").mkdir(parents=True)
    rows = stage_rows("train", result, store, Shard(0, 1), seconds=3.0, log=False)
    assert rows == [
        Row("train", "1 checkpoint, loss 0.12", "runs/small/train/last/", 3.0),
        Row("", "policy card", "/abs/card.md"),
        Row("", "0 episodes", ""),
    ]
    # a stage with neither the convention nor a derivation: its scalars
    (entry,) = produced("mystery", {"n": 3, "path": "p", "nested": {"x": 1}}, store, Shard(0, 1))
    assert entry == {"what": "n 3", "count": None, "path": "p"}


def test_shard_paths_and_dataset_shard_mode(store: RunStore) -> None:
    shard = Shard(1, 2)
    rows = stage_rows("demos", RESULTS["demos"][0], store, shard)
    assert [r.path for r in rows] == [
        "runs/small/episodes/shard-1.zarr",
        "runs/small/episodes/summary-1-of-2.json",
        "runs/small/logs/demos-1-of-2.log",
    ]
    failed = {
        "episodes_stored": 3,
        "new_successes": 1,
        "failures": {"ik": 2},
        "success_rate": 1 / 3,
    }
    assert stage_rows("demos", failed, store, shard)[0].text == (
        "3 episodes stored, 1 new, success 33 %, failed: ik 2"
    )
    shard_mode = {"shard": 1, "shards": 2, "exported": 0, "path": "/d/shard-1", "export_frames": 0}
    assert (
        stage_rows("dataset", shard_mode, store, shard)[0].text == "0 shards exported, up to date"
    )


def test_show_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r" / "scenes").mkdir(parents=True)
    assert show_path("scenes", Path("r")) == "r/scenes/"
    assert show_path("scenes", tmp_path / "r") == "r/scenes/"
    assert show_path("/elsewhere/x.json", Path("r")) == "/elsewhere/x.json"
    assert show_path("", Path("r")) == ""
    assert show_path(".", Path("r")) == "r/"


def test_table_layout_and_run_rows(store: RunStore) -> None:
    results = {s: RESULTS[s][0] for s in ("generate", "validate", "demos", "dataset")}
    seconds = {"generate": 33.4, "validate": 1.5, "demos": 17.4, "dataset": 6.6}
    rows = run_rows(results, seconds, store, Shard(0, 1))
    assert [r.stage for r in rows] == ["generate", "validate", "demos", "", "dataset", "logs"]
    assert rows[-1].path == "runs/small/logs/"
    text = format_table("stage=all done:", rows)
    lines = text.splitlines()
    assert lines[0] == "stage=all done:" and all(ln.startswith("  ") for ln in lines[1:])
    assert lines[1].split()[:3] == ["generate", "33.4", "s"]
    # columns line up: every path starts in the same column
    starts = {ln.index("runs/small/") for ln in lines[1:]}
    assert len(starts) == 1, text
    assert format_table("t", []) == "t"
