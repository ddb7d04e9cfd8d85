"""OMPL RRTConnect for base paths: what the planners of :mod:`factory.nav` share.

:func:`factory.nav.se2.plan_se2_path` plans the base's pose (x, y, yaw) for its footprint with
:func:`solve_rrt_connect` (RRTConnect, then OMPL's ``PathSimplifier``); its parameters are a
:class:`NavPlannerConfig` and its result a :class:`BasePath`. (A planner for a disc in the plane
used to live here: the rectangular footprint replaced it.)

Failures are results, not exceptions: ``ok`` is False and ``reason`` is ``nav_failed`` (the
``detail`` says why: start or goal blocked, not connected, no path within the time limit).

Seeding (:func:`seed_ompl`): OMPL draws the seeds of the generators it makes (one per planner,
state sampler and path simplifier) from one process-wide generator; ``ompl.util.RNG.setSeed``
resets that one. Called before every query, as :func:`factory.demos.plan.planner.plan` does for
the arm, a query's result depends on its seed alone, not on the queries the process ran
before: an episode plans the same in a worker that ran others first. OMPL logs an error
("Random number generation already started ...") for every call after the first; it is
silenced around the call.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

NAV_FAILED = "nav_failed"
"""The failure reason of a base-navigation query that has no (found) path."""


@dataclass(frozen=True)
class NavPlannerConfig:
    """Parameters of a base-path query.

    Attributes:
        timeout: seconds of RRTConnect per attempt.
        attempts: RRTConnect runs before giving up.
        range: RRTConnect's extension step (m); 0 lets OMPL choose.
        edge_step: edge-validation step as a share of a grid cell.
        simplify: seconds of path simplification (shortcuts, vertex reduction).
        check_step: step of the final re-check as a share of a grid cell.
    """

    timeout: float = 2.0
    attempts: int = 2
    range: float = 0.0
    edge_step: float = 0.25
    simplify: float = 0.3
    check_step: float = 0.1


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class BasePath:
    """A planned base path.

    Attributes:
        ok: whether a path was found.
        reason: ``""`` or ``nav_failed``.
        detail: why it failed, in words.
        path: poses (k, 3) in the world frame: x, y (m) and unwrapped yaw (rad), start and
            goal included; (0, 2) on failure.
        seconds: wall time of the query.
    """

    ok: bool
    reason: str = ""
    detail: str = ""
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    seconds: float = 0.0

    @property
    def length(self) -> float:
        """Length of the path in the plane (m)."""
        return float(np.linalg.norm(np.diff(self.path[:, :2], axis=0), axis=1).sum())


def solve_rrt_connect(setup: Any, cfg: NavPlannerConfig, resolution: float, attempt: int) -> Any:
    """Runs OMPL's RRTConnect on a prepared ``og.SimpleSetup`` (space, validity checker, start
    and goal set) and simplifies the solution.

    Args:
        resolution: the validity-checking resolution, a fraction of the space's extent.
        attempt: 0-based attempt number (for the message).

    Returns:
        the simplified ``og.PathGeometric``, or why there is none (a string).
    """
    from ompl import geometric as og

    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(resolution)
    planner = og.RRTConnect(info)
    if cfg.range > 0:
        planner.setRange(cfg.range)
    setup.setPlanner(planner)
    solved = setup.solve(cfg.timeout)
    if not solved or str(solved) != "Exact solution":
        return f"RRTConnect found no path in {cfg.timeout:.1f} s ({attempt + 1} attempts)"
    setup.simplifySolution(cfg.simplify)
    return setup.getSolutionPath()


def seed_ompl(seed: int) -> None:
    """Seeds OMPL's process-wide generator (see the module docstring), quietly.

    Args:
        seed: any integer; mapped to OMPL's valid range [1, 2**31 - 1].
    """
    from ompl import util as ou

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
    finally:
        ou.setLogLevel(level)
