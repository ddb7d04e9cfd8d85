"""Mobile pick-and-place: drive to a support, pick an object, drive to another support, place it.

The robot is the Panda on the Omron base (:mod:`factory.robots.mobile_panda`). The task lives
in modules with one job each, whose public names this package re-exports (import from here or
from them; importing the package is cheap, a name loads its module on first use):

* :mod:`factory.tasks.mobile_pick_place.task`: :class:`MobilePickPlaceTask`, the registry's
  entry (what the scene, demos, dataset and env layers ask of the task);
* :mod:`factory.tasks.mobile_pick_place.scene`: the task objects (:func:`mobile_task_objects`),
  the scene composed with the robot and its occupancy grid (:func:`mobile_setup`,
  :func:`compose_mobile`; light floor objects that close the way for the base are taken out,
  ``MobileSetup.cleared``), where the base can work (:func:`task_work_poses`), reasons and
  camera names;
* :mod:`factory.tasks.mobile_pick_place.plan`: :class:`MobilePlanner` (spawn, drive with the
  base's footprint in SE(2), pick, carry, place; every loop bounded, a time budget per episode)
  and the timed per-step plan :class:`MobileEpisodePlan`;
* :mod:`factory.tasks.mobile_pick_place.execute`: :func:`execute_mobile` (simulate, record,
  check success with :func:`check_mobile_success`, then render the successful episodes'
  images), :func:`replay`, :class:`MobileRenderer` and its cameras as a renderer of recorded
  states needs them (:func:`camera_rig`);
* :mod:`factory.tasks.mobile_pick_place.demos`: what ``stage=demos task=mobile_pick_place``
  records with (:func:`~factory.tasks.mobile_pick_place.demos.mobile_scene_planner`, the scene
  and its planner; :class:`~factory.tasks.mobile_pick_place.demos.MobilePickPlaceScene`);
* :mod:`factory.tasks.mobile_pick_place.dataset` and :mod:`factory.tasks.mobile_pick_place.env`:
  the features it adds to the LeRobot export, and its side of the evaluation env.

Frames: world frame for poses (m, rad); the base pose is the footprint centre's (x, y) and the
unwrapped yaw (the base joints' values); tool site +z is the approach, +x the closing axis.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from factory.tasks.mobile_pick_place.execute import (
        STATE_SPEC as STATE_SPEC,
    )
    from factory.tasks.mobile_pick_place.execute import (
        MobileRecordConfig as MobileRecordConfig,
    )
    from factory.tasks.mobile_pick_place.execute import (
        MobileRecording as MobileRecording,
    )
    from factory.tasks.mobile_pick_place.execute import (
        MobileRenderer as MobileRenderer,
    )
    from factory.tasks.mobile_pick_place.execute import (
        camera_rig as camera_rig,
    )
    from factory.tasks.mobile_pick_place.execute import (
        check_mobile_success as check_mobile_success,
    )
    from factory.tasks.mobile_pick_place.execute import (
        execute_mobile as execute_mobile,
    )
    from factory.tasks.mobile_pick_place.execute import (
        mobile_outcome as mobile_outcome,
    )
    from factory.tasks.mobile_pick_place.execute import (
        penetrations as penetrations,
    )
    from factory.tasks.mobile_pick_place.execute import (
        render_frames as render_frames,
    )
    from factory.tasks.mobile_pick_place.execute import (
        replay as replay,
    )
    from factory.tasks.mobile_pick_place.execute import (
        simulate as simulate,
    )
    from factory.tasks.mobile_pick_place.plan import (
        MobileEpisodePlan as MobileEpisodePlan,
    )
    from factory.tasks.mobile_pick_place.plan import (
        MobileMotionConfig as MobileMotionConfig,
    )
    from factory.tasks.mobile_pick_place.plan import (
        MobilePlanFailure as MobilePlanFailure,
    )
    from factory.tasks.mobile_pick_place.plan import (
        MobilePlanner as MobilePlanner,
    )
    from factory.tasks.mobile_pick_place.plan import (
        carry_order as carry_order,
    )
    from factory.tasks.mobile_pick_place.scene import (
        ALL_CAMERAS as ALL_CAMERAS,
    )
    from factory.tasks.mobile_pick_place.scene import (
        COLLISION as COLLISION,
    )
    from factory.tasks.mobile_pick_place.scene import (
        FISHEYE_CAMERAS as FISHEYE_CAMERAS,
    )
    from factory.tasks.mobile_pick_place.scene import (
        IMPRATIO as IMPRATIO,
    )
    from factory.tasks.mobile_pick_place.scene import (
        NO_PLACE_SUPPORT as NO_PLACE_SUPPORT,
    )
    from factory.tasks.mobile_pick_place.scene import (
        NO_SPAWN as NO_SPAWN,
    )
    from factory.tasks.mobile_pick_place.scene import (
        NOSLIP_ITERATIONS as NOSLIP_ITERATIONS,
    )
    from factory.tasks.mobile_pick_place.scene import (
        PLAN_TIMEOUT as PLAN_TIMEOUT,
    )
    from factory.tasks.mobile_pick_place.scene import (
        REASONS as REASONS,
    )
    from factory.tasks.mobile_pick_place.scene import (
        SUBTASKS as SUBTASKS,
    )
    from factory.tasks.mobile_pick_place.scene import (
        MobileSetup as MobileSetup,
    )
    from factory.tasks.mobile_pick_place.scene import (
        MobileTaskError as MobileTaskError,
    )
    from factory.tasks.mobile_pick_place.scene import (
        MobileTaskObjects as MobileTaskObjects,
    )
    from factory.tasks.mobile_pick_place.scene import (
        base_matrix as base_matrix,
    )
    from factory.tasks.mobile_pick_place.scene import (
        body_box as body_box,
    )
    from factory.tasks.mobile_pick_place.scene import (
        clear_for_base as clear_for_base,
    )
    from factory.tasks.mobile_pick_place.scene import (
        compose_mobile as compose_mobile,
    )
    from factory.tasks.mobile_pick_place.scene import (
        mobile_setup as mobile_setup,
    )
    from factory.tasks.mobile_pick_place.scene import (
        mobile_task_objects as mobile_task_objects,
    )
    from factory.tasks.mobile_pick_place.scene import (
        movable as movable,
    )
    from factory.tasks.mobile_pick_place.scene import (
        reachability as reachability,
    )
    from factory.tasks.mobile_pick_place.scene import (
        support_top as support_top,
    )
    from factory.tasks.mobile_pick_place.scene import (
        task_work_poses as task_work_poses,
    )

_LAZY: dict[str, str] = {
    "ALL_CAMERAS": "factory.tasks.mobile_pick_place.scene",
    "COLLISION": "factory.tasks.mobile_pick_place.scene",
    "FISHEYE_CAMERAS": "factory.tasks.mobile_pick_place.scene",
    "IMPRATIO": "factory.tasks.mobile_pick_place.scene",
    "MobileEpisodePlan": "factory.tasks.mobile_pick_place.plan",
    "MobileMotionConfig": "factory.tasks.mobile_pick_place.plan",
    "MobilePlanFailure": "factory.tasks.mobile_pick_place.plan",
    "MobilePlanner": "factory.tasks.mobile_pick_place.plan",
    "MobileRecordConfig": "factory.tasks.mobile_pick_place.execute",
    "MobileRecording": "factory.tasks.mobile_pick_place.execute",
    "MobileRenderer": "factory.tasks.mobile_pick_place.execute",
    "MobileSetup": "factory.tasks.mobile_pick_place.scene",
    "MobileTaskError": "factory.tasks.mobile_pick_place.scene",
    "MobileTaskObjects": "factory.tasks.mobile_pick_place.scene",
    "NOSLIP_ITERATIONS": "factory.tasks.mobile_pick_place.scene",
    "NO_PLACE_SUPPORT": "factory.tasks.mobile_pick_place.scene",
    "NO_SPAWN": "factory.tasks.mobile_pick_place.scene",
    "PLAN_TIMEOUT": "factory.tasks.mobile_pick_place.scene",
    "REASONS": "factory.tasks.mobile_pick_place.scene",
    "STATE_SPEC": "factory.tasks.mobile_pick_place.execute",
    "SUBTASKS": "factory.tasks.mobile_pick_place.scene",
    "base_matrix": "factory.tasks.mobile_pick_place.scene",
    "body_box": "factory.tasks.mobile_pick_place.scene",
    "camera_rig": "factory.tasks.mobile_pick_place.execute",
    "carry_order": "factory.tasks.mobile_pick_place.plan",
    "check_mobile_success": "factory.tasks.mobile_pick_place.execute",
    "clear_for_base": "factory.tasks.mobile_pick_place.scene",
    "compose_mobile": "factory.tasks.mobile_pick_place.scene",
    "execute_mobile": "factory.tasks.mobile_pick_place.execute",
    "mobile_outcome": "factory.tasks.mobile_pick_place.execute",
    "mobile_setup": "factory.tasks.mobile_pick_place.scene",
    "mobile_task_objects": "factory.tasks.mobile_pick_place.scene",
    "movable": "factory.tasks.mobile_pick_place.scene",
    "penetrations": "factory.tasks.mobile_pick_place.execute",
    "reachability": "factory.tasks.mobile_pick_place.scene",
    "render_frames": "factory.tasks.mobile_pick_place.execute",
    "replay": "factory.tasks.mobile_pick_place.execute",
    "simulate": "factory.tasks.mobile_pick_place.execute",
    "support_top": "factory.tasks.mobile_pick_place.scene",
    "task_work_poses": "factory.tasks.mobile_pick_place.scene",
}
"""Public name -> the module that defines it."""

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
