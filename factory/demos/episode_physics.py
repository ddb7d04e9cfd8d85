"""Where the GPU pipeline simulates the ``episode`` execution's episodes
(``demos.episode_physics``), and the planner processes' and the main process's parts when
MuJoCo Warp simulates them.

* ``cpu``: the planner processes plan and simulate each slot on the CPU, trying its seeds until
  an episode succeeds (:func:`~factory.demos.episode_execution.plan_and_simulate`); the main
  process only draws.
* ``warp``: the planner processes only plan (:func:`plan_slot`: a slot's next seeds until one
  plans); the main process steps a scene's plans together as MuJoCo Warp worlds
  (:class:`~factory.demos.execute.plan_worlds.WarpPlanWorlds`), rebuilds each recording and its
  verdict from the recorded states with the task's hook
  (:class:`~factory.demos.record.from_states.StatesRecorder`, :func:`simulate_plans`), and
  sends the slots that failed back to the planners with their next seed, as the ``batch``
  execution's ``gpu`` retries go.
* ``auto`` (the default): ``warp`` where the task's scene has the hook
  (:meth:`~factory.demos.record.scene.SimulatingScene.states_recorder`) and takes it by default
  (:attr:`~factory.demos.record.scene.SimulatingScene.gpu_physics_by_default`): ``open``,
  ``close``; else ``cpu``: ``place_inside`` (its hook written, its agreement with the CPU
  executor measured on two plans only: ``warp`` takes it) and ``mobile_pick_place`` (no hook).

The choice depends on the scene's class and ``demos.*`` only, so the planner processes and the
main process make the same one (:func:`states_recorder`).
"""

from __future__ import annotations

import logging
import time
from typing import Any

from factory.demos.execution import SlotResult, cached_scene
from factory.demos.record.from_states import StatesRecorder
from factory.demos.record.scene import SimulatingScene
from factory.demos.record.slots import StageEnv, episode_seed
from factory.errors import ConfigError, FactoryError

__all__ = ["EPISODE_PHYSICS", "plan_slot", "simulate_plans", "states_recorder"]

log = logging.getLogger(__name__)

EPISODE_PHYSICS = ("auto", "warp", "cpu")
"""The values of ``demos.episode_physics`` (module docstring)."""


def states_recorder(scene: SimulatingScene, physics: str) -> StatesRecorder | None:
    """The scene's hook when MuJoCo Warp simulates its episodes under ``demos.episode_physics =
    physics``; None when the planner processes simulate them on the CPU.

    Raises:
        ConfigError: ``physics`` is unknown, or ``warp`` for a task without the hook.
    """
    if physics not in EPISODE_PHYSICS:
        raise ConfigError(
            f"demos.episode_physics={physics!r} is unknown: choose one of "
            f"{', '.join(EPISODE_PHYSICS)}"
        )
    if physics == "cpu" or (physics == "auto" and not scene.gpu_physics_by_default):
        return None
    hook = scene.states_recorder()
    if hook is None and physics == "warp":
        raise ConfigError(
            f"task {scene.env.task!r}: demos.episode_physics=warp, but its episodes are "
            "simulated on the CPU only (its scene has no states_recorder): use "
            "demos.episode_physics=auto or cpu"
        )
    return hook


def plan_slot(env: StageEnv, scene_id: str, slot: int, attempt: int) -> SlotResult:
    """Plans one slot in a planner process (no simulation), trying its seeds from ``attempt``
    on until one plans or ``demos.attempts`` are spent."""
    out = SlotResult(slot, attempt=attempt)
    try:
        scene = cached_scene(env, scene_id)
    except FactoryError as e:
        out.error = str(e)
        return out
    for a in range(attempt, env.demos.attempts):
        out.attempt, out.seed = a, episode_seed(env.seed, scene_id, slot, a)
        res = scene.plan(out.seed)
        if isinstance(res, scene.plan_type):
            out.plan = res
            out.plan_seconds.append(res.seconds)
            out.segments.extend(res.plan_seconds.values())
            return out
        out.failures.append((res.reason, res.detail))
    return out


def simulate_plans(runner: Any, hook: StatesRecorder, plans: list[Any], rec_cfg: Any) -> list[Any]:
    """``plans`` (of one scene) stepped together on the device and recorded: one recording
    each, in order, with its outcome (no images; a world whose buffers overflowed even with the
    largest headroom fails as :data:`~factory.demos.execute.warp.OVERFLOW`).

    Args:
        runner: the scene's :class:`~factory.demos.execute.plan_worlds.WarpPlanWorlds`.
        hook: the scene's :class:`StatesRecorder`.
        rec_cfg: the recording settings (``fps``).

    The host's seconds rebuilding the recordings are added to the runner's
    ``times.record``; each recording's ``sim_seconds`` is its share of the device's.
    """
    from factory.demos.execute.warp import OVERFLOW
    from factory.demos.record.from_states import WorldPlan
    from factory.tasks.pick_place.objects import Outcome

    periods = runner.times.periods
    worlds = [WorldPlan(p.qpos0, p.ctrl, hook.probes(p)) for p in plans]
    runs = runner.run(worlds)
    recs = []
    t0 = time.perf_counter()
    for plan, run in zip(plans, runs, strict=True):
        rec = hook.recording(plan, run, rec_cfg)
        if run.overflow:
            rec.outcome = Outcome(False, OVERFLOW, {"overflow_bits": float(run.overflow)})
        rec.sim_seconds = (runner.times.periods - periods) / len(plans)
        recs.append(rec)
    runner.times.record += time.perf_counter() - t0
    return recs
