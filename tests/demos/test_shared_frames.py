"""Shared recording buffers: writer processes read frame-major slices in place."""

from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from factory.demos.execute.shared_frames import (
    Arena,
    ArenaPool,
    SharedView,
    opened,
    share,
    supported,
)

pytestmark = pytest.mark.skipif(not supported(), reason="memfd_create is Linux only")


def _checksum(arrays: dict[str, object]) -> dict[str, int]:
    return {k: int(np.asarray(a, np.int64).sum()) for k, a in opened(arrays).items()}


def test_arena_views_round_trip_through_a_process() -> None:
    f, n, h, w = 5, 4, 6, 7
    arena = Arena(Arena.bytes_for([((f, n, h, w, 3), np.uint8), ((f, n, 3), np.float64)]))
    rgb = arena.zeros((f, n, h, w, 3), np.uint8)
    state = arena.zeros((f, n, 3), np.float64)
    assert not rgb.any() and not state.any()
    rng = np.random.default_rng(0)
    rgb[:] = rng.integers(0, 255, rgb.shape)
    state[:] = rng.normal(size=state.shape)
    other = np.arange(6)
    # World 2's first 3 frames: a strided view, as the GPU executor's recordings are.
    arrays = {"rgb": rgb[:3, 2], "state": state[:3, 2], "other": other}
    shared = share(arrays, [arena])
    assert isinstance(shared["rgb"], SharedView) and isinstance(shared["state"], SharedView)
    assert shared["other"] is other
    np.testing.assert_array_equal(shared["rgb"].open(), rgb[:3, 2])
    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        got = pool.submit(_checksum, shared).result()
    assert got == {k: int(np.asarray(a, np.int64).sum()) for k, a in arrays.items()}
    arena.release()
    with pytest.raises(OSError):
        shared["rgb"].open()  # the memory file is closed: no new reader
    assert rgb.sum() > 0  # the main process's views stay valid


def test_arena_refuses_overflow_and_foreign_arrays() -> None:
    arena = Arena(4096)
    arena.zeros((4096,), np.uint8)
    with pytest.raises(MemoryError, match="full"):
        arena.zeros((1,), np.uint8)
    assert arena.view(np.zeros(3)) is None
    arena.release()


def test_pool_reuses_arenas_given_back() -> None:
    pool = ArenaPool(1 << 20)
    a = pool.take(4096)
    assert a.size == 5120  # what was asked and a quarter more
    x = a.empty((8,), np.int64)
    x[:] = 7
    b = pool.take(4096)  # a is still in use: another arena
    assert b is not a
    pool.give(a)
    c = pool.take(4096)
    assert c is a
    assert (c.empty((8,), np.int64) == 7).all()  # reused as it is
    c.reset()
    assert not c.zeros((8,), np.int64).any()  # zeros() zeroes a reused arena
    assert pool.take(2 << 20).size == 2 << 20  # larger than the capacity: its own size
    pool.close()
    assert a.fd is None and b.fd is None


def test_pool_waits_for_readers_only_beyond_its_capacity() -> None:
    """A small arena is made beside a large one in use (no waiting for its readers); a call
    that would exceed the capacity reclaims first, and free arenas too small are released."""
    given: list[Arena] = []
    pool = ArenaPool(1 << 20, reclaim=lambda: [pool.give(x) for x in given if x not in pool._free])
    big = pool.take(600_000)
    given.append(big)
    small = pool.take(100_000)  # fits beside the big one: no reclaim
    assert small is not big and big not in pool._free
    assert pool.total <= 1 << 20
    given.append(small)
    again = pool.take(700_000)  # would exceed the capacity: readers reclaimed, big reused
    assert again is big
    assert pool.reserve(900_000) is None  # small is free but too small; big in use
    pool.close()


def test_populate_allocates_the_pages_ahead_and_keeps_the_contents() -> None:
    """``Arena.populate`` takes the memory file's pages now (what page-locking would otherwise
    fault in while the CUDA driver waits); arrays already in the arena keep their values."""
    arena = Arena(64 * 4096)
    x = arena.empty((16,), np.int64)
    x[:] = 5
    before = os.fstat(arena.fd).st_blocks * 512
    assert arena.populate(40 * 4096)
    after = os.fstat(arena.fd).st_blocks * 512
    assert before < 40 * 4096 <= after < 64 * 4096
    assert (x == 5).all()
    assert not arena.zeros((8,), np.int64).any()  # a fresh arena's pages read as zeros
    arena.release()
    assert not arena.populate(4096)  # a released arena: nothing to allocate
