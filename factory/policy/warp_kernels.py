# mypy: ignore-errors
"""Warp kernels of the env's MuJoCo Warp simulation (:mod:`factory.policy.warp_sim`).

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types.
Importing this module imports Warp (not cheap); only the simulation imports it.
"""

import warp as wp


@wp.kernel
def frame_ctrl(
    steps: wp.array3d(dtype=float),
    k: int,
    ctrl: wp.array2d(dtype=float),
):
    """Each world's control of physics step ``k`` of the frame: ``ctrl[w, u] = steps[w, k,
    u]`` (``steps``: (worlds, steps per frame, nu), the frame's controls)."""
    w, u = wp.tid()
    ctrl[w, u] = steps[w, k, u]
