"""Warp set up by the project prints nothing on the terminal (``factory.sim.backend.init_warp``).

No ``from __future__ import annotations`` here: Warp reads the kernel's annotations as types.
"""

import pytest

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

wp = pytest.importorskip("warp")


@wp.kernel
def _twice(a: wp.array(dtype=float)):
    i = wp.tid()
    a[i] = 2.0 * a[i]


def test_warp_module_loads_print_nothing(capfd: pytest.CaptureFixture[str]) -> None:
    """Warp 1.19 prints a line per module it loads or compiles to stdout unless its log level
    is above info (its old ``config.quiet`` no longer exists); after ``init_warp`` a kernel
    builds and runs without a word."""
    from factory.sim.backend import init_warp

    init_warp()
    x = wp.ones(4, dtype=float, device="cpu")
    wp.launch(_twice, dim=4, inputs=[x], device="cpu")
    wp.synchronize()
    out, err = capfd.readouterr()
    assert "load on device" not in out + err and "Module" not in out
    assert x.numpy().tolist() == [2.0] * 4
