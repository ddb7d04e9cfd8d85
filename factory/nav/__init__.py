"""Navigation of a mobile base in a compiled scene (floor 3, beside ``assets``).

``OccupancyGrid.from_model(model, data)`` rasterizes the scene's collision geometry in the
robot's height band (:mod:`.grid`); ``grid.inflate(radius)`` grows it by the base's radius.
``plan_base_path`` finds a planar path with OMPL RRTConnect (:mod:`.rrt`), ``base_trajectory``
gives it headings and times it under :class:`BaseLimits` with ruckig (:mod:`.base_trajectory`),
``base_pose_beside`` and ``random_free_pose`` choose goals and spawn poses (:mod:`.goals`), and
``recheck_base_trajectory`` drives the real robot model along the result in MuJoCo
(:mod:`.recheck`). Failures are results with reasons ``nav_failed`` and ``base_collision``.

The robot model itself is ``factory.demos.mobile_robot`` (this package does not import it).
"""

from factory.nav.base_trajectory import (
    BaseLimits,
    BaseTrajectory,
    base_trajectory,
    time_base_path,
    yaw_waypoints,
)
from factory.nav.errors import NavError
from factory.nav.goals import BasePose, base_pose_beside, random_free_pose
from factory.nav.grid import OccupancyGrid
from factory.nav.recheck import BASE_COLLISION, RecheckResult, recheck_base_trajectory
from factory.nav.rrt import NAV_FAILED, BasePath, NavPlannerConfig, plan_base_path

__all__ = [
    "BASE_COLLISION",
    "NAV_FAILED",
    "BaseLimits",
    "BasePath",
    "BasePose",
    "BaseTrajectory",
    "NavError",
    "NavPlannerConfig",
    "OccupancyGrid",
    "RecheckResult",
    "base_pose_beside",
    "base_trajectory",
    "plan_base_path",
    "random_free_pose",
    "recheck_base_trajectory",
    "time_base_path",
    "yaw_waypoints",
]
