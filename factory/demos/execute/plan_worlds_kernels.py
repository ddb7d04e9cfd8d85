# mypy: ignore-errors
"""Warp kernels of :mod:`factory.demos.execute.plan_worlds` (the GPU physics of the ``episode``
execution).

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types.
Importing this module imports Warp (not cheap); only the runner imports it.
"""

import warp as wp


@wp.kernel
def keep_qpos(
    probe: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    qpos: wp.array2d(dtype=float),
    kept: wp.array3d(dtype=float),
):
    """After physics step ``step[0]`` (0-based, the counter not yet advanced): world ``w``'s
    configuration into ``kept[w, p]`` for each of its probes ``p`` at this step
    (``probe[w, p] == step[0]``; -1: no probe). ``probe``: (n, P); ``kept``: (n, P, nq)."""
    w, p = wp.tid()
    if probe[w, p] != step[0]:
        return
    for i in range(qpos.shape[1]):
        kept[w, p, i] = qpos[w, i]
