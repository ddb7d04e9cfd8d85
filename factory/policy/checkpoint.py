"""Trained policies on disk: ``policy/<name>/`` checkpoints in lerobot's format, what each was
trained on (:class:`TrainInfo`), and loading one to act in the env (:func:`load_policy`).

Layout of ``<run_dir>/policy/<name>/``:

* ``checkpoints/<step:06d>/pretrained_model/``: lerobot's ``save_pretrained`` output
  (``config.json``, ``model.safetensors``, ``train_config.json``, the pre- and post-processor
  pipelines with their normalisation statistics) plus ``factory_policy.json`` (the
  :class:`TrainInfo`, so the folder alone can be loaded and evaluated);
* ``checkpoints/<step>/training_state/``: optimizer, scheduler, RNG states and the step
  (lerobot's ``save_training_state``), for resuming;
* ``checkpoints/last``: a symbolic link to the newest complete checkpoint (lerobot's name);
* ``train.json``: the :class:`TrainInfo` of the newest checkpoint (``schema_version`` 1);
* ``train_log.jsonl``: one JSON object per logged step (``step, loss, lr, seconds, ...``).

A checkpoint is written into a temporary folder and renamed into place, and ``last`` is
replaced atomically after it, so a killed training leaves the previous checkpoint intact.

Importing this module is cheap; :func:`load_policy` imports torch and lerobot.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import shutil
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import PolicyError
from factory.store import atomic_write_json

log = logging.getLogger(__name__)

TRAIN_SCHEMA_VERSION = 1
TRAIN_JSON = "train.json"
TRAIN_LOG = "train_log.jsonl"
INFO_IN_MODEL = "factory_policy.json"
"""The :class:`TrainInfo` inside each ``pretrained_model`` folder."""
CHECKPOINTS = "checkpoints"
LAST = "last"
PRETRAINED = "pretrained_model"
TRAINING_STATE = "training_state"


@dataclass
class TrainInfo:
    """What a policy was trained on and how it reads observations.

    Attributes:
        name: the policy's name (``policy/<name>/``).
        policy_type: lerobot policy type (``diffusion``, ``act``, ...).
        inputs: ``state``, ``rgb`` or ``rgbd`` (:mod:`factory.policy.inputs`).
        dataset: path of the merged LeRobot dataset it trained on.
        scenes: the scene ids trained on (the dataset's, or those of ``train.scenes``).
        episodes: episodes trained on.
        steps: optimizer steps done (of this checkpoint).
        fps: frames per second of the data (Hz); the policy acts at this rate.
        features: observation key the policy reads (as the env and the dataset name it) ->
            shape of one observation as the env gives it (images (H, W, 3) uint8, depth
            (H, W) uint16 mm).
        policy_features: model input key -> shape as the model sees it after conversion
            (e.g. ``observation.state`` (17,), images (3, H, W)).
        depth_max_m: depth clipping range of ``rgbd`` (m).
        frames: frames trained on.
        episode_indices: the dataset's episode indices trained on (empty: all of them).
        action: what the model predicts (``tool``, ``tool_rel`` or ``joint``, see
            :mod:`factory.policy.inputs`); the env always gets 8-D joint targets.
        config: the ``train.*`` settings of the run.
        layout: the dataset's layout (``meta/factory.json``), which names the task it was
            trained on (:func:`factory.dataset.layout.layout_task`); empty in policies trained
            before it was recorded (their features tell the task).
    """

    name: str
    policy_type: str
    inputs: str
    dataset: str
    scenes: list[str]
    episodes: int
    steps: int
    fps: int
    features: dict[str, list[int]]
    policy_features: dict[str, list[int]] = field(default_factory=dict)
    depth_max_m: float = 2.0
    frames: int = 0
    config: dict[str, Any] = field(default_factory=dict)
    episode_indices: list[int] = field(default_factory=list)
    action: str = "joint"
    vision: str = "end_to_end"
    layout: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"schema_version": TRAIN_SCHEMA_VERSION, **asdict(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any], where: str) -> TrainInfo:
        """Reads a ``train.json`` / ``factory_policy.json`` object.

        Raises:
            PolicyError: another schema version or missing fields.
        """
        version = data.get("schema_version")
        if version != TRAIN_SCHEMA_VERSION:
            raise PolicyError(
                f"{where}: schema_version {version!r}, this factory reads "
                f"{TRAIN_SCHEMA_VERSION}: retrain with stage=train force=true"
            )
        known = set(cls.__dataclass_fields__)
        values = {k: v for k, v in data.items() if k in known}
        try:
            info = cls(**values)
        except TypeError as e:
            raise PolicyError(f"{where} is incomplete ({e}): retrain with stage=train") from None
        info.features = {k: [int(x) for x in v] for k, v in info.features.items()}
        return info


def read_info(path: Path) -> TrainInfo:
    """A :class:`TrainInfo` from a JSON file."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise PolicyError(f"{path} is unreadable ({e}): retrain with stage=train") from None
    return TrainInfo.from_json(data, str(path))


def check_features(
    info: TrainInfo,
    obs_keys: Iterable[str],
    shapes: Mapping[str, Sequence[int]] | None = None,
) -> None:
    """Checks that observations with these keys (and shapes) feed the policy.

    Args:
        info: the policy's training record.
        obs_keys: keys the env or the dataset provides.
        shapes: key -> shape of one observation (no batch axis), checked where given.

    Raises:
        PolicyError: a feature the policy reads is missing or has another shape (a policy
            trained on another dataset: other cameras, image size or inputs).
    """
    keys = set(obs_keys)
    missing = [k for k in info.features if k not in keys]
    if missing:
        raise PolicyError(
            f"policy {info.name!r} (inputs={info.inputs}, trained on {info.dataset}) reads "
            f"{', '.join(missing)}, which these observations lack: evaluate it where the "
            "training data came from, or train a policy on this data (stage=train)"
        )
    for k, want in info.features.items():
        if shapes is not None and k in shapes and list(shapes[k]) != list(want):
            raise PolicyError(
                f"policy {info.name!r} reads {k} of shape {tuple(want)}, got "
                f"{tuple(shapes[k])} (another dataset's setting): train a policy on this data "
                "(stage=train) or evaluate where it was trained"
            )


# ---- the run directory


def policy_dir(run_dir: Path, name: str) -> Path:
    return Path(run_dir) / "policy" / name


def last_checkpoint(out: Path) -> Path | None:
    """The newest complete checkpoint folder of ``policy/<name>`` (``checkpoints/last``)."""
    link = out / CHECKPOINTS / LAST
    if not link.exists():
        return None
    target = link.resolve()
    if not (target / PRETRAINED / "config.json").is_file():
        return None
    return target


def checkpoint_step(ckpt: Path) -> int:
    """The step of a checkpoint (its ``training_state/training_step.json``)."""
    from_file = ckpt / TRAINING_STATE / "training_step.json"
    try:
        return int(json.loads(from_file.read_text())["step"])
    except (OSError, ValueError, KeyError):
        return int(ckpt.name)


def publish_checkpoint(tmp: Path, final: Path) -> None:
    """Renames a written checkpoint folder into place and points ``last`` at it (atomic)."""
    if final.exists():
        shutil.rmtree(final)
    os.replace(tmp, final)
    link = final.parent / LAST
    tmp_link = final.parent / f".{LAST}.tmp"
    tmp_link.unlink(missing_ok=True)
    tmp_link.symlink_to(final.name)
    os.replace(tmp_link, link)


def prune_checkpoints(out: Path, keep: int) -> None:
    """Removes all but the ``keep`` newest checkpoints (never the one ``last`` names) and
    leftovers of interrupted writes."""
    root = out / CHECKPOINTS
    if not root.is_dir():
        return
    for p in root.glob(".tmp-*"):
        shutil.rmtree(p, ignore_errors=True)
    last = last_checkpoint(out)
    steps = sorted(p for p in root.iterdir() if p.is_dir() and p.name.isdigit())
    for p in steps[: max(0, len(steps) - max(1, keep))]:
        if last is None or p.resolve() != last:
            shutil.rmtree(p, ignore_errors=True)


def write_train_json(out: Path, info: TrainInfo) -> None:
    atomic_write_json(out / TRAIN_JSON, info.to_json())


# ---- loading


def resolve_ref(ref: str, run_dir: Path | None) -> Path:
    """The ``pretrained_model`` folder a reference names.

    Args:
        ref: a policy name under ``run_dir/policy/`` (its newest checkpoint), or a path to a
            ``pretrained_model`` folder, a checkpoint folder or a ``policy/<name>`` folder.

    Raises:
        PolicyError: nothing loadable there.
    """
    candidates = []
    if run_dir is not None and ref and "/" not in ref and ref not in (".", ".."):
        candidates.append(policy_dir(Path(run_dir), ref))
    candidates.append(Path(ref))
    for p in candidates:
        if (p / "config.json").is_file() and (p / "model.safetensors").is_file():
            return p
        if (p / PRETRAINED / "config.json").is_file():
            return p / PRETRAINED
        last = last_checkpoint(p)
        if last is not None:
            return last / PRETRAINED
        if (p / CHECKPOINTS).is_dir():
            raise PolicyError(
                f"policy {ref!r} has no finished checkpoint in {p / CHECKPOINTS}: run stage=train "
                "(it resumes) until it saves one"
            )
    trained = []
    if run_dir is not None and (Path(run_dir) / "policy").is_dir():
        trained = sorted(p.name for p in (Path(run_dir) / "policy").iterdir() if p.is_dir())
    have = f"trained in this run: {', '.join(trained)}" if trained else "none trained in this run"
    raise PolicyError(
        f"no policy {ref!r} ({have}): train one with stage=train train.name={ref}, or give the "
        "path of a lerobot pretrained_model folder"
    )


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """lerobot's ``from_pretrained`` prints to stdout; its words go to the log instead."""
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            yield
    finally:
        for line in buf.getvalue().splitlines():
            log.debug("lerobot: %s", line)


def resolve_device(device: str) -> str:
    """``auto`` -> ``cuda`` when a CUDA device is present, else ``cpu``; others unchanged.

    Raises:
        PolicyError: ``cuda`` asked for where there is none.
    """
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise PolicyError(f"device={device} but torch sees no CUDA device: use device=auto or cpu")
    return device


ENSEMBLE_K = 0.1
"""``eval.ensemble`` when unset, for the policies :func:`resolve_ensemble` ensembles: the weight
``exp(-k * age)`` of each kept chunk's prediction, the oldest chunk first (ACT's temporal
ensembling). On 3 held-out kitchens x 30 a state policy (2 CPU cores, 8,129 steps) succeeded
in 71 of 90 configurations ensembled (``stage=eval``) against 51 of 90 executing 8 actions of
each chunk, its ``slip`` failures 27 -> 6 (``benchmarks/results/policy-state-grasp-cpu2.json``;
docs/POLICY.md, "Results measured")."""


def resolve_ensemble(setting: float | None, info: TrainInfo) -> float | None:
    """The temporal ensembling weight of a loaded policy, or None (the policy's own chunks).

    Args:
        setting: ``eval.ensemble``: None (on with :data:`ENSEMBLE_K` for a diffusion policy
            whose actions are absolute, off otherwise), a negative value (off) or ``k >= 0``.
        info: what the policy was trained on.

    Raises:
        PolicyError: ``k >= 0`` asked of a policy that cannot be ensembled (not diffusion, or
            actions relative to the pose at the chunk's start: ``tool_rel``, a mobile base).
    """
    able = info.policy_type == "diffusion" and info.action != "tool_rel" and not is_mobile(info)
    if setting is None:
        return ENSEMBLE_K if able else None
    if setting < 0:
        return None
    if not able:
        raise PolicyError(
            f"eval.ensemble={setting}: temporal ensembling needs a diffusion policy with absolute "
            f"actions; {info.name} is {info.policy_type} with train.action={info.action}"
            f"{' on a mobile robot' if is_mobile(info) else ''}: set eval.ensemble=-1"
        )
    return float(setting)


def is_mobile(info: TrainInfo) -> bool:
    """Whether the policy drives the mobile robot's base (its actions are relative to it)."""
    from factory.tasks.mobile_pick_place.dataset import SUBTASK_KEY

    return SUBTASK_KEY in info.features


class ChunkEnsemble:
    """Temporal ensembling of a lerobot diffusion policy (ACT's, on diffusion chunks): a new
    chunk of ``horizon - n_obs_steps + 1`` actions is predicted every frame and the frame's
    action is the weighted mean of every kept chunk's prediction for it, weights
    ``exp(-k * age)`` with the oldest chunk first, so the plan the policy committed to steers
    and a new sample cannot jump to another grasp between chunks.

    Args:
        policy: a lerobot ``DiffusionPolicy`` (its ``config.n_action_steps`` is set to the
            chunk's full length, so call this before its ``reset``).
        k: the weights' decay per kept chunk (0: plain mean).
        every: a new chunk every ``every`` frames (1: every frame); the frames between take
            the weighted mean of the chunks kept, so inference runs ``every`` times less.
    """

    def __init__(self, policy: Any, k: float, every: int = 1) -> None:
        cfg = policy.config
        cfg.n_action_steps = cfg.horizon - cfg.n_obs_steps + 1
        if every < 1 or every > cfg.n_action_steps:
            raise PolicyError(
                f"eval.ensemble_every={every}: a new chunk every 1 to {cfg.n_action_steps} "
                "frames (the chunk's length)"
            )
        self.policy = policy
        self.k = float(k)
        self.every = int(every)
        self._chunks: list[tuple[int, Any]] = []
        self._t = 0

    def reset(self) -> None:
        """New episodes: forget the kept chunks."""
        self._chunks.clear()
        self._t = 0

    def select_action(self, batch: dict[str, Any]) -> Any:
        """The next actions (n, A) (the model's normalised actions) for the preprocessed
        observations of one frame; updates the policy's observation queues."""
        import torch
        from lerobot.policies.utils import populate_queues
        from lerobot.utils.constants import OBS_IMAGES

        p = self.policy
        batch = {k: v for k, v in batch.items() if k != "action"}
        if p.config.image_features:  # lerobot's select_action: the cameras as one key first
            batch[OBS_IMAGES] = torch.stack([batch[k] for k in p.config.image_features], dim=-4)
        p._queues = populate_queues(p._queues, batch)
        if self._t % self.every == 0 or not self._chunks:
            chunk = p.predict_action_chunk(batch)  # (n, steps, A)
            self._chunks.append((self._t, chunk))
        self._chunks = [(t, c) for t, c in self._chunks if self._t - t < c.shape[1]]
        preds = torch.stack([c[:, self._t - t] for t, c in self._chunks])  # oldest first
        w = torch.exp(-self.k * torch.arange(len(preds), dtype=preds.dtype, device=preds.device))
        self._t += 1
        return (w[:, None, None] * preds).sum(0) / w.sum()


ACT_PARTS = ("convert_s", "perception_s", "policy_s", "ik_s")
"""Where :meth:`LoadedPolicy.act`'s time goes (s): the observation converted to model inputs
(with a perception network on a GPU, the images' bytes copied there); the perception network
(to its positions back on the host); the preprocessor, the diffusion's chunk (or the queued
action) and the postprocessor, to actions on the host; the tool actions' IK."""


class LoadedPolicy:
    """A trained policy ready to act in the env: every conversion the training applied.

    Attributes:
        info: what it was trained on.
        path: its ``pretrained_model`` folder.
        device: the torch device it runs on.
        ensemble: the temporal ensembling weight ``k`` (:class:`ChunkEnsemble`), or None: the
            policy's own chunks, ``n_action_steps`` actions of each.
    """

    def __init__(
        self,
        info: TrainInfo,
        path: Path,
        policy: Any,
        preprocessor: Any,
        postprocessor: Any,
        device: str,
        ensemble: float | None = None,
        ensemble_every: int = 1,
    ) -> None:
        from factory.policy.inputs import ToolActionTracker, spec_from_features

        self.info = info
        self.path = path
        self.device = device
        self.spec = spec_from_features(
            info.inputs, info.features, info.depth_max_m, info.action, info.vision == "perception"
        )
        self.perception: Any = None
        """The perception network (``train.vision=perception``), set by :func:`load_policy`."""
        self._tracker = ToolActionTracker() if info.action != "joint" else None
        self._origin: np.ndarray | None = None
        self._base_origin: np.ndarray | None = None
        self._policy = policy
        self._pre = preprocessor
        self._post = postprocessor
        self._checked = False
        self.ensemble = ensemble
        self.ensemble_every = ensemble_every if ensemble is not None else 1
        self._ensemble = (
            ChunkEnsemble(policy, ensemble, ensemble_every) if ensemble is not None else None
        )
        if self._ensemble is not None:
            policy.reset()  # the queues of the longer chunks
        self.act_times: dict[str, float] = dict.fromkeys(ACT_PARTS, 0.0)
        """Seconds of :meth:`act` by part since :meth:`take_act_times` (see :data:`ACT_PARTS`)."""

    def take_act_times(self) -> dict[str, float]:
        """:attr:`act_times` (s, rounded to ms), then zeroed."""
        out = {k: round(v, 3) for k, v in self.act_times.items()}
        self.act_times = dict.fromkeys(ACT_PARTS, 0.0)
        return out

    @property
    def policy(self) -> Any:
        """The lerobot policy (``PreTrainedPolicy``)."""
        return self._policy

    def reset(self) -> None:
        """Starts new episodes: clears the policy's observation and action queues."""
        self._policy.reset()
        if self._ensemble is not None:
            self._ensemble.reset()
        if self._tracker is not None:
            self._tracker.reset()
        self._origin = self._base_origin = None

    def read_objects(self, batch: dict[str, Any], obs: Mapping[str, np.ndarray]) -> Any:
        """The perception network's environment values (n, 24) float32 on the CPU (the objects'
        poses in the arm's base frame, :func:`~factory.policy.inputs.env_features`' units),
        read from the converted observations ``batch``
        (:func:`~factory.policy.inputs.convert_observation`) of the raw ones ``obs``, whose
        robot state and camera calibration give the point cameras' poses."""
        import torch

        from factory.policy.perception import camera_stack

        net = self.perception
        images = camera_stack(batch, net.cameras, net.depth)
        poses = None
        if net.xyz:  # the point cameras' poses: kinematics, calibration
            from factory.policy.inputs import CAMERA_POSES
            from factory.policy.perception import camera_poses

            got = camera_poses(
                net.point_cameras,
                obs["observation.state"],
                obs.get(CAMERA_POSES),
                net.pose_cameras,
            )
            poses = torch.from_numpy(got).to(self.device)
        with torch.inference_mode():
            return net.predict(images.to(self.device), poses).float().to("cpu")

    def act(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Actions for a batch of observations.

        Args:
            obs: the env's observations, keyed like the dataset's features, each with a
                leading batch axis ``n`` and the contract's raw dtypes (uint8 (n, H, W, 3)
                images, uint16 (n, H, W) millimetres of depth, float32 vectors).

        Returns:
            (n, 8) float32: desired arm joints (rad) + gripper command (m); a mobile policy's
            (n, 11) add the base target x, y (m, world) and yaw (rad).

        Raises:
            PolicyError: the observations lack a feature the policy reads or have other shapes.
        """
        import torch

        from factory.policy.inputs import (
            BASE_DIM,
            BASE_RAW,
            TOOL_POS,
            base_absolute,
            convert_observation,
        )

        if not self._checked:
            check_features(self.info, obs, {k: np.shape(v)[1:] for k, v in obs.items()})
            self._checked = True
        clock, times = time.perf_counter, self.act_times
        t0 = clock()
        # a perception network reads the images on its device: the raw bytes go there
        on = self.device if self.perception is not None and self.device != "cpu" else None
        batch = convert_observation(self.spec, obs, on)
        t1 = clock()
        times["convert_s"] += t1 - t0
        if self.perception is not None:  # the object poses read from the cameras
            env = self.read_objects(batch, obs)
            for k in self.spec.visual_keys():
                del batch[k]
            if self.spec.mobile:  # the sub-task one-hot follows the predicted values
                env = torch.cat([env, batch["observation.environment_state"]], -1)
            batch["observation.environment_state"] = env
        t2 = clock()
        times["perception_s"] += t2 - t1
        with torch.inference_mode():
            if chunk_starts(self._policy):
                # this chunk's positions are relative to the tool's position now, its base
                # targets to the base pose now (as the training's chunk_actions)
                if self.spec.action == "tool_rel":
                    self._origin = batch["observation.state"][:, TOOL_POS].numpy().copy()
                if self.spec.mobile:
                    state = np.asarray(obs["observation.state"], np.float64)
                    self._base_origin = state[:, BASE_RAW].copy()
            batch = self._pre(batch)
            if self._ensemble is not None:
                action = self._ensemble.select_action(batch)
            else:
                action = self._policy.select_action(batch)
            action = self._post(action)
        out = np.asarray(action.detach().to("cpu").numpy(), np.float32)
        out = out.reshape(-1, self.spec.action_dim)
        t3 = clock()
        times["policy_s"] += t3 - t2
        if self.spec.mobile:
            assert self._base_origin is not None
            base = base_absolute(out[:, -BASE_DIM:], self._base_origin)
            out[:, -BASE_DIM:] = base.astype(np.float32)
        if self._tracker is not None:
            origin = self._origin if self.spec.action == "tool_rel" else None
            arm = self._tracker.joints(out[:, :10], np.asarray(obs["observation.state"]), origin)
            times["ik_s"] += clock() - t3
            if self.spec.mobile:  # the base target follows the arm's columns as predicted
                return np.concatenate([arm, out[:, 10:]], axis=1).astype(np.float32)
            return arm
        return out


def chunk_starts(policy: Any) -> bool:
    """Whether the policy's next ``select_action`` predicts a new action chunk (its queue of
    actions is empty: lerobot's diffusion ``_queues["action"]``, ACT's ``_action_queue``); a
    policy without a queue predicts at every step."""
    queues = getattr(policy, "_queues", None)
    if isinstance(queues, dict) and "action" in queues:
        return len(queues["action"]) == 0
    queue = getattr(policy, "_action_queue", None)
    if queue is not None:
        return len(queue) == 0
    return True


def _check_mobile_layout(info: TrainInfo, cfg: Any, path: Path) -> None:
    """Refuses a mobile policy trained on the earlier model inputs (the base pose's raw yaw in a
    20-wide state, world base targets), which this factory's conversions no longer produce.

    Raises:
        PolicyError: names the retraining.
    """
    from factory.policy.inputs import MOBILE_ROBOT_DIM
    from factory.tasks.mobile_pick_place.dataset import SUBTASK_KEY

    if SUBTASK_KEY not in info.features:
        return
    feat = cfg.input_features.get("observation.state")
    width = int(feat.shape[0]) if feat is not None else MOBILE_ROBOT_DIM
    if width != MOBILE_ROBOT_DIM:
        raise PolicyError(
            f"{path} is a mobile policy with a {width}-wide observation.state, trained before "
            f"the base heading became cos/sin and the base action relative ({MOBILE_ROBOT_DIM} "
            "wide): retrain it with stage=train"
        )


def load_policy(
    ref: str,
    run_dir: Path | None,
    device: str = "auto",
    ensemble: float | None = -1.0,
    ensemble_every: int = 1,
) -> LoadedPolicy:
    """Loads a trained policy with lerobot's ``from_pretrained`` and its processors.

    Args:
        ref: a policy name under ``run_dir/policy/<name>/`` (its newest checkpoint) or a path
            (a lerobot ``pretrained_model`` folder written by ``stage=train``, a checkpoint or a
            ``policy/<name>`` folder).
        run_dir: the run directory names are looked up in (None: paths only).
        device: ``auto`` (CUDA when present), ``cpu``, ``cuda``.
        ensemble: temporal ensembling (``eval.ensemble``, :func:`resolve_ensemble`): None
            (on where it applies), negative (off: the policy's own chunks) or its ``k``.
        ensemble_every: with ensembling, a new chunk every this many frames
            (``eval.ensemble_every``).

    Raises:
        PolicyError: nothing loadable, not written by ``stage=train``, or unreadable; an
            ensembling the policy cannot do.
    """
    path = resolve_ref(ref, run_dir)
    info_path = path / INFO_IN_MODEL
    if not info_path.is_file():
        raise PolicyError(
            f"{path} has no {INFO_IN_MODEL}: it was not trained by stage=train, so its inputs "
            "are unknown; train one with stage=train"
        )
    info = read_info(info_path)
    k = resolve_ensemble(ensemble, info)
    dev = resolve_device(device)
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    try:
        with quiet_stdout():
            cfg = PreTrainedConfig.from_pretrained(path)
            cfg.device = dev
            policy = get_policy_class(cfg.type).from_pretrained(path, config=cfg)
            pre, post = make_pre_post_processors(
                cfg,
                pretrained_path=str(path),
                preprocessor_overrides={"device_processor": {"device": dev}},
            )
    except (OSError, ValueError, KeyError, RuntimeError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise PolicyError(
            f"cannot load the policy in {path}: {msg} (retrain with stage=train)"
        ) from None
    _check_mobile_layout(info, cfg, path)
    policy.to(dev)
    policy.eval()
    policy.reset()
    perception = None
    if info.vision == "perception":
        from factory.policy.perception import load as load_perception

        perception = load_perception(path, dev)
    log.info(
        "loaded policy %s (%s, inputs=%s, %d steps) from %s on %s%s",
        info.name,
        info.policy_type,
        info.inputs,
        info.steps,
        path,
        dev,
        ""
        if k is None
        else f", temporal ensembling k={k:g}"
        + (f", a chunk every {ensemble_every} frames" if ensemble_every > 1 else ""),
    )
    loaded = LoadedPolicy(info, path, policy, pre, post, dev, k, ensemble_every)
    loaded.perception = perception
    return loaded
