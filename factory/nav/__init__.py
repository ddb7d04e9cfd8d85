"""Navigation of a mobile base in a compiled scene (floor 3, beside ``assets``).

``OccupancyGrid.from_model(model, data)`` rasterizes the scene's collision geometry in the
robot's height band (:mod:`.grid`); ``grid.inflate(radius)`` grows it by the base's radius.
``plan_base_path`` finds a planar path for a disc with OMPL RRTConnect (:mod:`.rrt`);
``plan_se2_path`` finds an (x, y, yaw) path for a base of a given :class:`Footprint`
(:mod:`.footprint`, :mod:`.se2`), which passes where the disc around it would not;
``base_trajectory`` gives a planar path headings and times it under :class:`BaseLimits` with
ruckig, ``time_base_path`` times a pose path (:mod:`.base_trajectory`); ``base_pose_beside``,
``work_poses``, ``random_free_pose`` and ``random_footprint_pose`` choose goals and spawn poses
(:mod:`.goals`), and
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
from factory.nav.footprint import Footprint, unwrap_yaw
from factory.nav.goals import (
    BasePose,
    base_pose_beside,
    random_footprint_pose,
    random_free_pose,
    work_poses,
)
from factory.nav.grid import OccupancyGrid
from factory.nav.recheck import BASE_COLLISION, RecheckResult, recheck_base_trajectory
from factory.nav.rrt import NAV_FAILED, BasePath, NavPlannerConfig, plan_base_path
from factory.nav.se2 import plan_se2_path

__all__ = [
    "BASE_COLLISION",
    "NAV_FAILED",
    "BaseLimits",
    "BasePath",
    "BasePose",
    "BaseTrajectory",
    "Footprint",
    "NavError",
    "NavPlannerConfig",
    "OccupancyGrid",
    "RecheckResult",
    "base_pose_beside",
    "base_trajectory",
    "plan_base_path",
    "plan_se2_path",
    "random_footprint_pose",
    "random_free_pose",
    "recheck_base_trajectory",
    "time_base_path",
    "unwrap_yaw",
    "work_poses",
    "yaw_waypoints",
]
