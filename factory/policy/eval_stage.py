"""``stage=eval``: closed-loop rollouts of a trained policy, of the recorded actions (replay) or
of the planner, in the simulation env; success rates with 95 % intervals.

Protocol (the paper's): held-out scenes, the run's scenes that are not in the policy's training
dataset (``eval.scenes=heldout``), each with ``eval.episodes_per_scene`` initial configurations
drawn by the demos' sampler from evaluation seeds (:func:`factory.policy.env.eval_seed`,
disjoint from the demos' seeds). ``replay`` instead runs every recorded episode of the dataset
from its recorded initial MuJoCo state with its recorded actions.

The evaluated task is ``task=`` or the one the dataset or the policy is of
(:func:`~factory.policy.eval_task.evaluated_task`); its env
(:class:`~factory.policy.vector_env.PickPlaceVecEnv`) runs it as the demos do. The mobile task
(:mod:`factory.tasks.mobile_pick_place.env`): the demos' planner's spawn per seed, 11-D actions
(arm, gripper, base target), sub-tasks advanced by the env's own checks, and ``per_subtask``
results besides the rest.

Writes ``eval/<policy>/``: ``episodes.jsonl`` (one line per finished episode; a re-run skips
them, so a killed evaluation resumes), ``results.json`` and ``videos/*.mp4``. Bad input (an
unknown policy, a run without held-out scenes, a checkpoint whose features the env cannot
give) stops with one line before anything is written.
"""

from __future__ import annotations

import json
import logging
import math
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from factory.context import StageContext
from factory.cores import usable_cores
from factory.errors import ConfigError, PolicyError, StoreError, TaskError
from factory.store import atomic_write_json

log = logging.getLogger(__name__)

KINDS = ("replay", "planner")
RUN_SCHEMA_VERSION = 1
MAX_BATCH = 16
"""Episodes of a scene stepped together when ``eval.batch`` is 0, on the CPU (with
``eval.executor=warp``: all of a scene's, one world each)."""
EXECUTORS = {"cpu": False, "warp": True, "warp_opengl": True}
"""``eval.executor`` settings -> whether a scene's episodes are the worlds of one device (one
worker process unless ``eval.workers`` says otherwise)."""
DEFAULT_MAX_STEPS = 400


def check_config(ec: Any) -> None:
    """Raises :class:`ConfigError` naming a bad ``eval.*`` value."""
    if ec.episodes_per_scene < 1:
        raise ConfigError(f"eval.episodes_per_scene must be >= 1, got {ec.episodes_per_scene}")
    if min(ec.max_steps, ec.batch, ec.workers, ec.nthread, ec.videos) < 0:
        raise ConfigError(
            "eval.max_steps, eval.batch, eval.workers, eval.nthread and eval.videos must be >= 0"
        )
    if getattr(ec, "executor", "cpu") not in EXECUTORS:
        raise ConfigError(
            f"eval.executor={ec.executor!r} is unknown: use one of {', '.join(EXECUTORS)}"
        )
    ensemble = getattr(ec, "ensemble", None)
    if ensemble is not None and not math.isfinite(float(ensemble)):
        raise ConfigError(f"eval.ensemble must be a finite number or null, got {ensemble}")
    every = getattr(ec, "ensemble_every", 1)
    if not isinstance(every, int) or isinstance(every, bool) or every < 1:
        raise ConfigError(
            f"eval.ensemble_every={every!r}: a whole number of frames >= 1 (1: a chunk every frame)"
        )
    scenes = ec.scenes
    if isinstance(scenes, str):
        if scenes not in ("heldout", "train"):
            raise ConfigError(
                f"eval.scenes must be heldout, train or a list of scene ids, got {scenes!r}"
            )
    elif not (isinstance(scenes, list | tuple) or hasattr(scenes, "__iter__")) or not list(scenes):
        raise ConfigError("eval.scenes must be heldout, train or a non-empty list of scene ids")


# ---- the dataset


def _dataset_meta(root: Path) -> dict[str, Any] | None:
    path = root / "meta" / "factory.json"
    if not path.is_file():
        return None
    meta: dict[str, Any] = json.loads(path.read_text())
    return meta


def _dataset_actions(root: Path) -> dict[int, np.ndarray]:
    """The ``action`` rows of every episode of a LeRobot dataset, by episode index."""
    import pyarrow.parquet as pq

    files = sorted((root / "data").glob("*/*.parquet"))
    if not files:
        raise StoreError(f"{root} holds no data files: re-run stage=dataset")
    out: dict[int, list[np.ndarray]] = {}
    for f in files:
        table = pq.read_table(f, columns=["episode_index", "frame_index", "action"])
        ep = table.column("episode_index").to_numpy()
        frame = table.column("frame_index").to_numpy()
        act = np.stack(table.column("action").to_numpy(zero_copy_only=False))
        for e in np.unique(ep):
            rows = ep == e
            out.setdefault(int(e), []).append(np.column_stack([frame[rows], act[rows]]))
    result = {}
    for e, parts in out.items():
        rows = np.concatenate(parts)
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        result[e] = rows[:, 1:].astype(np.float32)
    return result


def _replay_jobs(
    store: Any, dataset: Path, scenes: list[str] | None
) -> tuple[list[Any], dict[str, Any]]:
    """Replay jobs from the dataset (recorded initial states and actions), or from the
    episode stores when the run has no dataset."""
    from factory.demos.record.episodes import EpisodeStore
    from factory.policy.eval import Job

    jobs: list[Job] = []
    bases: dict[str, Any] = {}
    meta = _dataset_meta(dataset)
    if meta is not None:
        actions = _dataset_actions(dataset)
        for ep in meta["episodes"]:
            if scenes is not None and ep["scene_id"] not in scenes:
                continue
            extra = dataset / "extras" / ep["episode_id"]
            try:
                state0 = np.load(extra / "states.npz")["state"][0]
                robot = json.loads((extra / "robot.json").read_text())
            except (OSError, KeyError, ValueError) as e:
                raise StoreError(
                    f"{extra}: the episode's recorded states are unreadable ({e}): re-run "
                    "stage=dataset"
                ) from None
            act = actions.get(int(ep["episode_index"]))
            if act is None or len(act) != ep["n_frames"]:
                raise StoreError(
                    f"{dataset}: episode {ep['episode_id']!r} has no or wrong action rows: "
                    "re-run stage=dataset"
                )
            bases[ep["scene_id"]] = robot["base"]
            jobs.append(
                Job(
                    scene=ep["scene_id"],
                    seed=int(ep["seed"]),
                    episode_id=ep["episode_id"],
                    state=state0,
                    actions=act[:-1],
                    max_steps=int(ep["n_frames"]) - 1,
                )
            )
        return jobs, bases
    stores = sorted((store.root / "episodes").glob("shard-*.zarr"))
    if not stores:
        raise StoreError(
            f"no dataset at {dataset} and no episode stores in {store.root / 'episodes'}: run "
            "stage=demos (and stage=dataset) first"
        )
    for path in stores:
        es = EpisodeStore(path)
        for info in es:
            if scenes is not None and info.scene_id not in scenes:
                continue
            g = es.arrays(info.episode_id)
            bases[info.scene_id] = info.robot.__dict__
            jobs.append(
                Job(
                    scene=info.scene_id,
                    seed=int(info.seed),
                    episode_id=info.episode_id,
                    state=np.asarray(g["state"][0]),
                    actions=np.asarray(g["action"][:], np.float32)[:-1],
                    max_steps=info.n_frames - 1,
                )
            )
    return jobs, bases


# ---- what acts


def _policy_ref(cfg: Any) -> str:
    ref = str(cfg.eval.policy or "")
    if not ref:
        train = getattr(cfg, "train", None)
        ref = str(getattr(train, "name", "") or "")
    if not ref:
        raise PolicyError(
            "eval.policy is empty: name a trained policy (eval.policy=<name>), a pretrained_model "
            "folder, replay or planner"
        )
    return ref


def _check_policy_exists(ref: str, run_dir: Path) -> None:
    """An unknown policy fails here, with what exists."""
    if ref in KINDS or (run_dir / "policy" / ref).is_dir() or Path(ref).is_dir():
        return
    trained = sorted(p.name for p in (run_dir / "policy").glob("*") if p.is_dir())
    have = f"trained here: {', '.join(trained)}" if trained else "none trained in this run"
    raise PolicyError(
        f"unknown eval.policy {ref!r}: use replay, planner, a trained policy's name ({have}; "
        "stage=train makes one) or a path to a lerobot pretrained_model folder"
    )


def _load_trained(
    ref: str, run_dir: Path, device: str, ensemble: float | None, every: int = 1
) -> Any:
    try:
        from factory.policy.checkpoint import load_policy
    except ImportError as e:  # pragma: no cover - the module is part of the package
        raise PolicyError(f"trained policies cannot be loaded here ({e})") from None
    return load_policy(ref, run_dir, device, ensemble, every)


def _check_features(info: Any, spec: Any) -> None:
    from factory.policy.checkpoint import check_features

    check_features(info, spec.keys(), {k: s for k, (s, _) in spec.shapes().items()})


def _spec_for_policy(info: Any, run_spec: Any, env_state: bool) -> Any:
    """The env's observations for a trained policy: what it reads, from what the run records.

    Raises:
        PolicyError: the policy reads a feature the env cannot give (another dataset's
            cameras or inputs).
    """
    from dataclasses import replace

    full = replace(run_spec, env_state=True)
    _check_features(info, full)
    needs = set(info.features)
    cams = tuple(c for c in full.cameras if f"observation.images.{c}" in needs)
    depth_cams = tuple(c for c in full.cameras if f"observation.depth.{c}" in needs)
    if depth_cams:
        cams = tuple(c for c in full.cameras if c in set(cams) | set(depth_cams))
    return replace(
        full,
        cameras=cams,
        depth=bool(depth_cams),
        env_state=env_state or "observation.environment_state" in needs,
        pose_cameras=full.pose_cameras if "observation.camera_poses" in needs else (),
    )


# ---- the stage


def _identity(
    kind: str, name: str, ref: str, ec: Any, dataset: Path, policy: Any
) -> dict[str, Any]:
    """What the episodes of ``eval/<name>/`` belong to: the policy (its checkpoint), the seed
    root, the step limit, the controller and the dataset."""
    if policy is not None:
        ref = f"{Path(policy.path).resolve()} (step {policy.info.steps})"
    elif Path(ref).is_dir():
        ref = str(Path(ref).resolve())
    return {
        "schema_version": RUN_SCHEMA_VERSION,
        "policy": name,
        "kind": kind,
        "ref": ref,
        "seed": ec.seed,
        "max_steps": ec.max_steps,
        "interpolate": ec.interpolate,
        "dataset": str(dataset),
        "ensemble": getattr(policy, "ensemble", None),
        # only when set: earlier evaluations' folders keep resuming
        **(
            {"ensemble_every": every} if (every := getattr(policy, "ensemble_every", 1)) > 1 else {}
        ),
    }


def _prepare_out(out: Path, identity: dict[str, Any], force: bool) -> None:
    """Checks that ``out`` holds episodes of this evaluation (resume) or starts it afresh."""
    path = out / "run.json"
    if path.is_file():
        old = json.loads(path.read_text())
        if force or old != identity:
            if not force:
                diff = sorted(k for k in identity if old.get(k) != identity[k])
                raise PolicyError(
                    f"{out} holds episodes of another evaluation (differs in {', '.join(diff)}): "
                    "pass force=true to start over, or evaluate with the same settings"
                )
            log.info("eval: force=true, starting %s afresh", out)
            for p in ("episodes.jsonl", "results.json"):
                (out / p).unlink(missing_ok=True)
            shutil.rmtree(out / "videos", ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(path, identity)


def run(ctx: StageContext) -> dict[str, Any]:
    """Runs ``stage=eval``; returns the results' headline and the ``produced`` list."""
    from tqdm import tqdm

    from factory.console import terminal
    from factory.policy.env import RESEED_STRIDE, eval_seed
    from factory.policy.eval import (
        Job,
        append_records,
        drop_torn_records,
        read_records,
        record_key,
        slug,
        summarize,
    )
    from factory.policy.eval_task import evaluated_task
    from factory.policy.eval_units import (
        UnitSettings,
        log_unit_timing,
        make_units,
        run_units,
        sum_timings,
    )
    from factory.policy.obs_spec import obs_spec_of_dataset, obs_spec_of_demos

    t0 = time.perf_counter()
    cfg = ctx.cfg
    ec = cfg.eval
    check_config(ec)
    if ctx.shard.count > 1:
        raise ConfigError("stage=eval runs in one process: drop shard.index/shard.count")
    store = ctx.require_store()
    run_dir = store.root
    ref = _policy_ref(cfg)
    _check_policy_exists(ref, run_dir)
    kind = ref if ref in KINDS else "trained"
    policy = None
    if kind == "trained":
        policy = _load_trained(
            ref, run_dir, ec.device, getattr(ec, "ensemble", None), getattr(ec, "ensemble_every", 1)
        )
        name = slug(policy.info.name)
        dataset = Path(ec.dataset or policy.info.dataset)
        train_scenes = list(policy.info.scenes)
        training_data: dict[str, Any] | None = {
            "scenes": train_scenes,
            "episodes": int(policy.info.episodes),
            "dataset": str(dataset),
        }
    else:
        name = ref
        dataset = Path(ec.dataset) if ec.dataset else run_dir / "dataset" / "merged"
        meta0 = _dataset_meta(dataset)
        train_scenes = list(meta0["scenes"]) if meta0 else []
        training_data = None
        if kind == "replay" and meta0 is not None:
            training_data = {
                "scenes": train_scenes,
                "episodes": len(meta0["episodes"]),
                "dataset": str(dataset),
            }
    if ec.name:
        name = slug(str(ec.name))
    meta = _dataset_meta(dataset)
    task = evaluated_task(
        str(cfg.task),
        meta,
        policy.info.features if policy is not None else None,
        policy.info.layout if policy is not None else "",
    )
    run_scenes = store.scene_ids()
    listed = None if isinstance(ec.scenes, str) else [str(s) for s in ec.scenes]
    if listed is not None:
        missing = [s for s in listed if s not in run_scenes]
        if missing:
            raise StoreError(f"eval.scenes: no scene(s) {missing} in {store.scenes_dir}")
    # the episodes
    bases: dict[str, Any] = {}
    if kind == "replay":
        jobs, bases = _replay_jobs(store, dataset, listed)
        if not jobs:
            raise StoreError(f"no recorded episodes to replay in {dataset}: run stage=dataset")
        scenes = sorted({j.scene for j in jobs})
    else:
        if listed is not None:
            scenes = listed
        elif ec.scenes == "train":
            scenes = [s for s in train_scenes if s in run_scenes]
            if not scenes:
                raise PolicyError(
                    f"eval.scenes=train: none of the training scenes {train_scenes[:5]} is in "
                    f"{store.scenes_dir}"
                )
        else:
            scenes = [s for s in run_scenes if s not in set(train_scenes)]
            if not scenes:
                raise PolicyError(
                    f"no held-out scenes: all {len(run_scenes)} scene(s) of the run are in the "
                    "training dataset; evaluate on them with eval.scenes=train, or generate more "
                    "scenes (stage=generate) and evaluate before recording demos in them"
                )
        jobs = [
            Job(scene=s, seed=eval_seed(ec.seed, s, k), index=k)
            for s in scenes
            for k in range(ec.episodes_per_scene)
        ]
    longest = max((e["n_frames"] for e in meta["episodes"]), default=0) if meta else 0
    max_steps = ec.max_steps or (int(1.5 * longest) if longest else DEFAULT_MAX_STEPS)
    # what the env observes
    if meta is not None:
        run_spec = obs_spec_of_dataset(dataset, env_state=True, task=task.name)
    else:
        run_spec = obs_spec_of_demos(cfg.demos, env_state=True, task=task.name)
    if policy is not None:
        spec = _spec_for_policy(policy.info, run_spec, ec.env_state)
        order = tuple(getattr(policy.perception, "pose_cameras", None) or ())
        if order and spec.pose_cameras and len(order) == len(spec.pose_cameras):
            spec = replace(spec, pose_cameras=order)  # the calibration in the policy's order
    else:
        spec = replace(run_spec, cameras=(), depth=False, env_state=ec.env_state, pose_cameras=())
    # resume
    out = Path(ec.out) if ec.out else run_dir / "eval" / name
    identity = {**_identity(kind, name, ref, ec, dataset, policy), **task.eval_identity()}
    _prepare_out(out, identity, cfg.force)
    episodes_path = out / "episodes.jsonl"
    drop_torn_records(episodes_path)
    done = {record_key(r): r for r in read_records(episodes_path)}
    videos_dir = out / "videos"
    have_videos = len(list(videos_dir.glob("*.mp4"))) if videos_dir.is_dir() else 0
    want_videos = max(0, ec.videos - have_videos)
    cores = usable_cores()
    skipped: dict[str, str] = {}
    timings: list[dict[str, float]] = []
    all_keys = {j.key for j in jobs}
    todo_total = sum(1 for j in jobs if j.key not in done)
    log.info(
        "eval %s (%s): %d episode(s) in %d scene(s), %d finished before; max %d steps",
        name,
        kind,
        len(jobs),
        len(scenes),
        len(jobs) - todo_total,
        max_steps,
    )
    executor = getattr(ec, "executor", "cpu")
    if EXECUTORS[executor]:  # one process drives the device; a scene's episodes are its worlds
        workers = ec.workers or 1
        batch = ec.batch or max(1, len(jobs))
    else:
        workers = ec.workers or max(1, cores // 4)
        batch = ec.batch or MAX_BATCH
    nthread = ec.nthread or max(1, cores // workers)
    todo_jobs = [j for j in jobs if j.key not in done]
    units = make_units(todo_jobs, batch, want_videos, bases)
    settings = UnitSettings(
        run_dir=run_dir,
        kind=kind,
        policy_ref=str(policy.path) if policy is not None else "",
        device=ec.device,
        spec=spec,
        max_steps=max_steps,
        nthread=nthread,
        interpolate=ec.interpolate,
        demos=cfg.demos,
        videos_dir=videos_dir,
        reseed_stride=RESEED_STRIDE,
        task=task.name,
        executor=executor,
        ensemble=policy.ensemble if policy is not None else None,
        ensemble_every=policy.ensemble_every if policy is not None else 1,
    )
    with tqdm(
        total=len(jobs),
        initial=len(jobs) - todo_total,
        desc=f"eval {name}",
        unit="episode",
        disable=None,
        file=terminal(),
    ) as bar:
        for res in run_units(units, settings, workers, policy, cores):
            if res.skipped:
                if res.scene not in skipped:
                    log.warning("eval: scene %s cannot host the task: %s", res.scene, res.skipped)
                skipped[res.scene] = res.skipped
            else:
                append_records(episodes_path, res.records)
                for r in res.records:
                    done[record_key(r)] = r
                if res.timing:
                    log_unit_timing(name, res.scene, res.timing)
                    timings.append(res.timing)
            bar.update(res.episodes)
    records = [r for k, r in done.items() if k in all_keys]
    results = summarize(
        records,
        name,
        kind,
        training_data,
        time.perf_counter() - t0,
        {
            "ref": identity["ref"],
            "scenes_skipped": skipped,
            "max_steps": max_steps,
            "controller": "interpolate" if ec.interpolate else "hold",
            "ensemble": policy.ensemble if policy is not None else None,
            "ensemble_every": policy.ensemble_every if policy is not None else 1,
            "seed_root": ec.seed,
            "executor": executor,
            "timing_this_call": sum_timings(timings),
            **task.eval_notes(),
            "seed_rule": "replay: the recorded episodes' seeds"
            if kind == "replay"
            else "factory.policy.env.eval_seed(root, scene, k) = 2**32 + sha256 "
            "(demos' seeds are < 2**32)",
        },
        task.subtasks(),
    )
    atomic_write_json(out / "results.json", results)
    if not records and skipped:
        raise TaskError(
            f"no scene of the evaluation can host the task; first: {next(iter(skipped.values()))}"
        )
    log.info(
        "eval %s: success %.1f %% (95 %% CI %.1f-%.1f %%) over %d episodes; failures %s",
        name,
        100 * results["success_rate"],
        100 * results["ci95"][0],
        100 * results["ci95"][1],
        results["episodes"],
        results["failures"] or "none",
    )
    n_videos = len(list(videos_dir.glob("*.mp4"))) if videos_dir.is_dir() else 0
    return {
        "policy": name,
        "kind": kind,
        "success_rate": results["success_rate"],
        "ci95": results["ci95"],
        "episodes": results["episodes"],
        "failures": results["failures"],
        "produced": [
            {"what": "eval episodes", "count": results["episodes"], "path": str(out.absolute())},
            {"what": "eval videos", "count": n_videos, "path": str(videos_dir.absolute())},
        ],
    }
