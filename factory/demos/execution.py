"""How ``stage=demos`` executes a task's plans: the hooks between the task-agnostic machinery
and an execution model, and the registry of the models (:data:`EXECUTIONS`, chosen by the
task's :attr:`~factory.tasks.base.Task.demo_execution`).

The machinery is written once: the CPU item path (:func:`factory.demos.cpu_items.run_item`:
slots, seeds, attempts, storing, statistics) and the GPU pipeline
(:func:`factory.demos.gpu_pipeline.run_gpu`: scenes in order, a pool of planner processes
submitted ahead, writer processes, CPU retries, a log line and statistics per scene). An
:class:`Execution` fills in what differs between models:

* on the CPU, how a round of planned episodes is executed and recorded
  (:attr:`Execution.cpu_recorder`) and how many slots a round takes (:attr:`Execution.
  round_slots`);
* in the GPU pipeline, the per-slot work of a planner process (:attr:`Execution.slot_worker`,
  returning a :class:`SlotResult`) and the main process's GPU work per scene
  (:attr:`Execution.gpu_recorder`).

Every process keeps the task's scenes it works in (:func:`cached_scene`).
"""

from __future__ import annotations

import importlib
import logging
from abc import ABC, abstractmethod
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from factory.demos.record.scene import DemoScene
from factory.demos.record.slots import StageEnv
from factory.errors import ConfigError, FactoryError
from factory.sim.kernel_preload import PreloadReport

__all__ = [
    "EXECUTIONS",
    "CpuRecorder",
    "Execution",
    "GpuRecorder",
    "GpuRun",
    "SlotResult",
    "cached_scene",
    "execution_of",
    "store_episode",
    "tally",
]

log = logging.getLogger(__name__)

EXECUTIONS: dict[str, str] = {
    "batch": "factory.demos.batch_execution:BATCH",
    "episode": "factory.demos.episode_execution:EPISODE",
}
"""``Task.demo_execution`` -> ``"module:name"`` of its :class:`Execution` (resolved lazily: the
GPU executors load only where they run)."""


@dataclass
class SlotResult:
    """What a planner process returns for one episode slot in the GPU pipeline (picklable).

    Attributes:
        slot: the slot. seed, attempt: of its last attempt.
        plan: the episode's plan (None: no attempt planned, or none succeeded).
        rec: its recording without images, where the process simulated it (``episode``).
        look: its appearance and model patch (``batch``, when images are drawn).
        failures: ``(reason, detail)`` of each failed attempt, in order.
        plan_seconds: planning time of each attempt that planned (s).
        segments: planning time of each planned motion (s).
        simulate: simulation time over the attempts (s).
        error: the scene cannot host the task, and why ('' otherwise).
    """

    slot: int
    seed: int = 0
    attempt: int = 0
    plan: Any = None
    rec: Any = None
    look: Any = None
    failures: list[tuple[str, str]] = field(default_factory=list)
    plan_seconds: list[float] = field(default_factory=list)
    segments: list[float] = field(default_factory=list)
    simulate: float = 0.0
    error: str = ""


def tally(out: dict[str, Any], res: SlotResult) -> None:
    """Counts a slot's result into its scene's statistics ``out`` (failures logged)."""
    for reason, detail in res.failures:
        out["failures"][reason] += 1
        log.info("scene %s slot %d: %s: %s", out["scene_id"], res.slot, reason, detail[:200])
    out["plan"].extend(res.plan_seconds)
    out["segments"].extend(res.segments)
    out["simulate"] += res.simulate
    if res.error:
        out["error"] = res.error
        out["failures"]["scene_unusable"] += 1


def store_episode(store_path: str, meta: Any, arrays: dict[str, Any]) -> None:
    """Writes one episode into the store at ``store_path`` (run in the GPU pipeline's writer
    processes: each has its own zarr event loop, so episodes compress and write in parallel).
    Arrays given as :class:`~factory.demos.execute.shared_frames.SharedView` are read in place
    from the caller's shared memory."""
    from factory.demos.execute.shared_frames import opened
    from factory.demos.record.episodes import EpisodeStore

    EpisodeStore(store_path).write(meta, opened(arrays))


@dataclass
class GpuRun:
    """What the GPU pipeline gives its :class:`GpuRecorder` (one per run).

    Attributes:
        env: the stage's settings.
        pool: the planner processes.
        writers: the writer processes (:func:`store_episode`).
        nwriters: how many.
        bar: the progress bar (episodes), or None.
        device: the Warp device (None: CUDA where present, else the CPU).
        submit: ``(scene_id, slots, attempt)`` -> the slots' futures from their attempts on.
        to_cpu: ``(out, scene_id, slots, attempt)``: has the planner processes record the
            slots with the CPU executor from their attempts on, counted into ``out`` at the
            end of the run.
    """

    env: StageEnv
    pool: ProcessPoolExecutor
    writers: ProcessPoolExecutor
    nwriters: int
    bar: Any
    device: str | None
    submit: Callable[[str, list[int], dict[int, int]], list[Future[SlotResult]]]
    to_cpu: Callable[[dict[str, Any], str, list[int], dict[int, int]], None]


class CpuRecorder(ABC):
    """Executes and records rounds of a scene's planned episodes on the CPU (one per work
    item; :meth:`close` at its end).

    Attributes:
        rec_cfg: the recording settings (``cameras``, ``render``, ``fps``, image size).
    """

    rec_cfg: Any

    @abstractmethod
    def execute(self, planned: list[tuple[int, int, Any]], attempt: dict[int, int]) -> list[Any]:
        """The recordings of ``(slot, seed, plan)`` (one each, in order, with ``outcome``,
        ``time``, ``sim_seconds`` and ``render_seconds``); ``attempt``: slot -> its attempt
        (for the log)."""

    @abstractmethod
    def close(self) -> None:
        """Releases the renderer."""


class GpuRecorder(ABC):
    """The GPU pipeline's main-process work for one run: per scene, the planner processes'
    results recorded on the GPU and handed to the writers."""

    @abstractmethod
    def record_scene(
        self,
        scene: DemoScene,
        futures: list[Future[SlotResult]],
        attempt: dict[int, int],
        out: dict[str, Any],
        waited: dict[str, float],
    ) -> float:
        """Records a scene's slots as their results come in; returns the scene's GPU seconds.

        Args:
            scene: the scene, set up without its planner.
            futures: the planner processes' results of the scene's open slots.
            attempt: slot -> its attempt (retries go on from there).
            out: the scene's statistics (:func:`~factory.demos.record.slots.item_stats`).
            waited: seconds waited for ``plans`` and for earlier ``writes`` (added to).
        """

    def prepare(self, scene: DemoScene) -> None:
        """Readies what the scene's GPU calls need, in the pipeline's set-up thread once the
        scene is set up: for every scene after the first, while the scene before records on
        the GPU. A failure here must not lose the scene (:meth:`record_scene` then readies it
        itself). Default: nothing."""
        return None

    @abstractmethod
    def close(self) -> None:
        """Waits for the last writes and releases what the run holds."""


@dataclass(frozen=True)
class Execution:
    """An execution model of ``stage=demos`` (see the module).

    Attributes:
        round_slots: slots the CPU path plans and executes together, each round trying the
            next seed of those that failed: 0: all of the item's open slots; 1: a slot at a
            time, its attempts one after another.
        queue_per_worker: the GPU pipeline submits the next scenes' slots (beyond the next
            scene's) while fewer than this many per planner process are pending.
        slot_worker: a planner process's work on one slot from its attempt on, ``(env,
            scene_id, slot, attempt)`` (a module-level function: it is sent to the processes).
        cpu_recorder: ``(scene, env)`` -> the CPU recorder of a work item in the scene.
        gpu_recorder: ``(run)`` -> the GPU pipeline's recorder of one run.
        warm_up: ``(scene, env, device)`` -> compiles (or loads from Warp's kernel cache) the
            GPU kernels the pipeline's recorder will launch in the scene (set up without its
            planner), on Warp device ``device``, and returns the
            :class:`~factory.sim.kernel_preload.PreloadReport` (``stage=warmup``,
            :mod:`factory.demos.warmup`). None: the execution compiles nothing ahead.
    """

    round_slots: int
    queue_per_worker: int
    slot_worker: Callable[[StageEnv, str, int, int], SlotResult]
    cpu_recorder: Callable[[DemoScene, StageEnv], CpuRecorder]
    gpu_recorder: Callable[[GpuRun], GpuRecorder]
    warm_up: Callable[[DemoScene, StageEnv, str], PreloadReport] | None = None


def execution_of(task: Any) -> Execution:
    """The :class:`Execution` of a task (:attr:`~factory.tasks.base.Task.demo_execution`).

    Raises:
        ConfigError: the task names no execution of :data:`EXECUTIONS` (lists them).
    """
    name = task.demo_execution
    if name not in EXECUTIONS:
        raise ConfigError(
            f"task {task.name!r}: demo_execution={name!r} is unknown: choose one of "
            f"{', '.join(EXECUTIONS)}"
        )
    module, _, attr = EXECUTIONS[name].partition(":")
    execution: Execution = getattr(importlib.import_module(module), attr)
    return execution


_SCENES: dict[tuple[str, str, str, str], DemoScene | FactoryError] = {}
_KEEP_SCENES = 3
"""Scenes a process keeps (the GPU pipeline's planners see the slots of two or more scenes
interleaved: the one on the GPU and the next)."""


def cached_scene(env: StageEnv, scene_id: str) -> DemoScene:
    """The task's scene with its planner (:meth:`~factory.tasks.base.Task.demo_scene`), made
    once per process and scene (the last few kept; a scene that cannot host the task is not
    tried again).

    Raises:
        FactoryError: the scene cannot host the task.
    """
    from factory.tasks import get_task

    key = (env.run_dir, env.task, repr(env.demos), scene_id)
    if key in _SCENES:
        _SCENES[key] = _SCENES.pop(key)  # most recently used last
    else:
        while len(_SCENES) >= _KEEP_SCENES:
            del _SCENES[next(iter(_SCENES))]
        try:
            _SCENES[key] = get_task(env.task).demo_scene(env, scene_id)
        except FactoryError as e:
            _SCENES[key] = e
    got = _SCENES[key]
    if isinstance(got, FactoryError):
        raise got.with_traceback(None)
    return got
