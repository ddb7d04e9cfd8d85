"""``factory.cores``: worker defaults follow the process's affinity, not the machine's count."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from factory.cores import usable_cores


def test_usable_cores_is_the_affinity() -> None:
    assert usable_cores() == len(os.sched_getaffinity(0)) >= 1


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="Linux only")
def test_a_pinned_process_sizes_itself_to_its_cores() -> None:
    """A process pinned to one core (``taskset``, a SLURM allocation) counts one core, however
    many the machine has; the CPU backend's and the stability check's thread defaults follow."""
    code = (
        "import os; os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]});"
        "from factory.cores import usable_cores;"
        "from factory.sim.backend_cpu import CpuBackend;"
        "print(usable_cores(), CpuBackend().nthread)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == ["1", "1"], out.stdout + out.stderr
