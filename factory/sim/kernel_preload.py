"""Compiling a code path's GPU kernels in parallel before it first runs.

Warp compiles a kernel's module when the module is first launched, one module after the other:
a MuJoCo Warp scene's first step, its renderer and the executor's own kernels took 261 s on a
bare H100, nearly all of it in the compiler; with this module 75 s (86 module variants on 16
threads; ``benchmarks/results/demos-gpu16-h100-bare.json``). Which modules a path needs, and
with which block sizes, is decided on the host by the model (MuJoCo Warp builds kernels
specialised to it), not by values on the device (a grid size may come from an occupancy
query, never a kernel's choice): MuJoCo Warp's step is CUDA-graph capturable, its only
control flow being ``wp.capture_while`` and ``wp.capture_if``.

:func:`dry_launches` runs such a path with every launch recorded instead of run (the
conditional nodes run their bodies once), and :func:`preload` then loads the recorded modules
on a thread pool (Warp's own ``force_load`` does the same; the compiler runs outside Python's
lock). A module the trace missed still compiles when it is launched, as before: a trace can
only make the first launch faster, never change what runs. The trace's arrays hold garbage;
nothing of it may be kept.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

from factory.cores import usable_cores

log = logging.getLogger(__name__)

__all__ = ["PreloadReport", "dry_launches", "preload"]


@dataclass(frozen=True)
class PreloadReport:
    """What :func:`preload` did.

    Attributes:
        modules: module variants (module, device, block size) the trace launched.
        compiled: of those, the ones not loaded before (compiled, or read from the kernel cache).
        trace_s: seconds of the dry trace.
        load_s: seconds of the parallel load.
        workers: threads of the load.
        error: why the trace stopped early ("" if it ran through): the variants found until
            then were loaded; the rest compile at their first launch.
        wait_s: seconds waited for another process's preload (:func:`cache_lock`).
    """

    modules: int
    compiled: int
    trace_s: float
    load_s: float
    workers: int
    error: str = ""
    wait_s: float = 0.0

    def describe(self) -> str:
        """One line for the log: what was loaded, on how many threads, in how long."""
        early = f"; trace stopped early: {self.error}" if self.error else ""
        waited = (
            f"; waited {self.wait_s:.1f} s for another process's preload"
            if self.wait_s >= 0.5
            else ""
        )
        return (
            f"{self.compiled} modules to load of the {self.modules} launched, on {self.workers} "
            f"threads in {self.load_s:.1f} s (trace {self.trace_s:.1f} s){waited}{early}"
        )


LOCK_NAME = "factory-preload.lock"
"""The file in Warp's kernel cache folder that one preload at a time holds while it loads."""


@contextlib.contextmanager
def cache_lock(wp: Any) -> Iterator[float]:
    """Held while a preload loads its modules, across the processes of one machine that share
    Warp's kernel cache: the first compiles on every core, the next ones then read what it
    compiled from the cache instead of compiling the same modules at once with the same cores
    (three evaluation processes on a bare machine did). Yields the seconds waited for it;
    without a cache folder or ``fcntl`` (not POSIX), no lock."""
    folder = getattr(getattr(wp, "config", None), "kernel_cache_dir", None)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield 0.0
        return
    if not folder:
        yield 0.0
        return
    import os

    t0 = time.perf_counter()
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, LOCK_NAME), "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield time.perf_counter() - t0
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _block_dim(ctx: Any, device: Any, block_dim: int | None) -> int:
    resolve = getattr(ctx, "_resolve_launch_block_dim", None)
    if resolve is not None:
        return int(resolve(device, block_dim))
    if block_dim is None or block_dim <= 0:  # pragma: no cover - other Warp versions
        return 1 if device.is_cpu else 256
    return 1 if device.is_cpu else int(block_dim)  # pragma: no cover


@contextlib.contextmanager
def dry_launches(wp: Any) -> Iterator[dict[tuple[int, int, str], tuple[Any, Any, int]]]:
    """Within the block, ``wp.launch`` and ``wp.launch_tiled`` record the launched kernel's
    module, device and block size instead of running it, ``wp.capture_while`` and
    ``wp.capture_if`` call their bodies once (each branch), and
    ``wp.get_suggested_block_size`` records the module variant its occupancy query would load
    (and compile: 26-38 s for each of MuJoCo Warp's CCD kernels on a bare H200) and answers
    256 threads. Only the calling thread's calls are recorded; other threads' launches run
    as usual, and one trace runs at a time.

    Yields:
        ``(id(module), block_dim, device alias) -> (module, device, block_dim)``, filled as the
        block launches.
    """
    ctx = wp._src.context
    found: dict[tuple[int, int, str], tuple[Any, Any, int]] = {}

    def launch(kernel: Any, dim: Any, *args: Any, **kwargs: Any) -> None:
        device = ctx.get_device(kwargs.get("device") or (args[4] if len(args) > 4 else None))
        bd = _block_dim(ctx, device, kwargs.get("block_dim"))
        found[(id(kernel.module), bd, device.alias)] = (kernel.module, device, bd)

    def capture_while(condition: Any, while_body: Any, stream: Any = None, **kwargs: Any) -> None:
        if callable(while_body):
            while_body(**kwargs)

    def capture_if(
        condition: Any, on_true: Any = None, on_false: Any = None, stream: Any = None, **kw: Any
    ) -> None:
        for branch in (on_true, on_false):
            if callable(branch):
                branch(**kw)

    def suggested_block_size(kernel: Any, device: Any = None) -> tuple[int, int]:
        # Warp loads the module's default variant for the occupancy query (MuJoCo Warp asks it
        # for its CCD kernels' grid size): record that variant; the grid size does not change
        # which kernels a path launches.
        dev = ctx.get_device(device)
        if not dev.is_cuda:
            return (1, 1)
        bd = _block_dim(ctx, dev, kernel.module.options.get("block_dim"))
        found[(id(kernel.module), bd, dev.alias)] = (kernel.module, dev, bd)
        return (256, max(1, int(getattr(dev, "sm_count", 1) or 1)))

    dry: dict[str, Callable[..., Any]] = {
        "get_suggested_block_size": suggested_block_size,
        "launch": launch,
        "capture_while": capture_while,
        "capture_if": capture_if,
    }
    with _TRACE_LOCK:
        tracer = threading.get_ident()
        saved = {(owner, name): getattr(owner, name) for owner in (wp, ctx) for name in dry}
        try:
            for (owner, name), real in saved.items():
                setattr(owner, name, _this_thread(tracer, dry[name], real))
            yield found
        finally:
            for (owner, name), real in saved.items():
                setattr(owner, name, real)


_TRACE_LOCK = threading.Lock()
"""One trace at a time: :func:`dry_launches` patches Warp's module-level functions."""


def _this_thread(tracer: int, dry: Callable[..., Any], real: Callable[..., Any]) -> Any:
    """``dry`` for calls from the ``tracer`` thread, ``real`` for every other thread's (a
    scene's kernels are traced while another scene's call launches on the device)."""

    def call(*args: Any, **kwargs: Any) -> Any:
        if threading.get_ident() == tracer:
            return dry(*args, **kwargs)
        return real(*args, **kwargs)

    return call


def preload(
    wp: Any,
    trace: Callable[[], None],
    workers: int | None = None,
    around_trace: contextlib.AbstractContextManager[Any] | None = None,
) -> PreloadReport:
    """Runs ``trace`` under :func:`dry_launches` and loads the modules it launched, those not
    loaded yet, on ``workers`` threads (default: the cores this process may use).

    ``trace`` must repeat the launches of the real path (same model, options and block sizes;
    the number of worlds may be smaller) and keep nothing it makes. An exception in it is
    logged and ends the trace; what it found by then is still loaded. ``around_trace`` (e.g.
    a lock) is held during the trace only, not during the load; the load holds
    :func:`cache_lock` (one process of the machine at a time).
    """
    if workers is None:
        workers = usable_cores()
    t0 = time.perf_counter()
    error = ""
    with around_trace or contextlib.nullcontext(), dry_launches(wp) as found:
        try:
            trace()
        except Exception as e:  # the real path shows any real error
            error = f"{type(e).__name__}: {e}"
            log.info("kernel preload: the trace stopped early (%s); the rest compile on use", error)
    trace_s = time.perf_counter() - t0
    todo = [
        (module, device, bd)
        for module, device, bd in found.values()
        if (device.context, bd) not in getattr(module, "execs", {})
    ]
    n = max(1, min(workers, len(todo)))
    waited = 0.0
    t1 = time.perf_counter()
    if todo:
        with cache_lock(wp) as waited:
            t1 = time.perf_counter()
            with ThreadPoolExecutor(max_workers=n) as pool:
                for f in [pool.submit(m.load, d, block_dim=bd) for m, d, bd in todo]:
                    f.result()
    load_s = time.perf_counter() - t1
    return PreloadReport(len(found), len(todo), trace_s, load_s, n, error, waited)
