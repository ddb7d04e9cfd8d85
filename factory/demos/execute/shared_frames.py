"""Recording buffers that writer processes read in place (no pickling of images).

A GPU call of 512 worlds records tens of gigabytes of images. Handing each episode to a writer
process by pickling its arrays costs the main process about 60 ms per 180-frame episode at
3 x 128 px (a copy into the pickle and another through the pipe): as long as the GPU call
itself. Instead the call's frame buffers live in one anonymous shared memory file
(``memfd_create``, Linux; not bounded by the size of ``/dev/shm``), and a writer receives a
:class:`SharedView` (the file's ``/proc`` path, offset, shape, strides, dtype) and maps the
pages itself.

The main process keeps an :class:`Arena` open until every write that refers to it has finished,
then gives it back to its :class:`ArenaPool` for the next call (its pages stay resident);
:meth:`Arena.release` closes its file, and the pages are freed when the last view of the mapping
is gone.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

ALIGN = 4096
"""Byte alignment of the arrays inside an arena (one page)."""


def supported() -> bool:
    """Whether arenas work here (Linux: ``memfd_create`` and ``/proc/<pid>/fd``)."""
    return sys.platform.startswith("linux") and hasattr(os, "memfd_create")


@dataclass(frozen=True)
class SharedView:
    """Where an array lies in another process's arena (picklable; a few hundred bytes).

    Attributes:
        path: ``/proc/<pid>/fd/<fd>`` of the arena's memory file.
        size: the file's size (bytes).
        offset: the array's first byte in the file.
        shape, strides: the array's (strides in bytes).
        dtype: numpy dtype string.
    """

    path: str
    size: int
    offset: int
    shape: tuple[int, ...]
    strides: tuple[int, ...]
    dtype: str

    def open(self) -> np.ndarray:
        """The array, read-only, mapped from the arena (valid while the arena is open)."""
        with open(self.path, "rb") as f:
            mm = mmap.mmap(f.fileno(), self.size, prot=mmap.PROT_READ)
        return np.ndarray(
            self.shape, np.dtype(self.dtype), buffer=mm, offset=self.offset, strides=self.strides
        )


class Arena:
    """Arrays allocated in one shared memory file (zero-filled, pages taken on first touch).

    Args:
        nbytes: capacity (bytes); arrays are placed one after another, page-aligned.
        name: the file's name (shown in ``/proc/<pid>/fd``).
    """

    def __init__(self, nbytes: int, name: str = "factory-frames") -> None:
        if not supported():  # pragma: no cover - Linux only
            raise OSError("shared frame arenas need Linux (memfd_create)")
        self.size = max(ALIGN, int(nbytes))
        self.fd: int | None = os.memfd_create(name)
        os.ftruncate(self.fd, self.size)
        self.mm = mmap.mmap(self.fd, self.size)
        self._base = np.frombuffer(self.mm, np.uint8)
        self._addr = int(self._base.__array_interface__["data"][0])
        self._used = 0
        self.reused = False
        self.path = f"/proc/{os.getpid()}/fd/{self.fd}"

    def populate(self, nbytes: int) -> bool:
        """Allocates the pages of the arena's first ``nbytes`` now (``posix_fallocate`` of its
        memory file: the kernel takes and zeroes them), instead of at their first touch.

        A copy into fresh pages faults each in (the kernel takes and zeroes it) as it writes;
        populated ahead (in a thread while the stage's first plans are made), the first GPU
        call's image copy writes at memory speed.

        Returns:
            whether the pages were allocated (False where the file system refuses; they are
            then taken at first touch, as without this call).
        """
        need = min(self.size, -(-int(nbytes) // ALIGN) * ALIGN)
        if self.fd is None or need <= 0:
            return False
        try:
            os.posix_fallocate(self.fd, 0, need)
        except OSError:
            return False
        return True

    @staticmethod
    def bytes_for(specs: list[tuple[tuple[int, ...], Any]]) -> int:
        """Capacity for arrays of these ``(shape, dtype)``."""
        total = 0
        for shape, dtype in specs:
            n = int(np.prod(shape)) * np.dtype(dtype).itemsize
            total += -(-n // ALIGN) * ALIGN
        return total

    def reset(self) -> None:
        """Frees every array for new ones (their memory is reused as it is: not zeroed)."""
        self._used = 0
        self.reused = True

    def zeros(self, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        """A zero-filled array of ``shape`` in the arena."""
        out = self.empty(shape, dtype)
        if self.reused:
            out.fill(0)
        return out

    def empty(self, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        """An array of ``shape`` in the arena; zero in a new arena, old data after
        :meth:`reset` (for buffers the caller overwrites entirely)."""
        dt = np.dtype(dtype)
        n = int(np.prod(shape)) * dt.itemsize
        if self._used + n > self.size:
            raise MemoryError(f"arena of {self.size} bytes is full ({self._used} used, {n} asked)")
        out = self._base[self._used : self._used + n].view(dt).reshape(shape)
        self._used += -(-n // ALIGN) * ALIGN
        return out

    def view(self, a: np.ndarray) -> SharedView | None:
        """``a`` as a :class:`SharedView` if its memory lies in this arena, else None."""
        if self.fd is None or not isinstance(a, np.ndarray) or a.size == 0:
            return None
        start = int(a.__array_interface__["data"][0]) - self._addr
        if start < 0 or start >= self.size:
            return None
        # The furthest byte the view reaches must lie in the arena too.
        span = sum((n - 1) * abs(s) for n, s in zip(a.shape, a.strides, strict=True))
        if any(s < 0 for s in a.strides) or start + span + a.itemsize > self.size:
            return None
        return SharedView(self.path, self.size, start, a.shape, a.strides, a.dtype.str)

    def release(self) -> None:
        """Closes the memory file: no new reader can map it; the pages are freed once the
        views still alive (here and in readers) are gone."""
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __del__(self) -> None:  # pragma: no cover - best effort
        with contextlib.suppress(OSError):
            self.release()


class ArenaPool:
    """Arenas reused call after call, within a budget of bytes.

    Writing into fresh shared memory costs a page fault per 4 KiB page, four to five times the
    copy itself (measured: 3.8 against 0.8 ms per 6 MB frame block); an arena given back keeps
    its pages, so the next call writes at memory speed.

    Args:
        capacity: bytes all arenas together may take (pages are taken when first written).
        reclaim: called when no free arena fits and a new one would exceed ``capacity``: it
            should wait for the readers of arenas in use and :meth:`give` them back.
        headroom: a new arena is this much larger than asked (within the capacity), so that
            later, slightly larger calls reuse it.
    """

    def __init__(
        self,
        capacity: int,
        reclaim: Callable[[], None] | None = None,
        headroom: float = 1.25,
    ) -> None:
        self.capacity = int(capacity)
        self.reclaim = reclaim
        self.headroom = float(headroom)
        self._free: list[Arena] = []
        self._all: list[Arena] = []

    @property
    def total(self) -> int:
        """Bytes of every arena, free or in use."""
        return sum(a.size for a in self._all)

    def take(self, nbytes: int) -> Arena:
        """An arena with room for ``nbytes``: a free one if one is large enough, else a new
        one if the capacity allows (free arenas too small for it are released first), else
        one freed by ``reclaim`` (the owner waits for the readers of arenas in use), else a
        new one beyond the capacity."""
        arena = self.reserve(nbytes)
        if arena is None and self.reclaim is not None and len(self._all) > len(self._free):
            self.reclaim()
            arena = self.reserve(nbytes)
        if arena is None:
            arena = Arena(int(nbytes))
            self._all.append(arena)
        return arena

    def reserve(self, nbytes: int) -> Arena | None:
        """An arena with room for ``nbytes`` if one is free or can be made within the
        capacity now (without waiting for readers); None otherwise."""
        fits = [a for a in self._free if a.size >= nbytes]
        if fits:
            arena = min(fits, key=lambda a: a.size)
            self._free.remove(arena)
            arena.reset()
            return arena
        for small in list(self._free):  # too small for this call: make room
            if self.total + nbytes <= self.capacity:
                break
            self._free.remove(small)
            self._all.remove(small)
            small.release()
        room = self.capacity - self.total
        if nbytes > room:
            return None
        arena = Arena(min(room, int(self.headroom * nbytes)))
        self._all.append(arena)
        return arena

    def give(self, arena: Arena) -> None:
        """Returns ``arena`` once nothing reads it any more."""
        self._free.append(arena)

    def close(self) -> None:
        """Releases every arena (see :meth:`Arena.release`)."""
        for arena in self._all:
            arena.release()
        self._all, self._free = [], []


def share(arrays: dict[str, Any], arenas: list[Arena]) -> dict[str, Any]:
    """``arrays`` with every array that lies in one of ``arenas`` replaced by its
    :class:`SharedView` (the others unchanged)."""
    out: dict[str, Any] = {}
    for k, a in arrays.items():
        view = None
        for arena in arenas:
            view = arena.view(a) if isinstance(a, np.ndarray) else None
            if view is not None:
                break
        out[k] = a if view is None else view
    return out


def opened(arrays: dict[str, Any]) -> dict[str, Any]:
    """``arrays`` with every :class:`SharedView` mapped (the inverse of :func:`share`)."""
    return {k: a.open() if isinstance(a, SharedView) else a for k, a in arrays.items()}
