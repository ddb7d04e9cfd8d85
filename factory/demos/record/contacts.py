"""The robot's contacts with the scene: how deep the arm went into what it may not touch.

Shared by the demos' executors (``factory/demos/execute/cpu.py``, the policies' env) and the
tasks that simulate their own episodes (``factory/tasks/articulated/record.py``).
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["robot_penetration"]


def robot_penetration(
    model: mujoco.MjModel, data: mujoco.MjData, robot_geom: np.ndarray, allowed: np.ndarray
) -> float:
    """Deepest contact between a robot geom and a scene geom not in ``allowed`` (m; 0 where
    none penetrates), over the contacts' arrays at once."""
    n = int(data.ncon)
    if n == 0:
        return 0.0
    geom = np.asarray(data.contact.geom)[:n]
    dist = np.asarray(data.contact.dist)[:n]
    first = robot_geom[geom[:, 0]]
    other = np.where(first, geom[:, 1], geom[:, 0])
    hit = (first != robot_geom[geom[:, 1]]) & ~allowed[other]
    return max(0.0, float(-dist[hit].min())) if hit.any() else 0.0
