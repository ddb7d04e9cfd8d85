"""Run store: atomic writes, shards, manifest under concurrency, stamps."""

from __future__ import annotations

import json
import multiprocessing as mp
from pathlib import Path

import pytest

from factory.errors import ConfigError, StoreError
from factory.store import RunStore, Shard, atomic_write_json, resolve_shard


def test_atomic_write_leaves_no_temp(tmp_path: Path) -> None:
    p = atomic_write_json(tmp_path / "a" / "b.json", {"x": 1})
    assert json.loads(p.read_text()) == {"x": 1}
    assert [q.name for q in p.parent.iterdir()] == ["b.json"]
    with pytest.raises(ValueError):
        atomic_write_json(p, {"x": float("nan")})
    assert json.loads(p.read_text()) == {"x": 1}  # the old content survives a failed write
    assert [q.name for q in p.parent.iterdir()] == ["b.json"]


@pytest.mark.parametrize("count", [1, 2, 3, 7, 50])
def test_shards_partition_items(count: int) -> None:
    items = [f"scene_{i:03d}" for i in range(23)]
    parts = [Shard(k, count).select(items) for k in range(count)]
    flat = [x for p in parts for x in p]
    assert sorted(flat) == sorted(items) and len(flat) == len(items)
    # independent of input order
    assert Shard(0, count).select(list(reversed(items))) == parts[0]
    sizes = [len(p) for p in parts]
    assert max(sizes) - min(sizes) <= 1


def test_shard_from_slurm_env() -> None:
    env = {"SLURM_ARRAY_TASK_ID": "3", "SLURM_ARRAY_TASK_COUNT": "4"}
    assert resolve_shard(None, None, env) == Shard(3, 4)
    env = {"SLURM_ARRAY_TASK_ID": "5", "SLURM_ARRAY_TASK_COUNT": "4", "SLURM_ARRAY_TASK_MIN": "2"}
    assert resolve_shard(None, None, env) == Shard(3, 4)
    assert resolve_shard(1, 2, env) == Shard(1, 2)  # explicit wins
    assert resolve_shard(None, None, {}) == Shard(0, 1)


@pytest.mark.parametrize(("index", "count"), [(2, 2), (-1, 3), (0, 0)])
def test_bad_shard(index: int, count: int) -> None:
    with pytest.raises(ConfigError, match="shard"):
        Shard(index, count)


def test_run_dir_required() -> None:
    with pytest.raises(ConfigError, match="run_dir is required"):
        RunStore("")


def _record(run_dir: str, k: int) -> None:
    RunStore(run_dir).record_stage("compile", Shard(k, 8), "done", {"seed": 0}, n=k)


def test_manifest_survives_concurrent_shards(tmp_path: Path) -> None:
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_record, args=(str(tmp_path), k)) for k in range(8)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    manifest = RunStore(tmp_path).read_manifest()
    shards = manifest["stages"]["compile"]["shards"]
    assert sorted(shards) == sorted(f"{k}-of-8" for k in range(8))
    assert manifest["stages"]["compile"]["status"] == "done"
    assert manifest["schema_version"] == 1


def test_manifest_of_other_version_is_refused(tmp_path: Path) -> None:
    (tmp_path / "manifest.json").write_text('{"schema_version": 99}')
    with pytest.raises(StoreError, match="schema_version 99"):
        RunStore(tmp_path).read_manifest()
    (tmp_path / "manifest.json").write_text('{"schema_ver')
    with pytest.raises(StoreError, match="corrupt"):
        RunStore(tmp_path).read_manifest()


def test_stamps(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    item = tmp_path / "scenes" / "a"
    item.mkdir(parents=True)
    (item / "out.txt").write_text("x")
    assert not store.is_done(item, "step", "h1")
    store.mark_done(item, "step", "h1", ["out.txt"])
    assert store.is_done(item, "step", "h1")
    assert not store.is_done(item, "step", "h2")  # inputs changed
    (item / "out.txt").unlink()
    assert not store.is_done(item, "step", "h1")  # output gone
