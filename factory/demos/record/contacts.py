"""The robot's contacts with the scene: how deep the arm went into what it may not touch.

Shared by the demos' executors (``factory/demos/execute/cpu.py``, the policies' env), the
tasks that simulate their own episodes (``factory/tasks/articulated/record.py``) and the GPU
physics of those episodes (``factory/demos/execute/plan_worlds.py``: the contacts of many
worlds at once, :func:`penetration_by`).
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["penetration_by", "robot_penetration"]


def penetration_by(
    geom: np.ndarray,
    dist: np.ndarray,
    group: np.ndarray,
    n: int,
    robot_geom: np.ndarray,
    allowed: np.ndarray,
) -> np.ndarray:
    """Deepest contact between a robot geom and a scene geom not in ``allowed``, per group of
    contacts (a world's).

    Args:
        geom: (C, 2) the contacts' geoms (a negative id: no contact, ignored).
        dist: (C,) their signed distances (m; negative: penetrating).
        group: (C,) each contact's group, in ``0 .. n - 1``.
        n: groups.
        robot_geom, allowed: (ngeom,) bool.

    Returns:
        (n,) penetration depth (m, >= 0; 0 where none penetrates).
    """
    out = np.zeros(n)
    if len(geom) == 0:
        return out
    g1, g2 = geom[:, 0], geom[:, 1]
    valid = (g1 >= 0) & (g2 >= 0)
    g1, g2 = np.where(valid, g1, 0), np.where(valid, g2, 0)
    first = robot_geom[g1]
    other = np.where(first, g2, g1)
    hit = valid & (first != robot_geom[g2]) & ~allowed[other]
    if hit.any():
        np.maximum.at(out, np.asarray(group)[hit], np.maximum(0.0, -np.asarray(dist)[hit]))
    return out


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
    return float(penetration_by(geom, dist, np.zeros(n, np.int64), 1, robot_geom, allowed)[0])
