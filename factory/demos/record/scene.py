"""A scene set up to record one task's episodes: the object a task's
:meth:`~factory.tasks.base.Task.demo_scene` hook returns and ``stage=demos`` records with.

The demos machinery (:mod:`factory.demos.cpu_items`, :mod:`factory.demos.gpu_pipeline`) is
written once; per scene it asks the task's :class:`DemoScene` to plan an episode from a seed
(:meth:`DemoScene.plan`) and what a successful recording is stored as
(:meth:`DemoScene.payload`), and it executes the plans the way the task's
:attr:`~factory.tasks.base.Task.demo_execution` says: together on a batch of worlds by the
executors of :mod:`factory.demos.execute`, or, for a :class:`SimulatingScene`, one episode at
a time by the task's own simulation (:meth:`SimulatingScene.simulate`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from factory.demos.record.slots import StageEnv
from factory.schema.episode import EpisodeInfo

if TYPE_CHECKING:
    from factory.demos.record.from_states import StatesRecorder
    from factory.demos.record.rig import CameraRig

__all__ = ["DemoScene", "SimulatingScene"]


class DemoScene(ABC):
    """One scene of a run composed with the task's robot, and its planner.

    Args:
        env: the stage's settings (run, ``demos.*``, task, root seed).
        setup: the composed scene (``scene``, ``model``, ``cleared``; the task's set-up type).
        planner: its episode planner; None in a process that only records (the GPU
            pipeline's main process), where :meth:`plan` is not called.
    """

    plan_type: ClassVar[type[Any]]
    """The task's episode plan: what :meth:`plan` returns when the episode planned."""

    def __init__(self, env: StageEnv, setup: Any, planner: Any | None) -> None:
        self.env = env
        self.setup = setup
        self.planner = planner

    @property
    def scene_id(self) -> str:
        return str(self.setup.scene.id)

    def summary(self) -> dict[str, Any]:
        """What the stage's summary keeps of the scene (``scenes.<id>``): ``cleared``, the
        objects taken out for the robot; a task with a fixed base spot adds ``robot_base``
        (x, y m, yaw rad)."""
        return {"cleared": list(self.setup.cleared)}

    @abstractmethod
    def plan(self, seed: int) -> Any:
        """Plans the episode of ``seed`` (deterministic): a :attr:`plan_type`, else a failure
        with ``reason`` (a failure key), ``detail`` (a sentence for the log) and ``seconds``
        (planning time, s). A plan has ``seconds`` and ``plan_seconds`` (segment -> s)."""

    @abstractmethod
    def payload(
        self, slot: int, seed: int, plan: Any, rec: Any, rec_cfg: Any, recorder: str = "cpu"
    ) -> tuple[EpisodeInfo, dict[str, np.ndarray]]:
        """The metadata and arrays a successful recording of ``plan`` is stored as (episode
        ``slot`` of the scene, planned from ``seed``), recorded with the settings ``rec_cfg``
        by the ``recorder`` executor (``cpu`` or ``warp``):
        :func:`~factory.demos.record.payload.episode_meta` and
        :func:`~factory.demos.record.payload.episode_arrays` with the task's fields and arrays."""


class SimulatingScene(DemoScene):
    """A :class:`DemoScene` whose task simulates each episode itself (``demo_execution =
    "episode"``): the CPU path simulates and draws an episode at a time, the GPU pipeline's
    workers simulate without images and the GPU draws the recorded states with the scene's
    own cameras (:meth:`camera_rig`)."""

    @abstractmethod
    def record_config(self, render: bool | None = None) -> Any:
        """The recording settings of ``demos.*`` (``render``: overrides ``demos.render``)."""

    @abstractmethod
    def renderer(self, rec_cfg: Any) -> Any:
        """A CPU renderer of the scene's cameras for :meth:`simulate` (has ``close()``)."""

    @abstractmethod
    def camera_rig(self, rec_cfg: Any) -> CameraRig:
        """The cameras :meth:`renderer` draws with the settings ``rec_cfg``, for a renderer of
        recorded states (the GPU pipeline's,
        :class:`~factory.demos.execute.recording_render_warp.WarpRecordingRenderer`): each
        recorded camera's key, its camera in :attr:`setup`'s model, image size and lens, in
        the recorded order, and the depth format."""

    @abstractmethod
    def simulate(self, plan: Any, rec_cfg: Any, renderer: Any | None = None) -> Any:
        """Executes ``plan`` on the CPU and records it: a recording with ``outcome`` (its
        success check), ``time`` (F,) s, ``sim_seconds`` and ``render_seconds``; images drawn
        by ``renderer`` for a successful episode when ``rec_cfg.render``."""

    gpu_physics_by_default: ClassVar[bool] = True
    """Whether ``demos.episode_physics=auto`` simulates the task's episodes on MuJoCo Warp when
    :meth:`states_recorder` gives a hook (false: only ``demos.episode_physics=warp`` does,
    until the task's agreement with the CPU executor is measured)."""

    def states_recorder(self) -> StatesRecorder | None:
        """How an episode's recording and verdict follow from its simulated states, so that
        the GPU pipeline may simulate the task's episodes on MuJoCo Warp
        (:mod:`factory.demos.record.from_states`, ``demos.episode_physics``); None (the
        default): the planner processes simulate them on the CPU."""
        return None
