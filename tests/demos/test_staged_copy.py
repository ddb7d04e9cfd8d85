"""``factory.demos.execute.staged_copy.StagedCopy``: device arrays into unlocked host memory
through a few staging buffers, chunk by chunk, every byte where it belongs (on Warp's CPU
device: the same code path as CUDA's, without the page-locked buffers)."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")

from factory.demos.execute.staged_copy import StagedCopy
from factory.sim.backend import init_warp


@pytest.fixture(scope="module")
def warp() -> object:
    return init_warp()


@pytest.mark.parametrize(("chunk", "buffers"), [(1000, 2), (4096, 3), (1 << 20, 6)])
def test_every_byte_lands_in_its_destination(warp: object, chunk: int, buffers: int) -> None:
    rng = np.random.default_rng(0)
    sources = [
        rng.integers(0, 255, (37, 3 * 11 * 13), dtype=np.uint8),  # an rgb store (R, 3 H W)
        rng.integers(0, 65535, (37, 11 * 13), dtype=np.uint16),  # depth in mm
        rng.random((29, 143), dtype=np.float32),  # metric depth
        np.zeros((0, 5), np.uint8),  # a camera without rows
    ]
    copy = StagedCopy(wp, "cpu", chunk=chunk, buffers=buffers)
    dests = [np.full(a.shape, 7, a.dtype) for a in sources]
    pairs = [(d, wp.array(a, device="cpu")) for d, a in zip(dests, sources, strict=True)]
    assert copy(pairs) == sum(a.nbytes for a in sources)
    for d, a in zip(dests, sources, strict=True):
        np.testing.assert_array_equal(d, a)
    # a destination larger than its source keeps its tail; a second call reuses the buffers
    big = np.full(sources[0].size + 10, 9, np.uint8)
    copy([(big, pairs[0][1])])
    np.testing.assert_array_equal(big[: sources[0].size], sources[0].ravel())
    assert (big[sources[0].size :] == 9).all()
    copy.close()


def test_refuses_a_destination_that_does_not_fit(warp: object) -> None:
    copy = StagedCopy(wp, "cpu", chunk=64, buffers=2)
    src = wp.array(np.arange(100, dtype=np.uint16), device="cpu")
    with pytest.raises(ValueError, match="destination of 100 bytes for a source of 200"):
        copy([(np.zeros(100, np.uint8), src)])
    with pytest.raises(ValueError, match="contiguous"):
        copy([(np.zeros((100, 2), np.uint16)[:, 0], src)])
    with pytest.raises(ValueError, match="buffers=1"):
        StagedCopy(wp, "cpu", chunk=64, buffers=1)
    copy.close()
