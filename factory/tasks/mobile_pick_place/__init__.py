"""Mobile pick-and-place: drive to a support, pick an object, drive to another support, place it.

The robot is the Panda on the Omron base (:mod:`factory.robots.mobile_panda`). The task lives
in three modules, each with one job, whose public names this module re-exports (import from
here or from them):

* :mod:`factory.tasks.mobile_pick_place.scene`: the task objects (:func:`mobile_task_objects`), the
scene
  composed with the robot and its occupancy grid (:func:`mobile_setup`, :func:`compose_mobile`;
  light floor objects that close the way for the base are taken out, ``MobileSetup.cleared``),
  where the base can work (:func:`task_work_poses`), reasons and camera names;
* :mod:`factory.tasks.mobile_pick_place.plan`: :class:`MobilePlanner` (spawn, drive with the base's
  footprint in SE(2), pick, carry, place; every loop bounded, a time budget per episode) and
  the timed per-step plan :class:`MobileEpisodePlan`;
* :mod:`factory.tasks.mobile_pick_place.execute`: :func:`execute_mobile` (simulate, record, check
success
  with :func:`check_mobile_success`, then render the successful episodes' images),
  :func:`replay`, :class:`MobileRenderer`.

:mod:`factory.tasks.mobile_pick_place.demos` is what ``stage=demos task=mobile_pick_place``
records with (:func:`~factory.tasks.mobile_pick_place.demos.mobile_scene_planner`, the scene
and its planner; :class:`~factory.tasks.mobile_pick_place.demos.MobilePickPlaceScene`).

Frames: world frame for poses (m, rad); the base pose is the footprint centre's (x, y) and the
unwrapped yaw (the base joints' values); tool site +z is the approach, +x the closing axis.
"""

from __future__ import annotations

from factory.tasks.mobile_pick_place.execute import (
    STATE_SPEC,
    MobileRecordConfig,
    MobileRecording,
    MobileRenderer,
    check_mobile_success,
    execute_mobile,
    mobile_outcome,
    penetrations,
    render_frames,
    replay,
    simulate,
)
from factory.tasks.mobile_pick_place.plan import (
    MobileEpisodePlan,
    MobileMotionConfig,
    MobilePlanFailure,
    MobilePlanner,
    carry_order,
)
from factory.tasks.mobile_pick_place.scene import (
    ALL_CAMERAS,
    COLLISION,
    FISHEYE_CAMERAS,
    IMPRATIO,
    NO_PLACE_SUPPORT,
    NO_SPAWN,
    NOSLIP_ITERATIONS,
    PLAN_TIMEOUT,
    REASONS,
    SUBTASKS,
    MobileSetup,
    MobileTaskError,
    MobileTaskObjects,
    base_matrix,
    body_box,
    clear_for_base,
    compose_mobile,
    mobile_setup,
    mobile_task_objects,
    movable,
    reachability,
    support_top,
    task_work_poses,
)

__all__ = [
    "ALL_CAMERAS",
    "COLLISION",
    "FISHEYE_CAMERAS",
    "IMPRATIO",
    "NOSLIP_ITERATIONS",
    "NO_PLACE_SUPPORT",
    "NO_SPAWN",
    "PLAN_TIMEOUT",
    "REASONS",
    "STATE_SPEC",
    "SUBTASKS",
    "MobileEpisodePlan",
    "MobileMotionConfig",
    "MobilePlanFailure",
    "MobilePlanner",
    "MobileRecordConfig",
    "MobileRecording",
    "MobileRenderer",
    "MobileSetup",
    "MobileTaskError",
    "MobileTaskObjects",
    "base_matrix",
    "body_box",
    "carry_order",
    "check_mobile_success",
    "clear_for_base",
    "compose_mobile",
    "execute_mobile",
    "mobile_outcome",
    "mobile_setup",
    "mobile_task_objects",
    "movable",
    "penetrations",
    "reachability",
    "render_frames",
    "replay",
    "simulate",
    "support_top",
    "task_work_poses",
]
