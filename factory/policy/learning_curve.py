"""The learning curve of a training (``train.eval_every_minutes``): held-out success as the
policy trains.

Every ``train.eval_every_minutes`` of training the newest checkpoint's ``pretrained_model`` is
copied to ``policy/<name>/curve/<step>/`` (so that pruning old checkpoints cannot pull it away)
and ``stage=eval`` runs on it in a separate process (the run's own config with
``eval.episodes_per_scene=train.eval_episodes``, no videos, results in that folder,
``eval.*`` for the rest: the scenes, workers, device) while the training goes on. At most one
evaluation runs at a time; when one finishes, a line ``{"step", "seconds", "success", "ci95",
"episodes", "failures", "eval_seconds"}`` (``seconds``: training seconds at the checkpoint)
joins the loss lines of ``train_log.jsonl``, which the run report plots against steps and
time. The last step is evaluated too before ``stage=train`` returns.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
from pathlib import Path
from typing import Any

from factory.errors import PolicyError
from factory.policy.checkpoint import PRETRAINED

log = logging.getLogger(__name__)

CURVE = "curve"
"""Folder of the learning-curve evaluations under ``policy/<name>/``."""


def curve_gpu(device: str, visible: str | None) -> tuple[str | None, str]:
    """The GPU of the curve's evaluations: ``eval.device=cuda:<i>`` (e.g. ``cuda:1`` on a
    two-GPU machine, the training on GPU 0) becomes ``CUDA_VISIBLE_DEVICES`` of the evaluation's
    processes (the ``i``-th of the training's visible devices) and ``cuda`` in them, so that the
    evaluations' inference does not time-slice the training's GPU.

    Args:
        device: ``eval.device``.
        visible: the training process's ``CUDA_VISIBLE_DEVICES`` (None: unset, every GPU).

    Returns:
        ``(CUDA_VISIBLE_DEVICES for the evaluation or None to keep it, its eval.device)``.

    Raises:
        PolicyError: an index the visible devices do not have (names them).
    """
    if not device.startswith("cuda:"):
        return None, device
    index = device.split(":", 1)[1]
    if not index.isdigit():
        raise PolicyError(f"eval.device={device}: expected cuda:<index>, e.g. cuda:1")
    if visible is None:
        return index, "cuda"
    ids = [v.strip() for v in visible.split(",") if v.strip()]
    if int(index) >= len(ids):
        raise PolicyError(
            f"eval.device={device} but CUDA_VISIBLE_DEVICES={visible} shows {len(ids)} GPU(s): "
            f"use cuda:0..cuda:{len(ids) - 1}"
        )
    return ids[int(index)], "cuda"


def _evaluate(cfg: Any, log_path: str) -> None:
    """The child process: ``stage=eval`` (:func:`factory.policy.eval_stage.run`) with its
    output in ``log_path``."""
    import sys

    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    logging.basicConfig(
        level=getattr(logging, str(cfg.log_level).upper(), logging.INFO),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    visible, device = curve_gpu(cfg.eval.device, os.environ.get("CUDA_VISIBLE_DEVICES"))
    if visible is not None:  # before anything initialises CUDA: the workers inherit it
        os.environ["CUDA_VISIBLE_DEVICES"] = visible
        cfg = dataclasses.replace(cfg, eval=dataclasses.replace(cfg.eval, device=device))
    from factory.context import StageContext
    from factory.policy.eval_stage import run
    from factory.sim.gl import configure_gl
    from factory.store import RunStore, Shard

    configure_gl(cfg.render.gl)  # before anything imports mujoco
    run(StageContext(cfg=cfg, store=RunStore(cfg.run_dir), shard=Shard(0, 1)))


@dataclasses.dataclass
class _Job:
    step: int
    seconds: float
    folder: Path
    process: Any
    started: float


class LearningCurve:
    """Starts and collects the evaluations of a training's checkpoints.

    Args:
        cfg: the run's config (:class:`factory.config.FactoryConfig`) of ``stage=train``.
        out: ``policy/<name>/``.
        every_minutes: training minutes between evaluations (> 0).
        episodes: episodes per scene of each evaluation.
    """

    def __init__(self, cfg: Any, out: Path, every_minutes: float, episodes: int) -> None:
        curve_gpu(cfg.eval.device, os.environ.get("CUDA_VISIBLE_DEVICES"))  # fails here, early
        self.cfg = cfg
        self.root = out / CURVE
        self.every = 60.0 * every_minutes
        self.episodes = episodes
        self.next_at = self.every
        self.job: _Job | None = None
        self.done: set[int] = set()
        self.points: list[dict[str, Any]] = []

    def due(self, elapsed: float) -> bool:
        """Whether an evaluation should start now (``elapsed``: seconds of this call's
        training); False while one runs."""
        return self.job is None and elapsed >= self.next_at

    def start(self, checkpoint: Path, step: int, seconds: float) -> None:
        """Evaluates ``checkpoint`` (saved at ``step``, ``seconds`` into training) in the
        background."""
        import multiprocessing

        folder = self.root / str(step)
        model = folder / PRETRAINED
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(checkpoint / PRETRAINED, model)
        cfg = dataclasses.replace(
            self.cfg,
            stage="eval",
            force=True,
            eval=dataclasses.replace(
                self.cfg.eval,
                policy=str(model.absolute()),
                out=str(folder.absolute()),
                name=f"{self.cfg.train.name}_step{step}",
                episodes_per_scene=self.episodes,
                videos=0,
            ),
        )
        ctx = multiprocessing.get_context("spawn")
        # not daemonic: stage=eval starts a pool of worker processes when eval.workers > 1
        proc = ctx.Process(target=_evaluate, args=(cfg, str(folder / "eval.log")))
        proc.start()
        self.job = _Job(step, seconds, folder, proc, time.perf_counter())
        self.next_at += self.every
        self.done.add(step)
        log.info(
            "train: learning curve: evaluating step %d in the background (%s)",
            step,
            folder / "eval.log",
        )

    def poll(self, wait: bool = False) -> list[dict[str, Any]]:
        """The curve points of evaluations finished since the last call (``wait``: wait for
        the one running)."""
        job = self.job
        if job is None:
            return []
        if wait:
            job.process.join()
        elif job.process.is_alive():
            return []
        self.job = None
        results = job.folder / "results.json"
        if job.process.exitcode != 0 or not results.is_file():
            log.warning(
                "train: learning curve: the evaluation of step %d failed (exit %s): see %s",
                job.step,
                job.process.exitcode,
                job.folder / "eval.log",
            )
            return []
        res = json.loads(results.read_text())
        point = {
            "step": job.step,
            "seconds": round(job.seconds, 3),
            "success": res["success_rate"],
            "ci95": res["ci95"],
            "episodes": res["episodes"],
            "failures": res.get("failures", {}),
            "eval_seconds": round(time.perf_counter() - job.started, 1),
        }
        self.points.append(point)
        log.info(
            "train: learning curve: step %d: success %.1f %% (95 %% CI %.1f-%.1f %%) over %d "
            "episodes",
            job.step,
            100 * point["success"],
            100 * point["ci95"][0],
            100 * point["ci95"][1],
            point["episodes"],
        )
        return [point]

    def stop(self) -> None:
        """Ends the evaluation running, if any (the training failed or was interrupted)."""
        job, self.job = self.job, None
        if job is not None and job.process.is_alive():
            job.process.terminate()
            job.process.join(10)

    def finish(self, checkpoint: Path | None, step: int, seconds: float) -> list[dict[str, Any]]:
        """Evaluates the last checkpoint when its step has no point yet: waits for the
        evaluation running, then starts that one; returns the points collected on the way
        (:meth:`poll` with ``wait`` collects the last)."""
        points = self.poll(wait=True)
        if checkpoint is not None and step not in self.done:
            self.start(checkpoint, step, seconds)
        return points
