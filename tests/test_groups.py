"""The test groups of tests/conftest.py reach pytest-xdist's scheduler (the README's test command
runs ``-n auto --dist loadgroup``): a module stays in one process, so a shared run or Warp's CPU
kernels are built once per suite, not once per process."""

from __future__ import annotations

import pytest


def test_this_test_carries_its_group_under_loadgroup(request: pytest.FixtureRequest) -> None:
    """Under ``--dist loadgroup`` the scheduler groups by the ``@<group>`` suffix that xdist
    writes into each test id; pytest 9.2 ignores that write (pytest-xdist issue #1386), which
    silently turned the groups off (pyproject.toml pins pytest below 9.2)."""
    if not getattr(request.config.option, "loadgroup", False):  # set in xdist's workers
        pytest.skip("runs under the README's command (-n auto --dist loadgroup)")
    assert request.node.nodeid.endswith("@tests/test_groups.py"), request.node.nodeid
