"""Closed-loop evaluation: episodes, the agents that act in them, and their statistics.

An evaluation is a list of :class:`Job` (a scene and an initial configuration: an evaluation
seed, or a recorded episode's initial MuJoCo state for replay) run in batches of one scene
through :class:`~factory.policy.vector_env.PickPlaceVecEnv` (of the evaluated task). Three
kinds of agent:

* ``replay``: the dataset's recorded actions of each episode, from its recorded initial state;
* ``planner``: the demos' planner on the evaluation configuration (the privileged agent); an
  episode it cannot plan fails with the planner's reason (``plan:<reason>``);
* ``trained``: a policy (``LoadedPolicy.act``) on the env's observations.

Each finished episode is one record ``{scene, seed, episode_id, success, reason, steps}``
(``episodes.jsonl``); :func:`summarize` turns records into the results (success rate, Wilson
95 % interval, per scene, failure reasons).
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.policy.vector_env import PickPlaceVecEnv

log = logging.getLogger(__name__)

RESULTS_SCHEMA_VERSION = 1
Z95 = 1.959963984540054
"""The standard normal quantile of a two-sided 95 % interval."""

Actor = Callable[[dict[str, np.ndarray], np.ndarray], np.ndarray]
"""``actor(obs, steps) -> actions``: observations (n, ...) and each env's frame index (n,) to
actions (n, A): A = 8 (fixed base) or 11 (mobile: + base target)."""


@dataclass
class Job:
    """One episode to run.

    Attributes:
        scene: the scene id.
        seed: the configuration's seed (evaluation seed, or the recorded demo's seed).
        index: the configuration's number in its scene (evaluation).
        episode_id: the recorded episode (replay), else None.
        state: the recorded initial MuJoCo integration state (replay), else None.
        actions: actions per frame (T, 8) (replay, planner), else None.
        max_steps: frames before truncation.
        failure: why the episode cannot run (a planning failure): it fails without simulation.
    """

    scene: str
    seed: int
    index: int = 0
    episode_id: str | None = None
    state: np.ndarray | None = None
    actions: np.ndarray | None = None
    max_steps: int = 400
    failure: str = ""

    @property
    def key(self) -> str:
        """Identifies the episode in ``episodes.jsonl`` (resume)."""
        return self.episode_id or f"{self.scene}#{self.index}"


def slug(text: str) -> str:
    """``text`` as a file or folder name (letters, digits, ``_.-``)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_.") or "policy"


def record_key(record: dict[str, Any]) -> str:
    """The :attr:`Job.key` of a finished episode's record."""
    return str(record.get("episode_id") or f"{record['scene']}#{record['index']}")


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a success rate (two-sided, 95 % by default)."""
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    lo = 0.0 if successes == 0 else max(0.0, centre - half)
    hi = 1.0 if successes == n else min(1.0, centre + half)
    return (lo, hi)


def plan_actions(targets: np.ndarray, per_frame: int) -> np.ndarray:
    """A plan's per-physics-step targets (T, 8) -> actions per frame (F - 1, 8), as
    ``stage=demos`` records them: the target at the end of each frame."""
    t = len(targets)
    frames = int(np.ceil(t / per_frame)) + 1
    idx = np.minimum((np.arange(frames - 1) + 1) * per_frame, t) - 1
    return np.asarray(targets[idx], np.float32)


def scripted_actor(jobs: list[Job]) -> Actor:
    """Plays each job's ``actions``; past their end the last action is held."""

    width = next((j.actions.shape[1] for j in jobs if j.actions is not None), 8)

    def act(obs: dict[str, np.ndarray], steps: np.ndarray) -> np.ndarray:
        out = np.zeros((len(steps), width), np.float32)
        for i, job in enumerate(jobs):
            if job.actions is not None and len(job.actions):
                out[i] = job.actions[min(int(steps[i]), len(job.actions) - 1)]
        return out

    return act


@dataclass
class BatchTiming:
    """Where a batch's wall time went (s), summed over its frames.

    Attributes:
        frames: env steps taken (frames of the longest episode).
        reset_s: the envs' reset (and the policy's).
        step_s: ``env.step``: the controller and the physics of a frame; on MuJoCo Warp also
            the frame's kinematics and camera rays (one CUDA graph launch, asynchronous: the
            GPU's time shows where the host next waits for it, in ``observe_s``).
        observe_s: ``env.observations``: the images and signals the actor reads, copied to
            the host.
        act_s: the actor (a trained policy's inference, or the scripted actions).
        video_s: frames drawn for the rollout videos.
    """

    frames: int = 0
    reset_s: float = 0.0
    step_s: float = 0.0
    observe_s: float = 0.0
    act_s: float = 0.0
    video_s: float = 0.0

    def as_dict(self) -> dict[str, float]:
        """Plain numbers (s rounded to ms) for JSON and logs."""
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def run_batch(
    env: PickPlaceVecEnv,
    jobs: list[Job],
    actor: Actor,
    video: Iterable[int] = (),
    reset: Callable[[], None] | None = None,
    timing: BatchTiming | None = None,
    progress: Callable[[BatchTiming], None] | None = None,
) -> tuple[list[dict[str, Any]], dict[int, list[np.ndarray]]]:
    """Runs up to ``env.num_envs`` episodes of one scene together until all have ended.

    Args:
        env: the batched env (at least ``len(jobs)`` simulations).
        jobs: the episodes; all with ``state`` (replay) or all with ``seed`` configurations.
        actor: what acts (see :data:`Actor`); its actions for finished envs are ignored.
        video: indices into ``jobs`` whose frames are rendered for a video.
        reset: called after the envs are reset (e.g. the policy's ``reset``).
        timing: filled with where the time went (:class:`BatchTiming`), when given.
        progress: called with the timing so far after every frame (it decides how often to
            tell anyone).

    Returns:
        one record per job (in order) and the video frames by job index.
    """
    t = timing if timing is not None else BatchTiming()
    clock = time.perf_counter
    n = len(jobs)
    ids = list(range(n))
    limits = [j.max_steps for j in jobs]
    runnable = [i for i in ids if not jobs[i].failure]
    records: list[dict[str, Any] | None] = [None] * n
    frames: dict[int, list[np.ndarray]] = {i: [] for i in video if i in runnable}
    for i in ids:
        if jobs[i].failure:
            records[i] = _record(jobs[i], False, jobs[i].failure, 0)
    if runnable:
        t0 = clock()
        sel = [jobs[i] for i in runnable]
        if all(j.state is not None for j in sel):
            states = np.stack([j.state for j in sel])  # type: ignore[misc]
            env.reset(states=states, ids=runnable, max_steps=[limits[i] for i in runnable])
        else:
            env.reset(
                seeds=[j.seed for j in sel], ids=runnable, max_steps=[limits[i] for i in runnable]
            )
        if reset is not None:
            reset()
        t1 = clock()
        t.reset_s += t1 - t0
        for i in frames:
            frames[i].append(env.render(i))
        t.video_s += clock() - t1
        while not env.done[runnable].all():
            t0 = clock()
            obs = env.observations()
            t1 = clock()
            actions = np.asarray(actor(obs, env.steps), np.float32)
            if len(actions) < env.num_envs:
                pad = np.zeros((env.num_envs - len(actions), actions.shape[1]), np.float32)
                actions = np.concatenate([actions, pad])
            running = ~env.done
            t2 = clock()
            env.step(actions)
            t3 = clock()
            for i in frames:
                if running[i]:
                    frames[i].append(env.render(i))
            t.observe_s += t1 - t0
            t.act_s += t2 - t1
            t.step_s += t3 - t2
            t.video_s += clock() - t3
            t.frames += 1
            if progress is not None:
                progress(t)
        for i in runnable:
            r = env.result(i)
            records[i] = _record(jobs[i], r["success"], r["reason"], r["steps"], r.get("record"))
    return [r for r in records if r is not None], frames


def _record(
    job: Job, success: bool, reason: str, steps: int, extra: dict[str, Any] | None = None
) -> dict[str, Any]:
    """An episode's line of ``episodes.jsonl``; ``extra``: the env's own fields (the mobile
    env's ``subtask`` reached and ``subtasks_done``)."""
    return {
        "scene": job.scene,
        "seed": job.seed,
        "index": job.index,
        "episode_id": job.episode_id,
        "success": bool(success),
        "reason": "" if success else (reason or "timeout"),
        "steps": int(steps),
        **(extra or {}),
    }


# ---- records on disk


def read_records(path: Path) -> list[dict[str, Any]]:
    """The finished episodes of ``episodes.jsonl`` (a line cut off by a kill is ignored)."""
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            log.warning("%s: ignoring a line cut off by an interrupted run", path)
            continue
        if isinstance(rec, dict) and "success" in rec and "scene" in rec:
            out.append(rec)
    return out


def drop_torn_records(path: Path) -> None:
    """Rewrites ``episodes.jsonl`` without lines a killed run left unfinished, so that new
    records are appended after whole lines only."""
    if not path.is_file():
        return
    text = path.read_text()
    good = [json.dumps(r, sort_keys=True) for r in read_records(path)]
    if text != "".join(g + "\n" for g in good):
        from factory.store import atomic_write_text

        atomic_write_text(path, "".join(g + "\n" for g in good))


def append_records(path: Path, records: list[dict[str, Any]]) -> None:
    """Appends finished episodes to ``episodes.jsonl`` and syncs them to disk."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "".join(json.dumps(r, sort_keys=True) + "\n" for r in records)
    with open(path, "a", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def summarize(
    records: list[dict[str, Any]],
    policy: str,
    kind: str,
    training_data: dict[str, Any] | None,
    seconds: float,
    extra: dict[str, Any] | None = None,
    subtasks: tuple[str, ...] = (),
) -> dict[str, Any]:
    """The content of ``results.json``: success rate with its Wilson 95 % interval, per scene,
    failure reasons, seeds and the policy's training data; per sub-task (``subtasks``: the
    task's, in order) when the records count them."""
    n = len(records)
    k = sum(1 for r in records if r["success"])
    per_scene: dict[str, dict[str, Any]] = {}
    for r in records:
        s = per_scene.setdefault(r["scene"], {"episodes": 0, "successes": 0})
        s["episodes"] += 1
        s["successes"] += int(bool(r["success"]))
    for s in per_scene.values():
        s["success_rate"] = s["successes"] / s["episodes"]
        s["ci95"] = list(wilson(s["successes"], s["episodes"]))
    failures = Counter(r["reason"] for r in records if not r["success"])
    extra = dict(extra or {})
    if subtasks and any("subtasks_done" in r for r in records):
        extra["per_subtask"] = per_subtask(records, subtasks)
    seeds: dict[str, list[int]] = {}
    for r in records:
        seeds.setdefault(r["scene"], []).append(int(r["seed"]))
    return {
        "schema_version": RESULTS_SCHEMA_VERSION,
        "policy": policy,
        "kind": kind,
        "success_rate": k / n if n else 0.0,
        "ci95": list(wilson(k, n)),
        "episodes": n,
        "successes": k,
        "per_scene": dict(sorted(per_scene.items())),
        "failures": dict(failures.most_common()),
        "seeds": {s: sorted(v) for s, v in sorted(seeds.items())},
        "training_data": training_data,
        "seconds": seconds,
        **extra,
    }


def per_subtask(
    records: list[dict[str, Any]], subtasks: tuple[str, ...]
) -> dict[str, dict[str, Any]]:
    """Per sub-task (``subtasks``, in order): episodes that began it (``started``), that
    completed it (``completed``), its success rate among those that began it with the Wilson
    95 % interval, and the share of all episodes that completed it (``of_all``). A record's
    ``subtasks_done`` counts the sub-tasks it completed (all on success; failed planner
    episodes count 0)."""
    n = len(records)
    done = [int(r.get("subtasks_done", 0)) for r in records]
    out: dict[str, dict[str, Any]] = {}
    for k, name in enumerate(subtasks):
        started = sum(1 for d in done if d >= k)
        completed = sum(1 for d in done if d >= k + 1)
        out[name] = {
            "started": started,
            "completed": completed,
            "success_rate": completed / started if started else 0.0,
            "ci95": list(wilson(completed, started)),
            "of_all": completed / n if n else 0.0,
        }
    return out


def write_video(path: Path, frames: list[np.ndarray], fps: float) -> None:
    """Writes RGB frames (H, W, 3) uint8 as an h264 mp4 (PyAV), atomically."""
    import av

    h, w = frames[0].shape[:2]
    h2, w2 = h + h % 2, w + w % 2  # yuv420p needs even sizes
    tmp = path.with_name(f".{path.name}.{os.getpid()}.mp4")
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(tmp), "w") as out:
        stream = out.add_stream("h264", rate=max(1, round(fps)))
        stream.width, stream.height, stream.pix_fmt = w2, h2, "yuv420p"
        stream.options = {"crf": "20", "preset": "veryfast"}
        for im in frames:
            if (h2, w2) != (h, w):
                im = np.pad(im, ((0, h2 - h), (0, w2 - w), (0, 0)), mode="edge")
            for packet in stream.encode(av.VideoFrame.from_ndarray(im, format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    os.replace(tmp, path)
