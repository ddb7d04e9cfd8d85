"""The episode store's disk room: stage=demos stops before the disk fills, keeping its episodes."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from factory.demos.record import disk_room
from factory.demos.record.disk_room import MIN_MEASURED, DiskFull, DiskRoom
from factory.demos.record.episodes import EpisodeStore
from factory.demos.record.slots import episode_id
from factory.schema import scene_to_json


def _free_sequence(monkeypatch: pytest.MonkeyPatch, values: list[float]) -> None:
    """The disk's free bytes, one value per question (the last one repeated): a full disk
    cannot be made here, so its free space is what the test says."""
    it = iter(values)
    last = [values[0]]

    def free(path: Path) -> int:
        last[0] = next(it, last[0])
        return int(last[0])

    monkeypatch.setattr(disk_room, "_free", free)


def test_stops_when_the_episodes_left_do_not_fit(monkeypatch, tmp_path: Path) -> None:
    # 10 GB free at the start; 40 episodes later 6 GB: 100 MB an episode, 60 left need 6.3 GB
    _free_sequence(monkeypatch, [10e9, 6e9])
    room = DiskRoom(tmp_path / "shard-0.zarr", stored=5, to_make=100)
    with pytest.raises(DiskFull) as e:
        room.check(stored_now=45, made_or_failed=40)
    msg = str(e.value)
    assert "60 episode(s) left need about 6.3 GB" in msg and "100.0 MB an episode" in msg
    assert "6.0 GB are free" in msg and "demos.episodes_per_scene" in msg
    assert "45 stored episode(s) are kept" in msg


def test_goes_on_when_they_fit_or_too_few_are_measured(monkeypatch, tmp_path: Path) -> None:
    _free_sequence(monkeypatch, [10e9, 9e9])
    room = DiskRoom(tmp_path / "runs" / "shard-0.zarr", stored=0, to_make=100)
    room.check(stored_now=50, made_or_failed=50)  # 20 MB an episode, 50 left: 1.05 GB of 9
    _free_sequence(monkeypatch, [10e9, 1e6])
    room = DiskRoom(tmp_path / "shard-0.zarr", stored=0, to_make=100)
    room.check(stored_now=MIN_MEASURED - 1, made_or_failed=MIN_MEASURED - 1)  # too few yet
    room.check(stored_now=MIN_MEASURED, made_or_failed=100)  # nothing left


def test_free_space_of_a_folder_not_made_yet(tmp_path: Path) -> None:
    assert (
        disk_room._free(tmp_path / "a" / "b" / "shard-0.zarr") == shutil.disk_usage(tmp_path).free
    )


def test_demos_stage_stops_before_the_disk_fills(monkeypatch, make_kitchen, tmp_path) -> None:
    """The CPU item loop checks after each item: the second scene is not started, the first
    one's episode is kept, and a re-run with room goes on from it."""
    from factory.__main__ import main

    run = tmp_path / "run"
    scene = make_kitchen(run / "assets")
    for sid in ("a_kitchen", "b_kitchen"):
        (run / "scenes" / sid).mkdir(parents=True)
        (run / "scenes" / sid / "scene.json").write_text(scene_to_json(replace(scene, id=sid)))
    monkeypatch.setattr(disk_room, "MIN_MEASURED", 1)
    # 1 GB free at the start, 0.4 GB after the first episode: the one left needs 0.63 GB
    _free_sequence(monkeypatch, [1e9, 4e8])
    args = [
        "stage=demos",
        f"run_dir={run}",
        "demos.episodes_per_scene=1",
        "demos.width=32",
        "demos.height=32",
        "demos.workers=1",
        "demos.executor=cpu",
    ]
    assert main(args) == 2
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    assert store.episode_ids() == [episode_id("a_kitchen", 0)]
    _free_sequence(monkeypatch, [1e9])  # space freed: the run goes on from the stored episode
    assert main(args) == 0
    assert store.episode_ids() == [episode_id("a_kitchen", 0), episode_id("b_kitchen", 0)]
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["new_successes"] == 1


def test_gpu_pipeline_stops_before_a_scene(monkeypatch, make_kitchen, tmp_path: Path) -> None:
    """The GPU pipeline asks before each scene (here the first: an episode stored since the
    room was measured took the free space): nothing is planned or recorded, the error is
    DiskFull."""
    from factory.config import DemosConfig
    from factory.demos.gpu_pipeline import run_gpu
    from factory.demos.record.slots import StageEnv, WorkItem

    run = tmp_path / "run"
    scene = make_kitchen(run / "assets")
    (run / "scenes" / scene.id).mkdir(parents=True)
    (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    store_path = run / "episodes" / "shard-0.zarr"
    monkeypatch.setattr(disk_room, "MIN_MEASURED", 1)
    _free_sequence(monkeypatch, [1e9, 1e6])
    room = DiskRoom(store_path, stored=0, to_make=4)
    store = EpisodeStore(store_path)
    store._ensure_root()
    (store_path / "earlier-ep000").mkdir()  # counted as stored since the room was measured
    (store_path / "earlier-ep000" / "zarr.json").write_text("{}")
    env = StageEnv(str(run), str(store_path), DemosConfig(sleep=False), "pick_place", 0, 1)
    with pytest.raises(DiskFull, match="4 episode"):
        run_gpu(env, [WorkItem(scene.id, (0, 1, 2, 3))], 1, device="cpu", room=room)
    assert store.episode_ids() == ["earlier-ep000"]
