"""The CPU cores this process may use: its affinity (``taskset``, a SLURM allocation, a cgroup's
cpuset), not the machine's count. Every default that sizes worker processes or threads from the
machine reads :func:`usable_cores`, so that a job pinned to a share of a node sizes itself to
that share instead of oversubscribing the node."""

from __future__ import annotations

import os


def usable_cores() -> int:
    """CPU cores this process may run on: ``len(os.sched_getaffinity(0))`` where the system
    tells it (Linux), else ``os.cpu_count()``; at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)
