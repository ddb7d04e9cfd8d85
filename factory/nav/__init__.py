"""Navigation of a mobile base in a compiled scene (floor 3, beside ``assets``).

``OccupancyGrid.from_model(model, data)`` rasterizes the scene's collision geometry in the
robot's height band (:mod:`.grid`); ``grid.inflate(radius)`` grows it by a disc's radius.
``plan_se2_path`` finds an (x, y, yaw) path for a base of a given :class:`Footprint`
(:mod:`.footprint`, :mod:`.se2`; OMPL RRTConnect, :mod:`.rrt`), which passes where a disc
around the base would not; ``time_base_path`` times a pose path under :class:`BaseLimits`
with ruckig (:mod:`.base_trajectory`); ``work_poses`` and ``random_footprint_pose`` choose goals and
spawn poses (:mod:`.goals`), and ``recheck_base_trajectory`` drives the real robot model along
a trajectory in MuJoCo (:mod:`.recheck`). Failures are results with reasons ``nav_failed``
and ``base_collision``.

The robot model itself is ``factory.robots.mobile_panda`` (this package does not import it).
"""

from factory.nav.base_trajectory import (
    BaseLimits,
    BaseTrajectory,
    time_base_path,
)
from factory.nav.errors import NavError
from factory.nav.footprint import Footprint, unwrap_yaw
from factory.nav.goals import (
    BasePose,
    random_footprint_pose,
    work_poses,
)
from factory.nav.grid import OccupancyGrid
from factory.nav.recheck import BASE_COLLISION, RecheckResult, recheck_base_trajectory
from factory.nav.rrt import NAV_FAILED, BasePath, NavPlannerConfig
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
    "plan_se2_path",
    "random_footprint_pose",
    "recheck_base_trajectory",
    "time_base_path",
    "unwrap_yaw",
    "work_poses",
]
