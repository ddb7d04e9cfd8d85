"""Compiling a path's kernels in parallel before it runs (``factory.sim.kernel_preload``)."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")

from factory.sim.backend import init_warp
from factory.sim.kernel_preload import dry_launches, preload

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

init_warp()


@wp.kernel(module="unique")
def add_one(a: wp.array(dtype=float)):  # type: ignore[valid-type]
    a[wp.tid()] += 1.0


@wp.kernel(module="unique")
def times_two(a: wp.array(dtype=float)):  # type: ignore[valid-type]
    a[wp.tid()] *= 2.0


@wp.kernel(module="unique")
def count_down(n: wp.array(dtype=int)):  # type: ignore[valid-type]
    n[0] = n[0] - 1


def _path(a, n) -> None:  # type: ignore[no-untyped-def]
    """A path with a conditional loop, as MuJoCo Warp's solver has."""
    wp.launch(add_one, dim=a.shape[0], inputs=[a], device="cpu")

    def body() -> None:
        wp.launch(count_down, dim=1, inputs=[n], device="cpu")
        wp.launch(times_two, dim=a.shape[0], inputs=[a], device="cpu")

    wp.capture_while(n, while_body=body)


def test_preload_loads_the_modules_a_path_launches_and_runs_nothing(monkeypatch) -> None:
    """The dry trace runs no kernel (the arrays keep their values, the loop body runs once
    whatever its condition), records every module the path launches, and :func:`preload`
    loads them all; running the path for real afterwards loads nothing more."""
    a = wp.array(np.ones(4, np.float32), device="cpu")
    n = wp.array(np.array([3], np.int32), device="cpu")
    with dry_launches(wp) as found:
        _path(a, n)
    assert {m.name for m, _, _ in found.values()} == {
        k.module.name for k in (add_one, times_two, count_down)
    }
    assert a.numpy().tolist() == [1.0] * 4 and n.numpy().tolist() == [3]
    assert wp.launch is not None and wp.capture_while.__module__.startswith("warp")

    report = preload(wp, lambda: _path(a, n), workers=2)
    assert report.modules == 3 and not report.error
    assert report.compiled <= 3 and report.workers >= 1

    import warp._src.context as ctx

    loads: list[str] = []
    real_load = ctx.Module.load

    def load(self, device, block_dim=None, *args, **kwargs):  # type: ignore[no-untyped-def]
        if (device.context, 1) not in self.execs:
            loads.append(self.name)
        return real_load(self, device, block_dim, *args, **kwargs)

    monkeypatch.setattr(ctx.Module, "load", load)
    _path(a, n)
    assert loads == []
    assert a.numpy().tolist() == [16.0] * 4  # (1 + 1) * 2 ** 3: it ran for real


def test_a_trace_that_fails_still_loads_what_it_found() -> None:
    """An exception in the trace ends it and is reported; the modules launched before it
    are loaded (the real path compiles the rest when it launches them)."""
    a = wp.array(np.ones(2, np.float32), device="cpu")

    def trace() -> None:
        wp.launch(add_one, dim=2, inputs=[a], device="cpu")
        raise ValueError("garbage size from a dry launch")

    report = preload(wp, trace, workers=1)
    assert report.modules == 1
    assert "ValueError: garbage size" in report.error
    assert (wp.get_device("cpu").context, 1) in add_one.module.execs


def test_other_threads_launch_for_real_during_a_trace() -> None:
    """A trace records only its own thread's launches: another thread's launches during it
    run (the GPU pipeline traces the next scene while the current one runs); ``around_trace``
    is held during the trace only; the functions are Warp's own again afterwards."""
    import threading

    a = wp.array(np.ones(4, np.float32), device="cpu")
    b = wp.array(np.ones(4, np.float32), device="cpu")
    lock = threading.Lock()
    inside, other_done = threading.Event(), threading.Event()
    held: list[bool] = []

    def other() -> None:
        inside.wait(30)
        wp.launch(times_two, dim=4, inputs=[b], device="cpu")
        other_done.set()

    def trace() -> None:
        inside.set()
        assert other_done.wait(30)
        held.append(lock.locked())
        wp.launch(add_one, dim=4, inputs=[a], device="cpu")

    real = wp.launch
    t = threading.Thread(target=other)
    t.start()
    report = preload(wp, trace, workers=1, around_trace=lock)
    t.join()
    assert b.numpy().tolist() == [2.0] * 4  # the other thread's launch ran
    assert a.numpy().tolist() == [1.0] * 4  # the trace's did not
    assert report.modules == 1 and held == [True] and not lock.locked()
    assert wp.launch is real


def test_cache_lock_serialises_the_loads_of_two_processes(tmp_path) -> None:
    """A second process's preload waits while another holds the kernel cache's lock, and says
    how long it waited; without a cache folder there is no lock."""
    import subprocess
    import sys
    import time
    from types import SimpleNamespace

    from factory.sim.kernel_preload import LOCK_NAME, cache_lock

    holder = (
        "import fcntl, sys, time\n"
        f"f = open({str(tmp_path / LOCK_NAME)!r}, 'a'); fcntl.flock(f, fcntl.LOCK_EX)\n"
        "print('held', flush=True); time.sleep(1.5)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    fake = SimpleNamespace(config=SimpleNamespace(kernel_cache_dir=str(tmp_path)))
    t0 = time.perf_counter()
    with cache_lock(fake) as waited:
        assert waited >= 0.8 and time.perf_counter() - t0 >= 0.8
    proc.wait(timeout=30)
    with cache_lock(SimpleNamespace(config=SimpleNamespace(kernel_cache_dir=None))) as waited:
        assert waited == 0.0
