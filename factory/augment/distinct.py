"""Distinct configurations: two joint poses differ when at least one object moved far enough.

Configurations are ``(k, 4)`` ``[x, y, z, yaw_deg]`` of the same ``k`` objects. ``a`` and ``b``
are *distinct* when for some object the positions are at least ``min_distance`` apart (m) or
the turns differ by at least ``min_yaw_deg`` (deg, the shorter way round).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Distinctness:
    """When two configurations count as different.

    Attributes:
        min_distance: smallest move of one object (m) that makes a new configuration.
        min_yaw_deg: smallest turn of one object (deg) that makes a new configuration.
    """

    min_distance: float = 0.03
    min_yaw_deg: float = 15.0

    def differs(self, a: np.ndarray, others: np.ndarray) -> np.ndarray:
        """``(m,)`` bool: whether configuration ``a`` ``(k, 4)`` differs from each of
        ``others`` ``(m, k, 4)``."""
        if len(others) == 0:
            return np.ones(0, bool)
        dist = np.linalg.norm(others[..., :3] - a[None, :, :3], axis=-1)
        dyaw = np.abs(np.mod(others[..., 3] - a[None, :, 3] + 180.0, 360.0) - 180.0)
        return ((dist >= self.min_distance) | (dyaw >= self.min_yaw_deg)).any(axis=-1)

    def select(self, candidates: np.ndarray, kept: np.ndarray, limit: int) -> np.ndarray:
        """Greedy, in order: indices of at most ``limit`` candidates ``(n, k, 4)`` that differ
        from every configuration in ``kept`` ``(m, k, 4)`` and from each other.

        Two configurations can only be alike where their first objects lie within
        ``min_distance``: a k-d tree over the first objects' positions finds those pairs, and
        only they are compared in full.
        """
        from scipy.spatial import cKDTree

        n = len(candidates)
        if n == 0 or limit <= 0:
            return np.zeros(0, dtype=int)
        if self.min_distance <= 0 or self.min_yaw_deg <= 0:
            return np.arange(min(n, limit))  # nothing is alike
        first = candidates[:, 0, :3]
        blocked = np.zeros(n, bool)
        if len(kept):
            near = cKDTree(kept[:, 0, :3]).query_ball_point(first, r=self.min_distance)
            for i, js in enumerate(near):
                if js and not self.differs(candidates[i], kept[js]).all():
                    blocked[i] = True
        pairs = cKDTree(first).query_pairs(r=self.min_distance, output_type="ndarray")
        alike: dict[int, list[int]] = {}
        if len(pairs):
            a, b = pairs.min(axis=1), pairs.max(axis=1)
            dist = np.linalg.norm(candidates[a, :, :3] - candidates[b, :, :3], axis=-1)
            dyaw = np.abs(np.mod(candidates[a, :, 3] - candidates[b, :, 3] + 180.0, 360.0) - 180.0)
            same = ((dist < self.min_distance) & (dyaw < self.min_yaw_deg)).all(axis=-1)
            for i, j in zip(a[same].tolist(), b[same].tolist(), strict=True):
                alike.setdefault(j, []).append(i)
        chosen: list[int] = []
        taken = np.zeros(n, bool)
        for i in range(n):
            if len(chosen) >= limit:
                break
            if blocked[i] or any(taken[j] for j in alike.get(i, ())):
                continue
            taken[i] = True
            chosen.append(i)
        return np.asarray(chosen, dtype=int)
