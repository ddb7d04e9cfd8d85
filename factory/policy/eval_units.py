"""Units of an evaluation: batches of episodes of one scene, run in this process or spread over
worker processes (``eval.workers``).

A :class:`Unit` is up to ``eval.batch`` episodes of one scene stepped together in one
:class:`~factory.policy.vector_env.PickPlaceVecEnv` of the evaluated task; :func:`run_units`
runs a list of them and yields each unit's records as it finishes, so that the stage appends
them to ``episodes.jsonl`` at once (a killed evaluation resumes after the last finished unit).
With one worker the units run here, one after the other; with more, in ``spawn`` processes
(CUDA and EGL both want a fresh process), each with its own simulation, renderer and copy of
the policy: an image policy's evaluation is bound by rendering on the CPU, and workers spread
it over the cores.
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import StoreError, TaskError
from factory.policy.checkpoint import ACT_PARTS

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class UnitSettings:
    """What every unit of one evaluation shares (picklable: sent once to each worker).

    Attributes:
        run_dir: the run directory.
        kind: ``replay``, ``planner`` or ``trained``.
        policy_ref: a trained policy's reference (``eval.policy``), else empty.
        device: torch device of a trained policy.
        spec: the env's observations (:class:`~factory.policy.obs_spec.ObsSpec`).
        max_steps: frames per episode before truncation (policy episodes).
        nthread: simulation threads per process.
        interpolate: the env's controller (the first-order hold of the task's targets).
        demos: the run's demos settings (``cfg.demos``).
        videos_dir: where rollout videos go.
        reseed_stride: stride of :func:`usable_seed`'s retries.
        task: the evaluated task (a registered name).
        executor: the env's simulation, ``cpu`` or ``warp`` (``eval.executor``).
        ensemble: a trained policy's temporal ensembling ``k`` as resolved where it was
            loaded first (None: off).
        ensemble_every: with ensembling, a new chunk every this many frames.
    """

    run_dir: Path
    kind: str
    policy_ref: str
    device: str
    spec: Any
    max_steps: int
    nthread: int
    interpolate: bool
    demos: Any
    videos_dir: Path
    reseed_stride: int
    task: str
    executor: str = "cpu"
    ensemble: float | None = None
    ensemble_every: int = 1


@dataclass
class Unit:
    """Episodes of one scene stepped together.

    Attributes:
        scene: the scene id.
        jobs: the episodes (:class:`~factory.policy.eval.Job`), at most ``size``.
        size: simulations of the env (the scene's batch size: one env serves all its units).
        videos: the first ``videos`` episodes are written as rollout videos.
        base: replay: the robot's base spot when the episodes were recorded (``x, y, z, yaw``;
            m, rad, world frame), checked against the env's.
    """

    scene: str
    jobs: list[Any]
    size: int
    videos: int = 0
    base: dict[str, float] | None = None


@dataclass
class UnitResult:
    """What a unit gave: records of its episodes, or why its scene cannot host the task.

    ``timing``: where its wall time went (s): ``setup_s`` (the env made or reused, with its
    kernels on MuJoCo Warp; the planner's plans), then :class:`~factory.policy.eval.BatchTiming`'s
    fields, ``episodes`` and ``worlds`` (the env's simulations).
    """

    scene: str
    records: list[dict[str, Any]] = field(default_factory=list)
    skipped: str = ""
    episodes: int = 0
    timing: dict[str, float] = field(default_factory=dict)


def make_units(
    jobs: list[Any], batch: int, videos: int, bases: dict[str, Any] | None = None
) -> list[Unit]:
    """Splits episodes by scene into batches of at most ``batch``; the first ``videos``
    episodes (in order) are recorded as videos; ``bases``: replay's recorded base spots by
    scene."""
    scenes: dict[str, list[Any]] = {}
    for j in jobs:
        scenes.setdefault(j.scene, []).append(j)
    units = []
    for scene, todo in scenes.items():
        size = min(batch, len(todo))
        for start in range(0, len(todo), size):
            part = todo[start : start + size]
            n = min(videos, len(part))
            videos -= n
            units.append(Unit(scene, part, size, n, (bases or {}).get(scene)))
    return units


def usable_seed(env: Any, seed: int, stride: int) -> int:
    """The seed itself, or the first ``seed + k * stride`` whose configuration the sampler
    can place (the env's own rule)."""
    for k in range(100):
        try:
            env.sample_qpos(seed + k * stride)
            return seed + k * stride
        except TaskError:
            continue
    raise TaskError(f"scene {env.setup.scene.id!r}: no seed of 100 places the task objects")


def check_base(scene: str, recorded: dict[str, float] | None, placement: Any) -> None:
    """Replay needs the robot where it stood when the episodes were recorded.

    Raises:
        StoreError: the scene's base spot moved since the demos.
    """
    if recorded is None:
        return
    got = np.array([placement.x, placement.y, placement.z, placement.yaw])
    want = np.array([recorded["x"], recorded["y"], recorded["z"], recorded["yaw"]])
    if not np.allclose(got, want, atol=1e-6):
        raise StoreError(
            f"scene {scene!r}: the robot's base spot {got.round(3).tolist()} differs from the "
            f"recorded {want.round(3).tolist()} (the scene changed since the demos): re-record "
            "them (stage=demos force=true)"
        )


class UnitRunner:
    """Runs units in one process, keeping the env of the last scene and size."""

    def __init__(self, settings: UnitSettings, policy: Any = None, inline: bool = False) -> None:
        self.s = settings
        self.policy = policy
        self.inline = inline  # in the main process: log the progress too (no one else will)
        self._env: Any = None
        self._planner: Any = None
        self._key: tuple[str, int] | None = None

    def close(self) -> None:
        if self._env is not None:
            self._env.close()
        self._env = self._planner = self._key = None

    def _env_for(self, scene: str, size: int) -> tuple[Any, Any]:
        from factory.policy.env import make_vec_env

        if self._key != (scene, size):
            self.close()
            s = self.s
            self._env, self._planner = make_vec_env(
                s.run_dir,
                scene,
                size,
                s.spec,
                s.max_steps,
                s.nthread,
                s.interpolate,
                s.demos,
                s.task,
                s.executor,
            )
            self._key = (scene, size)
        return self._env, self._planner

    def run(self, unit: Unit) -> UnitResult:
        """Runs one unit; a scene that cannot host the task gives ``skipped``."""
        from factory.policy.eval import (
            BatchTiming,
            plan_actions,
            run_batch,
            scripted_actor,
            slug,
            write_video,
        )
        from factory.tasks import get_task

        s = self.s
        t0 = time.perf_counter()
        try:
            env, planner = self._env_for(unit.scene, unit.size)
            if s.kind == "replay":
                if not get_task(s.task).drives_base:  # else the recorded state holds the base
                    check_base(unit.scene, unit.base, env.setup.placement)
            else:
                for j in unit.jobs:
                    j.seed = usable_seed(env, j.seed, s.reseed_stride)
                    j.max_steps = s.max_steps
        except TaskError as e:
            return UnitResult(unit.scene, skipped=str(e), episodes=len(unit.jobs))
        batch = unit.jobs
        if s.kind == "planner":
            for j in batch:
                res = planner.plan_episode(j.seed)
                if hasattr(res, "targets"):
                    j.actions = plan_actions(res.targets, env.per_frame)
                    j.max_steps = len(j.actions)
                else:
                    j.failure = f"plan:{res.reason}"
        video = list(range(unit.videos))
        setup_s = time.perf_counter() - t0
        timing = BatchTiming()
        report = UnitProgress(
            progress_path(s.videos_dir, unit),
            unit,
            int(env.num_envs),
            setup_s,
            s.max_steps,
            log_as=s.videos_dir.parent.name if self.inline else None,
        )
        report.write(timing)
        act_parts: dict[str, float] = {}
        if self.policy is not None:
            policy = self.policy

            def actor(obs: dict[str, np.ndarray], steps: np.ndarray) -> np.ndarray:
                return np.asarray(policy.act(obs), np.float32)

            take = getattr(policy, "take_act_times", None)
            if take is not None:
                take()
            records, frames = run_batch(
                env, batch, actor, video, policy.reset, timing, report.maybe_write
            )
            if take is not None:
                act_parts = {f"act_{k}": v for k, v in take().items()}
        else:
            records, frames = run_batch(
                env, batch, scripted_actor(batch), video, timing=timing, progress=report.maybe_write
            )
        report.close()
        for i, fr in frames.items():
            if len(fr) > 1:
                clip = f"{slug(batch[i].episode_id or batch[i].scene)}-{batch[i].seed}"
                write_video(s.videos_dir / f"{clip}.mp4", fr, s.spec.fps)
        times = {
            "setup_s": round(setup_s, 3),
            **timing.as_dict(),
            **act_parts,
            **kernel_timing(env),
            "episodes": len(batch),
            "worlds": int(env.num_envs),
        }
        return UnitResult(unit.scene, records, episodes=len(batch), timing=times)


# ---- progress of running units

PROGRESS_EVERY_S = 20.0
"""How often a running unit rewrites its progress file (s)."""
PROGRESS_LOG_EVERY_S = 60.0
"""How often the main process logs the running units' progress (s)."""


def progress_path(videos_dir: Path, unit: Unit) -> Path:
    """``<eval out>/progress/<scene>-<first episode>.json``: a running unit's file (its first
    configuration's index, or a replay's recorded episode id)."""
    job = unit.jobs[0] if unit.jobs else None
    first = str((job.episode_id or job.index) if job is not None else 0).replace("/", "_")
    return videos_dir.parent / "progress" / f"{unit.scene}-{first}.json"


class UnitProgress:
    """A running unit's progress file: its frames so far and where their time went, rewritten
    atomically every :data:`PROGRESS_EVERY_S` and removed when the unit ends (its line in the
    log then says the same), so that a unit that never ends still says where it is."""

    def __init__(
        self,
        path: Path,
        unit: Unit,
        worlds: int,
        setup_s: float,
        max_steps: int,
        log_as: str | None = None,
    ) -> None:
        self.path = path
        self.log_as = log_as  # also log the file every PROGRESS_LOG_EVERY_S under this name
        self._logged = time.perf_counter()
        self.head = {
            "schema_version": 1,
            "scene": unit.scene,
            "episodes": len(unit.jobs),
            "worlds": worlds,
            "max_frames": int(max_steps),
            "setup_s": round(setup_s, 3),
            "pid": os.getpid(),
        }
        self._last = 0.0

    def write(self, timing: Any) -> None:
        from factory.store import atomic_write_json

        self._last = time.perf_counter()
        try:
            atomic_write_json(self.path, {**self.head, **timing.as_dict(), "at": time.time()})
        except OSError as e:  # progress is a courtesy: never the unit's failure
            log.debug("eval: progress file %s: %s", self.path, e)

    def maybe_write(self, timing: Any) -> None:
        now = time.perf_counter()
        if now - self._last >= PROGRESS_EVERY_S:
            self.write(timing)
        if self.log_as is not None and now - self._logged >= PROGRESS_LOG_EVERY_S:
            self._logged = now
            self.write(timing)
            log_progress(self.log_as, self.path.parent, only=self.path)

    def close(self) -> None:
        self.path.unlink(missing_ok=True)


def log_progress(name: str, folder: Path, only: Path | None = None) -> None:
    """One line per running unit (its progress file in ``folder``, or ``only`` that one):
    frames so far and where their seconds went."""
    found = sorted(folder.glob("*.json")) if folder.is_dir() else []
    for path in [only] if only is not None else found:
        try:
            p = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        parts = ", ".join(f"{k[:-2]} {float(p.get(k, 0.0)):.1f}" for k in TIMED)
        log.info(
            "eval %s: scene %s running: frame %d of at most %d on %d world(s), %.0f s ago (%s s)",
            name,
            p.get("scene", "?"),
            int(p.get("frames", 0)),
            int(p.get("max_frames", 0)),
            int(p.get("worlds", 0)),
            max(0.0, time.time() - float(p.get("at", time.time()))),
            parts,
        )


# ---- where the time went

TIMED = ("setup_s", "reset_s", "step_s", "observe_s", "act_s", "video_s")
"""The seconds of :attr:`UnitResult.timing`, in the order they are logged."""


ACT_TIMED = tuple(f"act_{k}" for k in ACT_PARTS)
"""A trained policy's ``act_s`` by part (:data:`factory.policy.checkpoint.ACT_PARTS`)."""


KERNEL_TIMED = ("kernel_modules", "kernels_loaded", "kernel_wait_s", "kernel_load_s")
"""A MuJoCo Warp unit's set-up kernels (:func:`kernel_timing`), summed over the units."""


def kernel_timing(env: Any) -> dict[str, float]:
    """What the env's MuJoCo Warp kernel preload did, for the unit's timing: modules loaded
    (compiled, or read from Warp's kernel cache) and its seconds (waited for another process's
    preload, and loading); empty on the CPU executor. A set-up of minutes with many modules
    loaded is a compile: the kernel cache did not hold them."""
    r = getattr(getattr(env, "sim", None), "preload", None)
    if r is None:
        return {}
    return {
        "kernel_modules": int(r.modules),
        "kernels_loaded": int(r.compiled),
        "kernel_wait_s": round(float(r.wait_s), 3),
        "kernel_load_s": round(float(r.load_s + r.trace_s), 3),
    }


def log_unit_timing(name: str, scene: str, timing: dict[str, float]) -> None:
    """One line per finished unit: its episodes, frames and where its seconds went (a trained
    policy's ``act`` by part too)."""
    total = sum(float(timing.get(k, 0.0)) for k in TIMED)
    parts = ", ".join(f"{k[:-2]} {float(timing.get(k, 0.0)):.1f}" for k in TIMED)
    if any(k in timing for k in ACT_TIMED):
        split = ", ".join(f"{k[4:-2]} {float(timing.get(k, 0.0)):.1f}" for k in ACT_TIMED)
        parts += f"; act: {split}"
    if "kernels_loaded" in timing:  # MuJoCo Warp: its set-up's kernels
        parts += (
            f"; setup's kernels: {int(timing['kernels_loaded'])} of "
            f"{int(timing['kernel_modules'])} loaded in {float(timing['kernel_load_s']):.1f}, "
            f"waited {float(timing['kernel_wait_s']):.1f}"
        )
    log.info(
        "eval %s: scene %s: %d episode(s) on %d world(s), %d frames in %.1f s (%s s)",
        name,
        scene,
        int(timing.get("episodes", 0)),
        int(timing.get("worlds", 0)),
        int(timing.get("frames", 0)),
        total,
        parts,
    )


def sum_timings(timings: list[dict[str, float]]) -> dict[str, float]:
    """The units' timings summed (seconds of every process together, not wall time): what
    ``results.json`` keeps as ``timing_this_call`` (empty when no unit ran in this call)."""
    if not timings:
        return {}
    split = any(k in t for t in timings for k in ACT_TIMED)
    kernels = any("kernels_loaded" in t for t in timings)
    keys = (
        *TIMED,
        *(ACT_TIMED if split else ()),
        *(KERNEL_TIMED if kernels else ()),
        "frames",
        "episodes",
    )
    out: dict[str, float] = {k: 0.0 for k in keys}
    for t in timings:
        for k in keys:
            out[k] += float(t.get(k, 0.0))
    counts = ("frames", "episodes", "kernel_modules", "kernels_loaded")
    return {
        "units": len(timings),
        **{k: (int(v) if k in counts else round(v, 3)) for k, v in out.items()},
    }


# ---- worker processes

_RUNNER: UnitRunner | None = None


def worker_gpus(device: str, visible: str | None) -> list[str]:
    """The GPUs a pool of evaluation workers spreads over, one each in turn: the visible ones
    (``CUDA_VISIBLE_DEVICES``, else every GPU torch counts) when ``device`` is ``auto`` or
    ``cuda`` and there are several; else none (every worker keeps the parent's view): each
    worker process is a CUDA context, and contexts on one GPU take turns on it.

    Args:
        device: ``eval.device``.
        visible: the parent's ``CUDA_VISIBLE_DEVICES`` (None: unset).
    """
    if device not in ("auto", "cuda"):
        return []
    if visible is not None:
        ids = [v.strip() for v in visible.split(",") if v.strip()]
    else:
        try:
            import torch

            count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        except ImportError:  # pragma: no cover - torch is a dependency of the policies
            count = 0
        ids = [str(i) for i in range(count)]
    return ids if len(ids) > 1 else []


def _init_worker(
    settings: UnitSettings, torch_threads: int, gpus: list[str], started: Any = None
) -> None:
    global _RUNNER
    if gpus and started is not None:  # this worker's GPU, before anything initialises CUDA
        with started.get_lock():
            k = started.value
            started.value += 1
        os.environ["CUDA_VISIBLE_DEVICES"] = gpus[k % len(gpus)]
    policy = None
    if settings.kind == "trained":
        import torch

        torch.set_num_threads(max(1, torch_threads))
        from factory.policy.checkpoint import load_policy

        k = settings.ensemble
        policy = load_policy(
            settings.policy_ref,
            settings.run_dir,
            settings.device,
            -1.0 if k is None else k,
            settings.ensemble_every,
        )
    _RUNNER = UnitRunner(settings, policy)


def _run_in_worker(unit: Unit) -> UnitResult:
    assert _RUNNER is not None, "the worker was not initialised"
    return _RUNNER.run(unit)


def run_units(
    units: list[Unit], settings: UnitSettings, workers: int, policy: Any = None, cores: int = 1
) -> Iterator[UnitResult]:
    """Runs ``units`` and yields their results as they finish.

    Args:
        units: the batches to run.
        settings: what they share.
        workers: processes (1: here, with ``policy`` already loaded; more: ``spawn`` workers
            that load the policy themselves).
        policy: the loaded policy (trained kind, one worker).
        cores: CPU cores to share among the workers' torch threads.
    """
    if workers <= 1 or len(units) <= 1:
        runner = UnitRunner(settings, policy, inline=True)
        try:
            for unit in units:
                yield runner.run(unit)
        finally:
            runner.close()
        return
    workers = min(workers, len(units))
    gpus = (
        worker_gpus(settings.device, os.environ.get("CUDA_VISIBLE_DEVICES"))
        if settings.kind == "trained" or settings.executor != "cpu"  # the kinds that use one
        else []
    )
    log.info(
        "eval: %d unit(s) over %d worker processes%s",
        len(units),
        workers,
        f", each on one of GPUs {','.join(gpus)} in turn" if gpus else "",
    )
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(settings, max(1, cores // workers), gpus, ctx.Value("i", 0)),
    ) as pool:
        pending: set[Future[UnitResult]] = {pool.submit(_run_in_worker, u) for u in units}
        progress = settings.videos_dir.parent / "progress"
        try:
            while pending:
                done, pending = wait(
                    pending, timeout=PROGRESS_LOG_EVERY_S, return_when=FIRST_COMPLETED
                )
                if not done:
                    log_progress(progress.parent.name, progress)
                for fut in done:
                    yield fut.result()
        finally:
            for fut in pending:
                fut.cancel()
