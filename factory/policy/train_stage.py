"""``stage=train``: a lerobot policy (``train.policy``, diffusion by default) trained on the run's
merged dataset, with resumable checkpoints under ``policy/<name>/``.

Order of work: every check that can fail on bad input (the settings, the dataset and the
features the inputs need, the policy type and its options, a ``policy/<name>`` holding a
training on other data) runs before anything is written. A re-run continues from the newest
checkpoint (a killed training loses at most ``train.save_every`` steps) up to ``train.steps``;
a finished one is skipped; ``force=true`` starts over.
"""

from __future__ import annotations

import json
import logging
import re
import shutil
import time
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any

from factory.context import StageContext
from factory.dataset.layout import meta_layout
from factory.errors import ConfigError, PolicyError
from factory.policy.checkpoint import (
    CHECKPOINTS,
    TRAIN_JSON,
    TrainInfo,
    policy_dir,
    read_info,
    write_train_json,
)
from factory.policy.device_batches import LOADERS
from factory.policy.inputs import INPUTS, VISIONS, InputSpec, input_spec
from factory.policy.recipe import PRECISIONS
from factory.policy.shading import MAX_STRENGTH

log = logging.getLogger(__name__)

NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
MODEL_SETTINGS = ("horizon", "n_obs_steps", "n_action_steps", "vision")
"""``train.*`` keys that shape the model: a resumed training must have the same."""


def check_config(tc: Any) -> None:
    """Raises :class:`ConfigError` naming a bad ``train.*`` value."""
    if not NAME.match(str(tc.name)):
        raise ConfigError(
            f"train.name {tc.name!r} is not a safe folder name: use letters, digits, _ . -"
        )
    if tc.inputs not in INPUTS:
        raise ConfigError(f"train.inputs must be one of {', '.join(INPUTS)}, got {tc.inputs!r}")
    vision = getattr(tc, "vision", "end_to_end")
    if vision not in VISIONS:
        raise ConfigError(f"train.vision must be one of {', '.join(VISIONS)}, got {vision!r}")
    if vision == "perception" and tc.inputs == "state":
        raise ConfigError(
            "train.vision=perception reads the cameras: use train.inputs=rgb or rgbd, or "
            "train.vision=end_to_end"
        )
    cams = getattr(tc, "cameras", None) or []
    if not isinstance(cams, list | tuple) or not all(isinstance(c, str) for c in cams):
        raise ConfigError(
            f"train.cameras must be a list of camera names, e.g. [wrist], got {cams!r}"
        )
    if getattr(tc, "perception_noise_m", 0.0) < 0:
        raise ConfigError(
            f"train.perception_noise_m must be >= 0 (0: none), got {tc.perception_noise_m}"
        )
    for key in ("steps", "batch_size", "save_every", "log_every", "keep_checkpoints"):
        if getattr(tc, key) < 1:
            raise ConfigError(f"train.{key} must be >= 1, got {getattr(tc, key)}")
    for key in ("horizon", "n_obs_steps", "n_action_steps", "num_workers", "threads"):
        if getattr(tc, key) < 0:
            raise ConfigError(f"train.{key} must be >= 0, got {getattr(tc, key)}")
    if tc.loader not in LOADERS:
        raise ConfigError(f"train.loader must be one of {', '.join(LOADERS)}, got {tc.loader!r}")
    if tc.video_cache not in ("auto", "memory", "off"):
        raise ConfigError(f"train.video_cache must be auto, memory or off, got {tc.video_cache!r}")
    if tc.max_minutes < 0:
        raise ConfigError(f"train.max_minutes must be >= 0 (0: no limit), got {tc.max_minutes}")
    shading = getattr(tc, "augment_shading", 0.0)
    if not 0 <= shading <= MAX_STRENGTH:
        raise ConfigError(
            f"train.augment_shading must be in [0, {MAX_STRENGTH}] (0: off), got {shading}"
        )
    if tc.precision not in PRECISIONS:
        raise ConfigError(
            f"train.precision must be one of {', '.join(PRECISIONS)}, got {tc.precision!r}"
        )
    if tc.aux_state is not None and tc.aux_state < 0:
        raise ConfigError(f"train.aux_state must be >= 0 (0: off), got {tc.aux_state}")
    if tc.ema is not None and not 0 <= tc.ema < 1:
        raise ConfigError(f"train.ema must be in [0, 1) (0: off), got {tc.ema}")
    if tc.gpus < 1:
        raise ConfigError(f"train.gpus must be >= 1, got {tc.gpus}")
    if tc.eval_every_minutes < 0:
        raise ConfigError(
            f"train.eval_every_minutes must be >= 0 (0: no learning curve), got "
            f"{tc.eval_every_minutes}"
        )
    if tc.eval_episodes < 1:
        raise ConfigError(f"train.eval_episodes must be >= 1, got {tc.eval_episodes}")
    if tc.lr < 0:
        raise ConfigError(f"train.lr must be >= 0 (0: the policy's preset), got {tc.lr}")
    options = tc.options or {}
    if not isinstance(options, dict) or any(
        not isinstance(v, dict | type(None)) for v in options.values()
    ):
        raise ConfigError(
            "train.options must map a policy type to its fields, e.g. "
            "train.options={diffusion: {down_dims: [64, 128]}}"
        )


def _settings(tc: Any) -> dict[str, Any]:
    data = asdict(tc) if is_dataclass(tc) and not isinstance(tc, type) else dict(tc)
    return json.loads(json.dumps(data, default=str))


def _identity(info: TrainInfo) -> dict[str, Any]:
    """What must match for a training to continue another's checkpoints."""
    cfg = info.config or {}
    return {
        "policy type": info.policy_type,
        "inputs": info.inputs,
        "dataset": info.dataset,
        "features": info.features,
        "dataset frames": info.frames,
        "scenes": info.scenes,
        **{f"train.{k}": cfg.get(k) for k in MODEL_SETTINGS},
        "train.options": (cfg.get("options") or {}).get(info.policy_type),
    }


def _dataset(root: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """``meta/info.json`` and ``meta/factory.json`` (empty if absent) of a dataset."""
    path = root / "meta" / "info.json"
    if not path.is_file():
        raise PolicyError(
            f"no LeRobot dataset at {root}: run stage=dataset first (or set train.dataset)"
        )
    info = json.loads(path.read_text())
    meta_path = root / "meta" / "factory.json"
    meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    return info, meta


def selected_scenes(wanted: Any, meta: dict[str, Any], root: Path) -> list[str] | None:
    """The scene ids ``train.scenes`` picks from a dataset's ``meta/factory.json`` (None: all).

    Raises:
        ConfigError: a bad value, a scene the dataset lacks, or more scenes than it has.
    """
    if wanted is None or wanted == "" or wanted == []:
        return None
    have = sorted(meta.get("scenes", []))
    if not have:
        raise ConfigError(
            f"train.scenes needs the dataset's meta/factory.json (a factory dataset): {root} "
            "has none; leave train.scenes empty"
        )
    if isinstance(wanted, bool) or not isinstance(wanted, int | list | tuple):
        raise ConfigError(
            f"train.scenes must be empty, a number or a list of scene ids, got {wanted!r}"
        )
    if isinstance(wanted, int):
        if not 1 <= wanted <= len(have):
            raise ConfigError(
                f"train.scenes={wanted}: the dataset at {root} has {len(have)} scene(s)"
            )
        return have[:wanted]
    missing = [str(s) for s in wanted if str(s) not in have]
    if missing:
        raise ConfigError(
            f"train.scenes: the dataset at {root} has no scene(s) {missing} (it has "
            f"{len(have)}: {', '.join(have[:5])}{' ...' if len(have) > 5 else ''})"
        )
    return sorted({str(s) for s in wanted})


def train_info(tc: Any, spec: InputSpec, root: Path) -> TrainInfo:
    """The training record of ``train.*`` on the dataset at ``root`` (steps 0)."""
    info, meta = _dataset(root)
    chosen = selected_scenes(getattr(tc, "scenes", None), meta, root)
    scenes = list(meta.get("scenes", []))
    episodes = int(info.get("total_episodes", len(meta.get("episodes", []))))
    frames = int(info.get("total_frames", 0))
    indices: list[int] = []
    if chosen is not None:
        eps = [e for e in meta.get("episodes", []) if e.get("scene_id") in chosen]
        scenes, episodes = chosen, len(eps)
        indices = sorted(int(e["episode_index"]) for e in eps)
        frames = sum(int(e.get("n_frames", 0)) for e in eps)
    return TrainInfo(
        name=tc.name,
        policy_type=tc.policy,
        inputs=tc.inputs,
        dataset=str(root.resolve()),
        scenes=scenes,
        episodes=episodes,
        steps=0,
        fps=round(float(info["fps"])),
        features=spec.raw_features(),
        policy_features=spec.model_features(),
        depth_max_m=spec.depth_max_m,
        frames=frames,
        config=_settings(tc),
        episode_indices=indices,
        action=spec.action,
        vision="perception" if spec.perception else "end_to_end",
        layout=meta_layout(meta),
    )


def run(ctx: StageContext) -> dict[str, Any]:
    """Runs ``stage=train``; returns the training's headline and the ``produced`` list."""
    from factory.policy.checkpoint import resolve_device
    from factory.policy.train import checkpoint_of, dataset_root, policy_config, train

    t0 = time.perf_counter()
    cfg = ctx.cfg
    tc = cfg.train
    check_config(tc)
    if ctx.shard.count > 1:
        raise ConfigError("stage=train runs in one process: drop shard.index/shard.count")
    store = ctx.require_store()
    root = dataset_root(store.root, tc.dataset)
    features = _dataset(root)[0]["features"]
    spec = input_spec(
        tc.inputs,
        features,
        tc.action,
        getattr(tc, "vision", "") == "perception",
        list(getattr(tc, "cameras", None) or []),
        bool(getattr(tc, "perception_points", True)),
    )
    if spec.mobile and spec.inputs == "state" and not spec.poses:
        log.warning(
            "train %s: the mobile dataset has no object poses (exported before its "
            "observation.environment_state), so train.inputs=state reads the robot, its base "
            "pose and the sub-task only (blind to the object): re-run stage=dataset "
            "force=true, or use train.inputs=rgb or rgbd",
            tc.name,
        )
    device = resolve_device(tc.device)
    if tc.gpus > 1 and device.startswith("cuda"):
        import torch

        have = torch.cuda.device_count()
        if have < tc.gpus:
            raise ConfigError(
                f"train.gpus={tc.gpus} but this machine has {have} CUDA device(s): "
                f"use train.gpus={max(have, 1)} or fewer"
            )
    policy_config(tc, spec, device)  # an unknown type or bad options fail before any write
    info = train_info(tc, spec, root)
    out = policy_dir(store.root, tc.name)
    resume: Path | None = None
    if out.exists() and cfg.force:
        log.info("train %s: force=true, starting over", tc.name)
        shutil.rmtree(out)
    elif (out / TRAIN_JSON).is_file():
        old = read_info(out / TRAIN_JSON)
        mine, theirs = _identity(info), _identity(old)
        diff = [k for k in mine if mine[k] != theirs[k]]
        if diff:
            raise PolicyError(
                f"{out} holds a training that differs in {', '.join(diff)} (its checkpoints do "
                "not fit this data or these settings): pass force=true to start over, or "
                "choose another train.name"
            )
        ckpt, step = checkpoint_of(out)
        if ckpt is not None and step >= tc.steps:
            log.info("train %s: finished before (%d steps in %s)", tc.name, step, ckpt)
            return {
                "policy": tc.name,
                "steps": step,
                "skipped": True,
                "produced": [_produced(out)],
            }
        resume = ckpt
        info.steps = step
    out.mkdir(parents=True, exist_ok=True)
    if resume is None:
        write_train_json(out, info)
    curve = None
    if tc.eval_every_minutes > 0:
        from factory.policy.learning_curve import LearningCurve

        curve = LearningCurve(cfg, out, tc.eval_every_minutes, tc.eval_episodes)
    try:
        if tc.gpus > 1:
            from factory.policy.data_parallel import launch

            launch(tc.gpus, device, _train_rank, (tc, spec, root, out, info, resume, curve))
            ckpt, step = checkpoint_of(out)
            result = _result_of(out, resume, ckpt, step)
        else:
            result = train(tc, spec, root, out, info, resume, curve=curve)
    except BaseException:
        if curve is not None:
            curve.stop()  # no evaluation outlives a failed or killed training
        raise
    log.info(
        "train %s: step %d (from %d), loss %.4f, %.2f steps/s, %.1f s",
        tc.name,
        result.step,
        result.resumed_from,
        result.loss,
        result.steps_per_s,
        time.perf_counter() - t0,
    )
    return {
        "policy": tc.name,
        "type": tc.policy,
        "inputs": tc.inputs,
        "device": device,
        "steps": result.step,
        "finished": result.step >= tc.steps,
        "resumed_from": result.resumed_from,
        "loss": result.loss,
        "steps_per_s": result.steps_per_s,
        "checkpoint": result.checkpoint,
        "produced": [_produced(out)],
    }


def _train_rank(accelerator: Any, *args: Any) -> None:
    """One rank of a data-parallel training (:func:`factory.policy.data_parallel.launch`)."""
    from factory.policy.train import train

    tc, spec, root, out, info, resume, curve = args
    train(tc, spec, root, out, info, resume, curve=curve, accelerator=accelerator)


def _result_of(out: Path, resume: Path | None, ckpt: Path | None, step: int) -> Any:
    """What rank 0 trained, read back from its log and checkpoints."""
    from factory.policy.checkpoint import TRAIN_LOG, checkpoint_step
    from factory.policy.train import TrainResult

    lines = [json.loads(x) for x in (out / TRAIN_LOG).read_text().splitlines() if x.strip()]
    losses = [r for r in lines if "loss" in r]
    last = losses[-1] if losses else {}
    start = checkpoint_step(resume) if resume is not None else 0
    return TrainResult(
        step=step,
        resumed_from=start,
        loss=float(last.get("loss", float("nan"))),
        seconds=float(last.get("seconds", 0.0)),
        steps_per_s=float(last.get("steps_per_s", 0.0)),
        checkpoint=str(ckpt) if ckpt is not None else "",
    )


def _produced(out: Path) -> dict[str, Any]:
    root = out / CHECKPOINTS
    n = len([p for p in root.iterdir() if p.is_dir() and p.name.isdigit()]) if root.is_dir() else 0
    return {"what": "policy checkpoints", "count": n, "path": str(root.absolute())}
