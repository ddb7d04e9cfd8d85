"""``stage=validate``: physics validation of every scene, with the scene checks of the floors
above physics.

The physics (compile, settle, collisions, stability, repair) is :mod:`factory.sim.validate`;
this entry point hands it the checks that need more than ``sim``: ``route``, the mobile
task's route check (:func:`factory.nav.route.route_scene_check`: both supports reachable for
the robot's base, 1.5 m apart at least, one free region between them), run on every scene
made for the mobile task; ``task``, the feasibility critic of the task a scene was made for
(:meth:`factory.tasks.base.Task.feasibility`: for the fixed pick-and-place a free base spot
and room for the task objects within reach: ``no_task_objects``, ``no_base_spot``,
``no_room``). A scene failing a check keeps its place in the run; its report
(``scenes/<id>/report.json``, ``validate.checks.route``) and ``validate/summary.json`` say
why (``no_route``, ``no_place_support``, ``place_support_too_small``, ``no_spawn_area``, ...).
"""

from __future__ import annotations

from typing import Any

from factory.context import StageContext
from factory.schema import Scene


def run(ctx: StageContext) -> dict[str, Any]:
    """Stage entry point: ``stage=validate``."""
    from factory.nav.route import route_scene_check
    from factory.scenes.finish import task_check
    from factory.sim.validate import run as validate
    from factory.tasks import task_for_scene

    assets = ctx.require_store().assets_dir

    def task(scene: Scene, model: Any) -> dict[str, Any] | None:
        if scene.task is None or task_for_scene(scene).drives_base:
            return None  # a driving task's feasibility is its route: the check above
        return task_check(scene, assets)

    return validate(ctx, checks={"route": route_scene_check, "task": task})


__all__ = ["run"]
