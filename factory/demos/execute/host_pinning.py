"""Page-locking existing host memory for the GPU's copies into it (CUDA driver API).

A device-to-host copy into ordinary (pageable) memory goes through a small staging buffer of
the driver: about 2 GB/s measured on an H200 node for the GPU demo executor's end-of-call image
copies (tens of gigabytes per call), against the link's 20+ GB/s into page-locked memory.
The recordings live in shared memory arenas (:mod:`factory.demos.execute.shared_frames`) that writer
processes map, so they cannot be allocated by CUDA; instead the arena's pages are registered
with ``cuMemHostRegister`` (they stay page-locked until unregistered), and copies into them run
at full speed. Warp sees registered memory as pinned.

Registration needs the CUDA driver (``libcuda``); without it (or when registration fails, e.g.
under a locked-memory limit) :func:`register` returns False and copies stay pageable.
"""

from __future__ import annotations

import ctypes
import logging
from functools import cache
from typing import Any

log = logging.getLogger(__name__)

_PORTABLE = 0x01
"""``CU_MEMHOSTREGISTER_PORTABLE``: the registration holds in every CUDA context."""


@cache
def _driver() -> Any:
    """The CUDA driver library, or None where there is none."""
    try:
        lib = ctypes.CDLL("libcuda.so.1")
    except OSError:
        return None
    lib.cuMemHostRegister_v2.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_uint]
    lib.cuMemHostUnregister.argtypes = [ctypes.c_void_p]
    lib.cuCtxPushCurrent_v2.argtypes = [ctypes.c_void_p]
    lib.cuCtxPopCurrent_v2.argtypes = [ctypes.POINTER(ctypes.c_void_p)]
    return lib


class _Current:
    """Makes a CUDA context current on this thread for the block (push/pop)."""

    def __init__(self, lib: Any, context: int) -> None:
        self.lib, self.context = lib, context

    def __enter__(self) -> None:
        self.lib.cuCtxPushCurrent_v2(ctypes.c_void_p(self.context))

    def __exit__(self, *exc: object) -> None:
        old = ctypes.c_void_p()
        self.lib.cuCtxPopCurrent_v2(ctypes.byref(old))


def register(address: int, nbytes: int, context: int) -> bool:
    """Page-locks ``nbytes`` of host memory from ``address`` for the GPU.

    Args:
        address: first byte (page-aligned is best; the driver rounds to pages).
        nbytes: length of the range (bytes).
        context: the CUDA context (``CUcontext`` as an int, e.g. a Warp device's ``context``).

    Returns:
        whether the range is now registered (False: no driver, or the driver refused; the
        reason is logged).
    """
    lib = _driver()
    if lib is None or nbytes <= 0:
        return False
    with _Current(lib, context):
        err = lib.cuMemHostRegister_v2(ctypes.c_void_p(address), nbytes, _PORTABLE)
    if err != 0:
        log.warning(
            "could not page-lock %.1f GB of host memory for GPU copies (CUDA error %d); "
            "copies stay pageable (slower). Raise the locked-memory limit (ulimit -l) to fix.",
            nbytes / 1e9,
            err,
        )
        return False
    return True


def unregister(address: int, context: int) -> None:
    """Ends the registration that starts at ``address`` (see :func:`register`)."""
    lib = _driver()
    if lib is None:
        return
    with _Current(lib, context):
        lib.cuMemHostUnregister(ctypes.c_void_p(address))
