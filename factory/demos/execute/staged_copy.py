"""Copying a GPU call's images into host memory that is not page-locked, at page-locked speed.

A device-to-host copy into ordinary (pageable) memory goes through a small staging buffer of the
CUDA driver: about 2 GB/s measured on an H200 node for the GPU demo executor's end-of-call image
copies (tens of gigabytes a call). Page-locking the destination instead (``cuMemHostRegister``
of the shared memory arena the writers read) copies at the link's speed, but locking 90 GB took
51 s on an H200 node, and while it runs the driver holds every other CUDA call of the process:
the first scene's kernel loading waited for it, and the stage's first GPU call with it
(``docs/DEMOS.md``, "On a bare GPU machine").

:class:`StagedCopy` copies through a few page-locked buffers of its own instead (allocated once,
:data:`CHUNK` bytes each): the device copies chunk ``i + 1`` into one buffer while host threads
copy the chunks before it on into the arena (numpy copies run outside Python's lock, several at
once), so the destination needs no locking. All CUDA calls stay on the calling thread.
"""

from __future__ import annotations

import logging
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

__all__ = ["BUFFERS", "CHUNK", "StagedCopy"]

log = logging.getLogger(__name__)

CHUNK = 64 << 20
"""Bytes of one staging buffer (64 MiB): large enough that a copy's fixed cost is small, small
enough that several buffers cost little page-locked memory."""

BUFFERS = 6
"""Staging buffers, and host threads copying out of them: one is filled over the link while the
others are copied on (a host copy into fresh pages, which the kernel must fault in and zero,
runs at a few GB/s per thread)."""


class StagedCopy:
    """Copies device arrays into host arrays through page-locked staging buffers (see the
    module). Make one per executor and device; the buffers are kept between calls.

    Args:
        wp: the ``warp`` module.
        device: the Warp device the sources live on (``cuda:0``; on ``cpu`` the buffers are
            ordinary memory and each copy is synchronous: the same path, for tests).
        chunk: bytes of one staging buffer.
        buffers: how many (and host threads).
    """

    def __init__(self, wp: Any, device: str, chunk: int = CHUNK, buffers: int = BUFFERS) -> None:
        if chunk <= 0 or buffers < 2:
            raise ValueError(f"StagedCopy: chunk={chunk} must be > 0 and buffers={buffers} >= 2")
        self.wp = wp
        self.device = wp.get_device(device)
        self.chunk = int(chunk)
        pinned = bool(self.device.is_cuda)
        self._bufs = [
            wp.empty(self.chunk, dtype=wp.uint8, device="cpu", pinned=pinned)
            for _ in range(buffers)
        ]
        self._views = [b.numpy() for b in self._bufs]
        self._pool = ThreadPoolExecutor(buffers, thread_name_prefix="staged-copy")

    def __call__(self, pairs: list[tuple[np.ndarray, Any]]) -> int:
        """Copies each source into its destination and returns when every byte has landed.

        Args:
            pairs: ``(dest, src)``: ``dest`` a C-contiguous host numpy array, ``src`` a
                contiguous Warp array on :attr:`device` whose bytes (``src.size`` elements)
                fit in ``dest``; the bytes are copied as they are, from ``dest``'s first byte.

        Returns:
            the bytes copied.

        Raises:
            ValueError: a destination is not contiguous, or smaller than its source.
        """
        wp = self.wp
        jobs: list[tuple[np.ndarray, int, int]] = []  # (dest bytes, src pointer, bytes)
        for dest, src in pairs:
            nbytes = int(src.size) * int(wp.types.type_size_in_bytes(src.dtype))
            if not dest.flags.c_contiguous or not src.is_contiguous:
                raise ValueError("StagedCopy: source and destination must be contiguous")
            if dest.nbytes < nbytes:
                raise ValueError(
                    f"StagedCopy: destination of {dest.nbytes} bytes for a source of {nbytes}"
                )
            if nbytes:
                jobs.append((dest.reshape(-1).view(np.uint8), int(src.ptr), nbytes))
        nbuf = len(self._bufs)
        landing: list[Future[Any] | None] = [None] * nbuf  # the host copy out of each buffer
        k = total = 0
        with wp.ScopedDevice(self.device):
            for dest, ptr, nbytes in jobs:
                for off in range(0, nbytes, self.chunk):
                    n = min(self.chunk, nbytes - off)
                    i = k % nbuf
                    k += 1
                    pending = landing[i]
                    if pending is not None:  # buffer i is free once its host copy is done
                        pending.result()
                    part = wp.array(
                        ptr=ptr + off, dtype=wp.uint8, shape=(n,), device=self.device, copy=False
                    )
                    # One chunk over the link (milliseconds), then its host copy runs on a
                    # thread beside the next chunks' (the slow part: fresh pages fault in).
                    wp.copy(self._bufs[i], part, count=n)
                    if self.device.is_cuda:
                        wp.synchronize_stream(self.device.stream)
                    landing[i] = self._pool.submit(
                        np.copyto, dest[off : off + n], self._views[i][:n]
                    )
                    total += n
            for f in landing:
                if f is not None:
                    f.result()
        return total

    def close(self) -> None:
        """Ends the host threads (the buffers go with the object)."""
        self._pool.shutdown()
