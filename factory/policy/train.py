"""Training a lerobot policy on a merged factory dataset, with lerobot's own pieces.

* the policy config class by type name from lerobot's registry
  (``PreTrainedConfig.get_choice_class``), its input features set from
  :mod:`factory.policy.inputs`, ``make_policy`` and ``make_pre_post_processors`` with the
  statistics of the converted features;
* ``LeRobotDataset(root=..., delta_timestamps=...)`` from the policy config's
  ``observation_delta_indices`` / ``action_delta_indices``, decoded with PyAV, with lerobot's
  ``EpisodeAwareSampler`` where the policy drops episode ends (diffusion);
* the policy's optimizer and scheduler presets (``make_optimizer_and_scheduler``);
* lerobot's ``save_checkpoint`` / ``load_training_state`` for ``checkpoints/<step>/``
  (``pretrained_model`` + ``training_state``), written aside and renamed into place;
* lerobot's ``ImageTransforms`` on the RGB images when ``train.augment_images`` is on (never on
  depth; without its affine transform when depth is read, which would move RGB off depth),
  and a random crop to 90 % for policies that have one (diffusion's ``crop_shape``).

One private touch of lerobot: the loaded dataset's ``meta.info["features"]`` loses the video
features the policy does not read, because ``LeRobotDataset.__getitem__`` decodes every video
feature of a frame (a state policy would decode six videos per sample for nothing).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import PolicyError
from factory.policy.aux_state import AUX_TARGET
from factory.policy.checkpoint import (
    CHECKPOINTS,
    INFO_IN_MODEL,
    PRETRAINED,
    TRAIN_LOG,
    TRAINING_STATE,
    TrainInfo,
    checkpoint_step,
    prune_checkpoints,
    publish_checkpoint,
    quiet_stdout,
    write_train_json,
)
from factory.policy.inputs import (
    ACTION,
    BASE_RAW,
    CAMERA_POSES,
    DEPTH_PREFIX,
    EE_POSE,
    ENV_STATE,
    STATE,
    SUBTASK_KEY,
    InputSpec,
    chunk_actions,
    convert_sample,
    depth_image,
    env_features,
    model_actions,
    state_features,
)
from factory.policy.perception import CAMERA_POSE, camera_poses, point_cameras_of
from factory.policy.recipe import (
    STATE_DIFFUSION_DEFAULTS,
    STATE_DIFFUSION_LR,
    default_lr,
    diffusion_defaults,
    resolve_aux_state,
    resolve_compile,
    resolve_ema,
    resolve_precision,
)

__all__ = ["STATE_DIFFUSION_DEFAULTS", "STATE_DIFFUSION_LR", "Trainer", "train"]

log = logging.getLogger(__name__)

DEPTH_STATS_SAMPLES = 64
"""Frames decoded to measure the statistics of the converted depth images."""
CROP_RATIO = 0.9
"""Random crop (training) / centre crop (acting) of image policies with a ``crop_shape``."""
OFFLINE_DEFAULTS: dict[str, Any] = {"pretrained_backbone_weights": None, "push_to_hub": False}
"""Policy config fields set unless ``train.options`` says otherwise: no downloads (ACT would
fetch ImageNet weights), nothing pushed."""
PERCEPTION_STATE = "perception_optimizer.pt"
"""In a checkpoint's ``training_state``: the perception network's optimizer and schedule."""
EXTRAS = "factory_extras.safetensors"
"""In a checkpoint's ``training_state``: what lerobot's format has no place for: the raw
weights where ``pretrained_model`` holds their average (``raw.<i>``, the policy's trained
parameters in order), the auxiliary head (``aux.<name>``) and the average's update count."""


# ---- the lerobot policy config


def known_policy_types() -> list[str]:
    """Every policy type lerobot's registry knows."""
    import lerobot.policies.factory  # noqa: F401  (imports and so registers every config)
    from lerobot.configs.policies import PreTrainedConfig

    return sorted(PreTrainedConfig.get_known_choices())


def policy_config(tc: Any, spec: InputSpec, device: str) -> Any:
    """The lerobot config of ``train.policy`` for these inputs.

    Settings: ``train.horizon`` (the config's ``horizon``, or ``chunk_size`` for chunking
    policies such as ACT), ``train.n_obs_steps``, ``train.n_action_steps`` (0: the policy's
    default), ``train.options.<type>`` (any field of the config), :data:`OFFLINE_DEFAULTS`,
    the diffusion recipe of the inputs (:func:`factory.policy.recipe.diffusion_defaults`).

    Raises:
        PolicyError: an unknown type (the available ones listed), an unknown option, or values
            the config rejects.
    """
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature

    known = known_policy_types()
    if tc.policy not in known:
        raise PolicyError(f"unknown train.policy {tc.policy!r}: lerobot has {', '.join(known)}")
    cls = PreTrainedConfig.get_choice_class(tc.policy)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {k: v for k, v in OFFLINE_DEFAULTS.items() if k in fields}
    if tc.policy == "diffusion":  # a perception policy's lerobot part is a state policy
        recipe = diffusion_defaults(spec.inputs, spec.perception)
        kwargs.update({k: v for k, v in recipe.items() if k in fields})
    if tc.horizon > 0:
        key = "horizon" if "horizon" in fields else "chunk_size" if "chunk_size" in fields else ""
        if not key:
            raise PolicyError(f"train.horizon: policy {tc.policy} has no horizon or chunk_size")
        kwargs[key] = tc.horizon
    for key in ("n_obs_steps", "n_action_steps"):
        value = getattr(tc, key)
        if value > 0:
            if key not in fields:
                raise PolicyError(f"train.{key}: policy {tc.policy} has no such setting")
            kwargs[key] = value
    options = dict((tc.options or {}).get(tc.policy, {}) or {})
    unknown = sorted(k for k in options if k not in fields)
    if unknown:
        raise PolicyError(
            f"train.options.{tc.policy}: {', '.join(unknown)} not a field of {cls.__name__} "
            "(see lerobot's configuration_*.py)"
        )
    for k, v in options.items():
        kwargs[k] = tuple(v) if isinstance(v, list) else v
    kwargs["device"] = device
    try:
        cfg = cls(**kwargs)
    except (ValueError, TypeError, NotImplementedError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise PolicyError(f"train.policy={tc.policy} rejects these settings: {msg}") from None
    types = {STATE: FeatureType.STATE, ENV_STATE: FeatureType.ENV}
    cfg.input_features = {
        k: PolicyFeature(types.get(k, FeatureType.VISUAL), tuple(shape))
        for k, shape in spec.model_features().items()
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (spec.action_dim,))}
    # object poses are normalised like the robot state (lerobot leaves ENV as it is)
    mapping = dict(cfg.normalization_mapping)
    mapping.setdefault("ENV", mapping.get("STATE", NormalizationMode.MIN_MAX))
    cfg.normalization_mapping = mapping
    h, w = spec.image_size
    if (
        tc.augment_images
        and not spec.perception
        and spec.cameras
        and getattr(cfg, "crop_shape", "absent") is None
        and getattr(cfg, "resize_shape", None) is None
        and "crop_shape" not in options
    ):
        cfg.crop_shape = (int(h * CROP_RATIO), int(w * CROP_RATIO))
    try:
        cfg.validate_features()
    except (ValueError, TypeError) as e:
        raise PolicyError(f"train.policy={tc.policy} cannot use these inputs: {e}") from None
    return cfg


# ---- data


class LowDimFrames:
    """The converted low-dimensional features of every frame, gathered like lerobot gathers
    them (``LeRobotDataset.__getitem__``: delta indices clamped to the episode, ``*_is_pad``
    masks), without its per-sample cost.

    ``LeRobotDataset.__getitem__`` spends about 11 ms per sample in Hugging Face ``datasets``
    (a copy of the features per column query), more than a small state policy's step; here
    the columns of the loaded ``hf_dataset`` are read once, converted once (the forward
    kinematics of every frame) and indexed with numpy. ``tests/policy/test_train.py`` checks
    that both give the same samples.
    """

    def __init__(
        self,
        base: Any,
        spec: InputSpec,
        videos: dict[str, np.ndarray] | None = None,
        aux: bool = False,
        points: bool = True,
    ) -> None:
        self.spec = spec
        self.videos = videos or {}
        table = base.hf_dataset.data
        index = np.asarray(table.column("index").to_numpy(), np.int64)
        if not np.array_equal(index, np.arange(len(index))):
            raise PolicyError(
                f"{base.root}: frames are not in index order: re-run stage=dataset force=true"
            )

        def column(key: str) -> np.ndarray:
            return np.stack(table.column(key).to_numpy(zero_copy_only=False)).astype(np.float32)

        state = column(STATE)
        # mobile: the dataset's base pose per frame (x, y m, yaw rad), the actions' origin
        self.base_pose = state[:, BASE_RAW] if spec.mobile else None
        self.values: dict[str, np.ndarray] = {
            STATE: state_features(spec, state),
            ACTION: model_actions(column(ACTION), spec.action),
        }
        if spec.mobile:  # the sub-task one-hot, after the object values where read
            ee, env = (column(EE_POSE), column(ENV_STATE)) if spec.mobile_poses else (None, None)
            self.values[ENV_STATE] = spec.mobile_env(column(SUBTASK_KEY), state, ee, env)
        elif spec.inputs == "state" or spec.perception:
            self.values[ENV_STATE] = spec.env_model(state, column(EE_POSE), column(ENV_STATE))
        if aux:  # the auxiliary target: the environment state of the sample's frame
            self.values[AUX_TARGET] = env_features(state, column(EE_POSE), column(ENV_STATE))
        self.episode = np.asarray(table.column("episode_index").to_numpy(), np.int64)
        eps = base.meta.episodes
        self.start = {
            int(e): int(f)
            for e, f in zip(eps["episode_index"], eps["dataset_from_index"], strict=True)
        }
        self.end = {
            int(e): int(t)
            for e, t in zip(eps["episode_index"], eps["dataset_to_index"], strict=True)
        }
        self.delta: dict[str, list[int]] = dict(base.delta_indices or {})
        if spec.mobile and SUBTASK_KEY in self.delta:  # the one-hot is read at its frames
            self.delta[ENV_STATE] = self.delta[SUBTASK_KEY]
        self.point_cameras: list[str] = []
        """The perception's cameras whose pixels become points (``train.perception_points``)."""
        if spec.perception and points:
            self.point_cameras = point_cameras_of(spec.cameras, spec.depth, spec.pose_cameras)
        if self.point_cameras:
            # each point camera's pose and field of view at each frame: the wrist camera's by
            # forward kinematics of the joints, the others' from the recorded calibration
            calib = column(CAMERA_POSES) if spec.pose_cameras else None
            self.values[CAMERA_POSE] = camera_poses(
                self.point_cameras, state, calib, spec.pose_cameras
            )
        if spec.perception:  # the poses at the robot state's frames; the cameras' newest only
            if STATE in self.delta:
                self.delta[ENV_STATE] = self.delta[STATE]
            for key in spec.visual_keys():
                self.delta.pop(key, None)
        self.raw_keys = list(spec.raw_features())

    def __len__(self) -> int:
        return len(self.episode)

    def item(self, idx: int) -> dict[str, Any]:
        import torch

        ep = int(self.episode[idx])
        start, end = self.start[ep], self.end[ep]
        out: dict[str, Any] = {}
        for key, values in self.values.items():
            delta = self.delta.get(key)
            if delta is None:
                out[key] = torch.from_numpy(values[idx])
                continue
            q = idx + np.asarray(delta)
            out[key] = torch.from_numpy(values[np.clip(q, start, end - 1)])
        if self.spec.action == "tool_rel" or self.spec.mobile:
            base = None if self.base_pose is None else self.base_pose[idx]
            act = chunk_actions(self.spec, out[ACTION].numpy(), self.values[STATE][idx], base)
            out[ACTION] = torch.from_numpy(act)
        for key, frames in self.videos.items():
            delta = self.delta.get(key)
            at = idx if delta is None else np.clip(idx + np.asarray(delta), start, end - 1)
            pix = torch.from_numpy(np.ascontiguousarray(frames[at]))
            if key.startswith(DEPTH_PREFIX):
                out[key] = depth_image(pix.to(torch.int32), self.spec.depth_max_m)
            else:
                out[key] = pix.movedim(-1, -3).to(torch.float32) / 255.0
        for key in [*self.raw_keys, ACTION]:
            if key in self.delta:
                q = idx + np.asarray(self.delta[key])
                out[f"{key}_is_pad"] = torch.from_numpy((q < start) | (q >= end))
        return out


class TrainSet:
    """A ``LeRobotDataset`` whose samples are converted to the model's inputs (a torch map-style
    dataset: ``len`` and ``[i]``), with RGB augmentation when given.

    Policies without images, and image policies whose videos were decoded into memory
    (``train.video_cache``, :mod:`factory.policy.video_frames`), read :class:`LowDimFrames`;
    other image policies read ``LeRobotDataset.__getitem__`` (video decoding dominates there)
    and convert the sample.
    """

    def __init__(
        self,
        base: Any,
        spec: InputSpec,
        augment: Any = None,
        videos: dict[str, np.ndarray] | None = None,
        aux: bool = False,
        points: bool = True,
    ) -> None:
        self.base = base
        self.spec = spec
        self.augment = augment
        self.videos = videos
        cached = not spec.cameras or videos is not None
        self.frames = LowDimFrames(base, spec, videos, aux, points) if cached else None

    def __len__(self) -> int:
        return len(self.base)

    def __getitem__(self, idx: int) -> dict[str, Any]:
        if self.frames is not None:
            out = self.frames.item(idx)
        else:
            out = convert_sample(self.spec, self.base[idx])
            if out[STATE].ndim == 2:  # lerobot squeezes a one-frame video window: restore it
                for k in self.spec.visual_keys():
                    if out[k].ndim == 3:
                        out[k] = out[k][None]
        if self.augment is not None:
            for k in self.spec.image_keys():
                out[k] = self.augment(out[k])
        return out


def delta_timestamps(cfg: Any, spec: InputSpec, fps: float) -> dict[str, list[float]] | None:
    """lerobot's delta timestamps (s) of every feature read, from the policy's delta indices."""
    out: dict[str, list[float]] = {}
    obs = cfg.observation_delta_indices
    if obs is not None:
        for k in spec.raw_features():
            if k != CAMERA_POSES:  # the perception reads the calibration of the frame only
                out[k] = [i / fps for i in obs]
    act = cfg.action_delta_indices
    if act is not None:
        out[ACTION] = [i / fps for i in act]
    return out or None


def open_dataset(
    root: Path,
    spec: InputSpec,
    cfg: Any,
    augment: bool,
    video_cache: str = "off",
    aux: bool = False,
    points: bool = True,
    shading: float = 0.0,
) -> tuple[Any, TrainSet]:
    """The ``LeRobotDataset`` (videos the policy reads only) and its converted view.

    Args:
        shading: strength of the RGB images' shading augmentation (``train.augment_shading``,
            :class:`~factory.policy.shading.SampleShading`; 0: off).
        aux: the samples hold the auxiliary target (:data:`AUX_TARGET`) where the frames are
            in memory (the trainer drops the auxiliary loss otherwise).
        points: a perception policy's samples hold its point cameras' poses
            (``train.perception_points``: the wrist camera's, and those of the cameras whose
            calibration the spec reads, :attr:`~factory.policy.inputs.InputSpec.pose_cameras`).
        video_cache: ``memory`` decodes the videos the policy reads into memory once
            (:func:`~factory.policy.video_frames.decode_videos`), ``auto`` does so when they take
            less than half of the available memory, ``off`` decodes per sample (lerobot).
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    info = json.loads((root / "meta" / "info.json").read_text())
    base = LeRobotDataset(
        "factory/demos",
        root=root,
        delta_timestamps=delta_timestamps(cfg, spec, float(info["fps"])),
        video_backend="pyav",
    )
    keep = set(spec.visual_keys())
    feats = base.meta.info["features"]
    for k in [k for k, f in feats.items() if f["dtype"] in ("video", "image") and k not in keep]:
        del feats[k]
    transforms = None
    if augment and spec.cameras:
        from lerobot.datasets.transforms import ImageTransforms, ImageTransformsConfig

        tcfg = ImageTransformsConfig(enable=True)
        if spec.depth:
            # the affine transform would move the RGB image and not its depth image: a depth
            # pixel would no longer lie under its colour (the perception reads both)
            tcfg.tfs.pop("affine", None)
            tcfg.max_num_transforms = min(tcfg.max_num_transforms, len(tcfg.tfs))
        transforms = ImageTransforms(tcfg)
    if shading > 0 and spec.cameras:
        from factory.policy.shading import SampleShading

        transforms = SampleShading(shading, transforms)
    videos = None
    keys = spec.visual_keys()
    if keys and video_cache != "off":
        from factory.policy.video_frames import available_bytes, decode_videos, frame_bytes

        need = frame_bytes(keys, spec.image_size) * base.num_frames
        have = available_bytes()
        if video_cache == "memory" or need < have // 2:
            t0 = time.perf_counter()
            videos = decode_videos(base, keys)
            log.info(
                "train: %d video streams decoded into memory (%.1f GB) in %.1f s",
                len(keys),
                need / 1e9,
                time.perf_counter() - t0,
            )
        else:
            log.info(
                "train: decoding video per sample: the frames need %.1f GB, %.1f GB available "
                "(train.video_cache=memory forces the cache)",
                need / 1e9,
                have / 1e9,
            )
    if keys and videos is None:
        _check_per_sample_decoding()
    return base, TrainSet(base, spec, transforms, videos, aux, points)


def _check_per_sample_decoding() -> None:
    """Refuses per-sample video decoding where lerobot's ``pyav`` backend cannot run: it reads
    through ``torchvision.io.VideoReader``, which newer torchvision releases no longer have
    (the GPU machine's); the factory's own decoder (``train.video_cache``) needs only PyAV.

    Raises:
        PolicyError: names the setting that avoids it.
    """
    import torchvision

    if not hasattr(torchvision.io, "VideoReader"):
        raise PolicyError(
            f"decoding the videos per sample needs torchvision.io.VideoReader, which torchvision "
            f"{torchvision.__version__} lacks: set train.video_cache=memory (every frame decoded "
            "once with PyAV)"
        )


def _low_dim(
    root: Path, keys: list[str], episodes: list[int] | None = None
) -> dict[str, np.ndarray]:
    """Columns ``keys`` of every frame (of ``episodes`` only, when given), float32."""
    import pyarrow.parquet as pq

    files = sorted((root / "data").glob("*/*.parquet"))
    parts: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    wanted = None if episodes is None else np.asarray(sorted(episodes), np.int64)
    for f in files:
        table = pq.read_table(f, columns=[*keys, "episode_index"])
        keep = None
        if wanted is not None:
            ep = np.asarray(table.column("episode_index").to_numpy(), np.int64)
            keep = np.isin(ep, wanted)
        for k in keys:
            col = np.stack(table.column(k).to_numpy(zero_copy_only=False))
            parts[k].append(col if keep is None else col[keep])
    return {k: np.concatenate(v).astype(np.float32) for k, v in parts.items()}


def relative_action_rows(
    base: Any, spec: InputSpec, trainset: TrainSet, episodes: list[int] | None
) -> np.ndarray:
    """Every action a training sample holds (``tool_rel`` or mobile): for each frame of the
    episodes trained on and each step of the action window (clamped to the episode, as
    sampled), the model's action relative to that frame (:func:`chunk_actions`: the tool
    position relative to that frame's, the base target relative to that frame's base pose):
    (frames x window, A)."""
    import dataclasses as dc

    frames = trainset.frames or LowDimFrames(base, dc.replace(spec, cameras=()))
    idx = np.arange(len(frames.episode))
    if episodes is not None:
        idx = idx[np.isin(frames.episode, episodes)]
    delta = np.asarray(frames.delta.get(ACTION, [0]))
    start = np.array([frames.start[int(e)] for e in frames.episode[idx]])
    end = np.array([frames.end[int(e)] for e in frames.episode[idx]])
    q = np.clip(idx[:, None] + delta[None, :], start[:, None], end[:, None] - 1)
    act = frames.values[ACTION][q]  # (N, H, A) absolute model actions
    base = None if frames.base_pose is None else frames.base_pose[idx]
    rel = chunk_actions(spec, act, frames.values[STATE][idx], base)
    return rel.reshape(-1, rel.shape[-1])


def model_stats(
    spec: InputSpec,
    root: Path,
    base: Any,
    trainset: TrainSet,
    episodes: list[int] | None = None,
) -> dict[str, Any]:
    """Normalisation statistics of the model's inputs and the action (lerobot's layout:
    feature -> {min, max, mean, std, count, q01, ...}).

    The converted robot and environment states and the action are measured over every frame
    trained on (``episodes``: those episodes only), the RGB images' come from the dataset's own
    statistics (all its episodes), the depth images' from :data:`DEPTH_STATS_SAMPLES` decoded
    frames of the episodes trained on.
    """
    from lerobot.datasets.compute_stats import get_feature_stats

    keys = [STATE, EE_POSE, ACTION]
    if spec.mobile:
        keys.append(SUBTASK_KEY)
    if spec.mobile_poses or (not spec.mobile and (spec.inputs == "state" or spec.perception)):
        keys.append(ENV_STATE)
    rows = _low_dim(root, keys, episodes)
    if spec.action == "tool_rel" or spec.mobile:
        actions = relative_action_rows(base, spec, trainset, episodes)
    else:
        actions = model_actions(rows[ACTION], spec.action)
    stats: dict[str, Any] = {
        STATE: get_feature_stats(state_features(spec, rows[STATE]), axis=0, keepdims=False),
        ACTION: get_feature_stats(actions, axis=0, keepdims=False),
    }
    if spec.mobile:
        ee, env = (rows[EE_POSE], rows[ENV_STATE]) if spec.mobile_poses else (None, None)
        values = spec.mobile_env(rows[SUBTASK_KEY], rows[STATE], ee, env)
        stats[ENV_STATE] = get_feature_stats(values, axis=0, keepdims=False)
    elif spec.inputs == "state" or spec.perception:
        env = spec.env_model(rows[STATE], rows[EE_POSE], rows[ENV_STATE])
        stats[ENV_STATE] = get_feature_stats(env, axis=0, keepdims=False)
    if spec.perception:  # the lerobot policy reads no images (the perception network does)
        return stats
    for k in spec.image_keys():
        stats[k] = {s: np.asarray(v) for s, v in base.meta.stats[k].items()}
    depth_keys = spec.depth_keys()
    if depth_keys:
        import torch

        pool = np.arange(len(base))
        if episodes is not None:
            eps = base.meta.episodes
            pool = np.concatenate(
                [
                    np.arange(int(eps["dataset_from_index"][e]), int(eps["dataset_to_index"][e]))
                    for e in episodes
                ]
            )
        n = len(pool)
        pick = np.linspace(0, n - 1, min(n, DEPTH_STATS_SAMPLES)).round().astype(int)
        idx = pool[np.unique(pick)]
        frames: dict[str, list[Any]] = {k: [] for k in depth_keys}
        plain = TrainSet(base, spec, None, trainset.videos)
        for i in idx:
            item = plain[int(i)]
            for k in depth_keys:
                frames[k].append(item[k].reshape(-1, *item[k].shape[-3:]))
        for k in depth_keys:
            arr = torch.cat(frames[k]).numpy()
            st = get_feature_stats(arr, axis=(0, 2, 3), keepdims=True)
            stats[k] = {s: (v.reshape(3, 1, 1) if s != "count" else v) for s, v in st.items()}
    return stats


def model_meta(meta: Any, spec: InputSpec) -> Any:
    """The dataset's metadata as the model sees it: ``make_policy`` takes the action's shape
    from the dataset's features, so a ``tool`` action (10,) needs a copy that says so."""
    import copy

    if spec.action_dim == int(meta.features[ACTION]["shape"][0]):
        return meta
    out = copy.copy(meta)
    out.info = copy.deepcopy(meta.info)
    out.info["features"][ACTION]["shape"] = [spec.action_dim]
    names = out.info["features"][ACTION].get("names")
    if names is not None:
        out.info["features"][ACTION]["names"] = [
            *(f"tool_{k}" for k in ("x", "y", "z", "r11", "r21", "r31", "r12", "r22", "r32")),
            "gripper",
            *(["base_x", "base_y", "base_yaw"] if spec.mobile else []),
        ]
    return out


# ---- the loop


@dataclass
class TrainResult:
    """What a call of :func:`train` did.

    Attributes:
        step: the last step done (== ``train.steps`` when finished).
        resumed_from: the checkpoint's step it started from (0: from scratch).
        loss: mean loss of the last logged interval.
        seconds: wall seconds of this call's optimizer steps.
        steps_per_s: optimizer steps per second in this call (data loading included).
        checkpoint: the newest checkpoint folder.
    """

    step: int
    resumed_from: int
    loss: float
    seconds: float
    steps_per_s: float
    checkpoint: str


def _read_log(path: Path, upto: int) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except ValueError:
            continue  # a line cut by a kill
        if int(rec.get("step", 0)) <= upto:
            out.append(rec)
    return out


COMPILED = ("rgb_encoder", "unet")
"""Modules of a diffusion policy that ``train.compile`` compiles."""
COMPILE_BACKEND = "inductor"
"""``torch.compile`` backend of ``train.compile`` (tests trace with ``aot_eager``)."""


def _compile_modules(policy: Any) -> list[str]:
    """Compiles :data:`COMPILED` of ``policy`` in place (their parameters and state-dict keys
    stay those of the plain module); returns the names compiled."""
    inner = getattr(policy, "diffusion", None)
    done = []
    for name in COMPILED:
        module = getattr(inner, name, None)
        if module is not None:
            module.compile(backend=COMPILE_BACKEND, dynamic=False)
            done.append(name)
    return done


def _cycle(loader: Any) -> Iterator[Any]:
    while True:
        yield from loader


class Trainer:
    """A lerobot policy, its processors, optimizer, scheduler and data, ready to step.

    Built from ``train.*`` and the inputs (a fresh policy with the statistics of the converted
    features) or from a checkpoint (its ``pretrained_model`` and ``training_state``: weights,
    processors with their statistics, optimizer, scheduler, RNG and step).

    Attributes:
        cfg: the lerobot policy config; policy: the lerobot policy; pre, post: its pre- and
        post-processor pipelines; pipeline: lerobot's ``TrainPipelineConfig`` (saved with each
        checkpoint); optimizer, scheduler; base: the ``LeRobotDataset``; trainset: its
        converted view; step: optimizer steps done; device: the torch device.
    """

    def __init__(
        self,
        tc: Any,
        spec: InputSpec,
        root: Path,
        out: Path,
        resume: Path | None = None,
        episodes: list[int] | None = None,
        accelerator: Any = None,
    ) -> None:
        import torch
        from lerobot.configs.default import DatasetConfig
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.configs.train import TrainPipelineConfig
        from lerobot.optim.factory import make_optimizer_and_scheduler
        from lerobot.policies.factory import make_policy, make_pre_post_processors
        from lerobot.utils.random_utils import set_seed
        from lerobot.utils.train_utils import load_training_state

        from factory.policy.checkpoint import resolve_device

        if tc.threads > 0:
            torch.set_num_threads(tc.threads)
        self.tc = tc
        self.spec = spec
        if accelerator is None:
            self.device = resolve_device(tc.device)
        else:  # this rank's device: cuda:<rank>, or the CPU
            dev = accelerator.device
            self.device = "cpu" if dev.type == "cpu" else str(dev)
        if self.device.startswith("cuda"):
            torch.backends.cudnn.benchmark = True  # fixed image shapes: the fastest kernels
        set_seed(tc.seed)
        if resume is not None:
            pretrained = resume / PRETRAINED
            cfg = PreTrainedConfig.from_pretrained(pretrained)
            cfg.device = self.device
            cfg.pretrained_path = pretrained
        else:
            cfg = policy_config(tc, spec, self.device)
        self.cfg = cfg
        self.precision = resolve_precision(getattr(tc, "precision", "fp32"), self.device)
        # train.vision=perception: the lerobot policy is a state policy (its recipe, no
        # auxiliary head); the perception network learns the poses the aux target holds
        recipe_inputs = "state" if spec.perception else spec.inputs
        self.aux_weight = 0.0
        if not spec.perception:
            setting = getattr(tc, "aux_state", 0.0)
            self.aux_weight = resolve_aux_state(setting, tc.policy, spec.inputs, spec.poses)
        self.ema_decay = resolve_ema(getattr(tc, "ema", 0.0), tc.policy, recipe_inputs)
        self.base, self.trainset = open_dataset(
            root,
            spec,
            cfg,
            tc.augment_images,
            getattr(tc, "video_cache", "off"),
            self.aux_weight > 0 or spec.perception,
            bool(getattr(tc, "perception_points", True)),
            float(getattr(tc, "augment_shading", 0.0)),
        )
        if spec.perception and self.trainset.frames is None:
            raise PolicyError(
                "train.vision=perception needs the camera frames in memory: set "
                "train.video_cache=memory (or free memory for train.video_cache=auto)"
            )
        if self.aux_weight > 0 and self.trainset.frames is None:
            log.warning(
                "train: the auxiliary state loss needs the camera frames in memory "
                "(train.video_cache): training without it"
            )
            self.aux_weight = 0.0
        self.episodes = sorted(episodes) if episodes else None
        with quiet_stdout():
            self.policy = make_policy(cfg, ds_meta=model_meta(self.base.meta, spec))
        if resume is not None:
            self.pre, self.post = make_pre_post_processors(
                cfg,
                pretrained_path=str(cfg.pretrained_path),
                preprocessor_overrides={"device_processor": {"device": self.device}},
            )
        else:
            stats = model_stats(spec, root, self.base, self.trainset, self.episodes)
            self.pre, self.post = make_pre_post_processors(cfg, dataset_stats=stats)
        self.pipeline = TrainPipelineConfig(
            dataset=DatasetConfig(repo_id="factory/demos", root=str(root), video_backend="pyav"),
            policy=cfg,
            output_dir=out,
            job_name=out.name,
            seed=tc.seed,
            num_workers=tc.num_workers,
            batch_size=tc.batch_size,
            steps=tc.steps,
            eval_freq=0,
            log_freq=tc.log_every,
            save_freq=tc.save_every,
        )
        self.pipeline.optimizer = cfg.get_optimizer_preset()
        self.pipeline.scheduler = cfg.get_scheduler_preset()
        if tc.lr > 0:
            self.pipeline.optimizer.lr = tc.lr
        elif default_lr(tc.policy) > 0:
            self.pipeline.optimizer.lr = default_lr(tc.policy)
        self.optimizer, self.scheduler = make_optimizer_and_scheduler(self.pipeline, self.policy)
        self.step = 0
        if resume is not None:
            self.step, self.optimizer, self.scheduler = load_training_state(
                resume, self.optimizer, self.scheduler
            )
        self.params = [p for p in self.policy.parameters() if p.requires_grad]
        self.grad_clip = float(getattr(self.pipeline.optimizer, "grad_clip_norm", 0.0) or 0.0)
        encoder = getattr(getattr(self.policy, "diffusion", None), "rgb_encoder", None)
        if encoder is not None:
            encoder.to(memory_format=torch.channels_last)  # NHWC convolutions on tensor cores
        self.compiled = resolve_compile(
            getattr(tc, "compile", False), tc.policy, spec.inputs, self.device
        )
        self.perception: Any = None
        if spec.perception:
            self._make_perception(resume)
        if self.compiled:
            compiled = _compile_modules(self.policy)
            if self.perception is not None:
                self.perception.compile(backend=COMPILE_BACKEND, dynamic=False)
                compiled.append("perception")
            log.info("train: torch.compile: %s", ", ".join(compiled) or "nothing to compile")
        self.aux_head: Any = None
        self.tap: Any = None
        if self.aux_weight > 0 and encoder is None:
            log.warning(
                "train: policy %s has no image encoder to tap: no auxiliary loss", tc.policy
            )
            self.aux_weight = 0.0
        extras = _read_extras(resume)
        if self.aux_weight > 0:
            from factory.policy.aux_state import FeatureTap, make_head

            assert self.trainset.frames is not None
            target = self.trainset.frames.values[AUX_TARGET]
            n_cams = len(cfg.image_features)
            feat_dim = int(cfg.spatial_softmax_num_keypoints) * 2
            self.tap = FeatureTap(encoder)
            self.aux_head = make_head(n_cams * feat_dim, target).to(self.device)
            aux_state = {k[4:]: v for k, v in extras.items() if k.startswith("aux.")}
            if aux_state:
                self.aux_head.load_state_dict(aux_state)
            self.aux_optimizer = torch.optim.AdamW(
                self.aux_head.parameters(), lr=self.pipeline.optimizer.lr, weight_decay=1e-6
            )
        self.ema: Any = None
        if self.ema_decay > 0:
            from factory.policy.ema import EmaWeights

            # a resumed policy holds the average (pretrained_model); the raw weights are extras
            updates = int(extras["ema.updates"].item()) if "ema.updates" in extras else 0
            self.ema = EmaWeights(self.params, self.ema_decay, updates)
            raw = [extras[f"raw.{i}"] for i in range(len(self.params)) if f"raw.{i}" in extras]
            if len(raw) == len(self.params):
                with torch.no_grad():
                    for p, r in zip(self.params, raw, strict=True):
                        p.copy_(r.to(p.device))
        self.last_aux: Any = None
        self.sync: Any = None
        if accelerator is not None and accelerator.num_processes > 1:
            from factory.policy.data_parallel import GradientSync

            head = list(self.aux_head.parameters()) if self.aux_head is not None else []
            if self.perception is not None:
                head = list(self.perception.parameters())
            self.sync = GradientSync(accelerator, [*self.params, *head])
            self.sync.broadcast_weights()
            if self.ema is not None:
                import torch.distributed as dist

                for t in self.ema.shadow:
                    dist.broadcast(t, 0)
        self.policy.train()

    def _make_perception(self, resume: Path | None) -> None:
        """The perception network (``train.vision=perception``), its optimizer (AdamW at the
        policy's learning rate) and schedule (the policy's: 500 warm-up steps, then a cosine
        to 0 at ``train.steps``); from the checkpoint ``resume`` where given."""
        import math

        import torch

        from factory.policy import perception

        frames = self.trainset.frames
        assert frames is not None
        target = frames.values[AUX_TARGET]
        settings = perception.settings_of(
            list(self.spec.cameras),
            self.spec.depth,
            self.spec.image_size,
            target,
            self.spec.depth_max_m,
            frames.point_cameras,
            self.spec.pose_cameras,
            bool(getattr(self.tc, "perception_objects", True)),
        )
        if resume is not None and (resume / PRETRAINED / perception.WEIGHTS).is_file():
            net = perception.load(resume / PRETRAINED, self.device)
        else:
            net = perception.build(settings).to(self.device)
        self.perception = net.to(memory_format=torch.channels_last).train()
        self.perception_optimizer = torch.optim.AdamW(
            net.parameters(), lr=self.pipeline.optimizer.lr, weight_decay=1e-6
        )
        total, warm = max(int(self.tc.steps), 1), 500

        def factor(step: int) -> float:
            if step < warm:
                return (step + 1) / warm
            return 0.5 * (1 + math.cos(math.pi * min(1.0, (step - warm) / max(total - warm, 1))))

        self.perception_scheduler = torch.optim.lr_scheduler.LambdaLR(
            self.perception_optimizer, factor
        )
        state = None if resume is None else resume / TRAINING_STATE / PERCEPTION_STATE
        if state is not None and state.is_file():
            saved = torch.load(state, map_location=self.device, weights_only=True)
            self.perception_optimizer.load_state_dict(saved["optimizer"])
            self.perception_scheduler.load_state_dict(saved["scheduler"])
        self.noise_gen = torch.Generator(device=self.device).manual_seed(self.tc.seed + 17)
        self.last_perception_m: Any = None
        log.info(
            "train: train.vision=perception: %d-parameter perception network over %s (%s; "
            "points of %s), position noise %.3g m",
            sum(p.numel() for p in net.parameters()),
            ", ".join(self.spec.cameras),
            "RGB + depth" if self.spec.depth else "RGB",
            ", ".join(net.point_cameras) or "no camera",
            float(getattr(self.tc, "perception_noise_m", 0.0)),
        )

    @property
    def rank(self) -> int:
        """This process's rank (0 without data parallelism)."""
        return 0 if self.sync is None else self.sync.rank

    def sampler(self) -> Any:
        """lerobot's ``EpisodeAwareSampler`` over the episodes trained on (without the last
        frames where the policy drops them), shuffled; None: every frame, shuffled."""
        from lerobot.datasets.sampler import EpisodeAwareSampler

        drop_last = getattr(self.cfg, "drop_n_last_frames", 0) or 0
        if not drop_last and self.episodes is None:
            return None
        meta = self.base.meta
        sampler = EpisodeAwareSampler(
            meta.episodes["dataset_from_index"],
            meta.episodes["dataset_to_index"],
            episode_indices_to_use=self.episodes,
            drop_n_last_frames=drop_last,
            shuffle=True,
        )
        if not sampler.indices:
            raise PolicyError(
                f"every episode is shorter than the {drop_last} last frames policy "
                f"{self.cfg.type} drops: record longer episodes or lower the horizon"
            )
        return sampler

    def loader(self) -> Iterator[Any]:
        """Endless batches of ``train.batch_size`` samples (:meth:`sampler`): gathered on the
        device (:class:`~factory.policy.device_batches.DeviceBatches`, ``train.loader``) or
        collated by torch's DataLoader."""
        import torch

        from factory.policy.device_batches import DeviceBatches, resolve_loader

        sampler = self.sampler()
        frames = self.trainset.frames
        setting = getattr(self.tc, "loader", "dataloader")
        if resolve_loader(setting, self.device, frames is not None) == "device":
            assert frames is not None
            indices = None if sampler is None else np.asarray(list(sampler.indices), np.int64)
            augment = bool(self.tc.augment_images and self.spec.cameras)
            log.info("train: batches gathered on %s (train.loader=%s)", self.device, setting)
            return DeviceBatches(
                frames,
                self.device,
                self.tc.batch_size,
                indices,
                self.tc.seed + self.step + 1_000_003 * self.rank,
                augment,
                shift=not (self.perception is not None and self.perception.xyz),
                shading=float(getattr(self.tc, "augment_shading", 0.0)),
            )
        workers = self.tc.num_workers
        loader: Any = torch.utils.data.DataLoader(
            self.trainset,  # type: ignore[arg-type]
            batch_size=self.tc.batch_size,
            shuffle=sampler is None,
            sampler=sampler,
            num_workers=workers,
            pin_memory=self.device.startswith("cuda"),
            drop_last=False,
            prefetch_factor=2 if workers > 0 else None,
            persistent_workers=workers > 0,
        )
        return _cycle(loader)

    def optimize(self, batch: dict[str, Any]) -> Any:
        """One optimizer step on a batch as the loader gives it; returns the policy's loss, a
        0-d tensor on the device (reading it waits for the GPU: :func:`train` reads the
        losses once per logged interval). With the auxiliary loss, its value of this step is
        :attr:`last_aux`.

        Under ``bf16`` the forward pass runs in torch's bfloat16 autocast (weights, gradients
        and the optimizer stay fp32).
        """
        import torch

        target = batch.pop(AUX_TARGET, None)
        pose = batch.pop(CAMERA_POSE, None)
        images = None
        if self.perception is not None:
            from factory.policy.perception import add_noise, camera_stack

            images = camera_stack(batch, self.perception.cameras, self.perception.depth)
            for k in self.spec.visual_keys():
                batch.pop(k, None)
            noise = float(getattr(self.tc, "perception_noise_m", 0.0))
            env = batch[ENV_STATE].to(self.device, non_blocking=True)
            batch[ENV_STATE] = add_noise(env, noise, self.noise_gen)
        batch = self.pre(batch)
        kind = "cuda" if self.device.startswith("cuda") else "cpu"
        with torch.autocast(kind, dtype=torch.bfloat16, enabled=self.precision == "bf16"):
            loss, _ = self.policy.forward(batch)
            total = loss
            if images is not None and target is not None:
                seen, err_m = self.perception.loss(
                    images.to(self.device, non_blocking=True),
                    target.to(self.device, non_blocking=True),
                    None if pose is None else pose.to(self.device, non_blocking=True),
                )
                total = loss + seen
                self.last_aux = seen.detach()
                self.last_perception_m = err_m
            if self.aux_head is not None and target is not None:
                b, n_obs = batch[STATE].shape[:2]
                feats = self.tap.take(b, n_obs, len(self.cfg.image_features))
                aux = self.aux_head.loss(feats, target.to(self.device, non_blocking=True))
                total = loss + self.aux_weight * aux
                self.last_aux = aux.detach()
        if self.tap is not None:
            self.tap.clear()
        total.backward()
        if self.sync is not None:
            self.sync.average()
        if self.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.params, self.grad_clip)
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=True)
        if self.aux_head is not None:
            self.aux_optimizer.step()
            self.aux_optimizer.zero_grad(set_to_none=True)
        if self.perception is not None:
            if self.grad_clip > 0:
                torch.nn.utils.clip_grad_norm_(self.perception.parameters(), self.grad_clip)
            self.perception_optimizer.step()
            self.perception_optimizer.zero_grad(set_to_none=True)
            self.perception_scheduler.step()
        if self.scheduler is not None:
            self.scheduler.step()
        if hasattr(self.policy, "update"):
            self.policy.update()
        if self.ema is not None:
            self.ema.update(self.params)
        self.step += 1
        return loss.detach()

    def parameters(self) -> int:
        return sum(p.numel() for p in self.params)

    def save(self, ckpt_root: Path, info: TrainInfo) -> Path:
        """Writes ``checkpoints/<step>/`` aside, renames it into place, points ``last`` at it."""
        from lerobot.utils.train_utils import get_step_identifier, save_checkpoint

        from factory.store import atomic_write_json

        ident = get_step_identifier(self.step, self.tc.steps)
        tmp = ckpt_root / f".tmp-{ident}"
        shutil.rmtree(tmp, ignore_errors=True)
        extras: dict[str, Any] = {}
        with (
            self.ema.applied(self.params) if self.ema is not None else nullcontext([]) as raw,
            _contiguous_state(self.optimizer),
        ):
            save_checkpoint(
                tmp,
                self.step,
                self.pipeline,
                self.policy,
                self.optimizer,
                self.scheduler,
                self.pre,
                self.post,
            )
        if self.ema is not None:
            import torch

            extras.update({f"raw.{i}": r for i, r in enumerate(raw)})
            extras["ema.updates"] = torch.tensor([self.ema.updates], dtype=torch.int64)
        if self.aux_head is not None:
            extras.update({f"aux.{k}": v for k, v in self.aux_head.state_dict().items()})
        if self.perception is not None:
            import torch

            from factory.policy import perception

            perception.save(self.perception, tmp / PRETRAINED)
            torch.save(
                {
                    "optimizer": self.perception_optimizer.state_dict(),
                    "scheduler": self.perception_scheduler.state_dict(),
                },
                tmp / TRAINING_STATE / PERCEPTION_STATE,
            )
        if extras:
            from safetensors.torch import save_file

            save_file(
                {k: v.detach().contiguous().cpu() for k, v in extras.items()},
                str(tmp / "training_state" / EXTRAS),
            )
        info.steps = self.step
        atomic_write_json(tmp / PRETRAINED / INFO_IN_MODEL, info.to_json())
        final = ckpt_root / ident
        publish_checkpoint(tmp, final)
        return final


@contextmanager
def _contiguous_state(optimizer: Any) -> Iterator[None]:
    """The optimizer's state tensors made contiguous for the block: lerobot saves them with
    safetensors, which refuses the channels-last moments of a channels-last image encoder;
    the originals are put back after it."""
    swapped: list[tuple[dict[str, Any], str, Any]] = []
    for state in optimizer.state.values():
        for key, value in state.items():
            if hasattr(value, "is_contiguous") and not value.is_contiguous():
                swapped.append((state, key, value))
                state[key] = value.contiguous()
    try:
        yield
    finally:
        for state, key, value in swapped:
            state[key] = value


def _read_extras(resume: Path | None) -> dict[str, Any]:
    """The :data:`EXTRAS` of a checkpoint (empty: none, or no checkpoint)."""
    if resume is None:
        return {}
    path = resume / "training_state" / EXTRAS
    if not path.is_file():
        return {}
    from safetensors.torch import load_file

    return dict(load_file(str(path)))


def train(
    tc: Any,
    spec: InputSpec,
    root: Path,
    out: Path,
    info: TrainInfo,
    resume: Path | None,
    progress: bool = True,
    curve: Any = None,
    accelerator: Any = None,
) -> TrainResult:
    """Trains (or resumes) the policy of ``policy/<name>`` up to ``train.steps`` steps.

    Args:
        tc: ``train.*`` (:class:`factory.config.TrainConfig`).
        spec: the inputs (checked against the dataset).
        root: the merged dataset.
        out: ``policy/<name>``.
        info: the training record (``steps`` is updated at every checkpoint).
        resume: the checkpoint to continue from, or None.
        progress: show a progress bar with the loss.
        curve: the learning curve (:class:`factory.policy.learning_curve.LearningCurve`) that
            evaluates checkpoints as training goes (``train.eval_every_minutes``), or None.
        accelerator: this rank's ``accelerate.Accelerator`` under ``train.gpus`` > 1
            (:mod:`factory.policy.data_parallel`); rank 0 alone writes.
    """
    import torch
    from tqdm import tqdm

    from factory.console import terminal
    from factory.store import atomic_write_text

    trainer = Trainer(tc, spec, root, out, resume, info.episode_indices or None, accelerator)
    main = trainer.rank == 0
    if not main:
        curve = None
    step = resumed_from = trainer.step
    log_path = out / TRAIN_LOG
    history = _read_log(log_path, step)
    if main and log_path.exists():  # drop lines past the checkpoint of a killed run
        atomic_write_text(log_path, "".join(json.dumps(r) + "\n" for r in history))
    seconds_before = float(history[-1]["seconds"]) if history else 0.0
    batches = trainer.loader()
    log.info(
        "train %s: %s on %s (%s%s%s), inputs=%s %s, %d frames in %d episodes, %d parameters, "
        "batch %d, %s",
        info.name,
        trainer.cfg.type,
        trainer.device,
        trainer.precision,
        f", auxiliary state loss x{trainer.aux_weight:g}" if trainer.aux_weight > 0 else "",
        f", EMA {trainer.ema_decay:g}" if trainer.ema_decay > 0 else "",
        spec.inputs,
        dict(spec.model_features()),
        info.frames or trainer.base.num_frames,
        info.episodes or trainer.base.num_episodes,
        trainer.parameters(),
        tc.batch_size,
        f"resuming from step {step}" if resume is not None else "from scratch",
    )
    ckpt_root = out / CHECKPOINTS
    ckpt_root.mkdir(parents=True, exist_ok=True)
    newest = str(resume) if resume is not None else ""
    losses: list[Any] = []
    aux_losses: list[Any] = []
    seen_m: list[Any] = []  # the perception's position errors (m) of the interval's batches
    last_loss = float("nan")
    limit = 60.0 * float(getattr(tc, "max_minutes", 0.0) or 0.0)
    t0 = time.perf_counter()
    with (
        tqdm(
            total=tc.steps,
            initial=step,
            desc=f"train {info.name}",
            unit="step",
            file=terminal(),
            disable=None if progress and main else True,
        ) as bar,
        log_path.open("a") if main else open(os.devnull, "w") as log_file,
    ):
        while step < tc.steps:
            losses.append(trainer.optimize(next(batches)))
            if trainer.last_aux is not None:
                aux_losses.append(trainer.last_aux)
            if getattr(trainer, "last_perception_m", None) is not None:
                seen_m.append(trainer.last_perception_m)
            step = trainer.step
            bar.update(1)
            late = limit > 0 and time.perf_counter() - t0 > limit
            if trainer.sync is not None:  # every rank stops at the same step: rank 0's clock
                at_log = step % tc.log_every == 0 or step == tc.steps
                late = trainer.sync.any(late) if at_log else False
            if step % tc.log_every == 0 or step == tc.steps or late:
                last_loss = float(torch.stack(losses).float().mean().item())
                losses.clear()
                if not np.isfinite(last_loss):
                    raise PolicyError(
                        f"the loss became {last_loss} by step {step}: lower train.lr and "
                        "retrain (force=true)"
                    )
                elapsed = time.perf_counter() - t0
                rec = {
                    "step": step,
                    "loss": round(last_loss, 6),
                    "lr": trainer.optimizer.param_groups[0]["lr"],
                    "seconds": round(seconds_before + elapsed, 3),
                    "steps_per_s": round((step - resumed_from) / max(elapsed, 1e-9), 3),
                }
                if aux_losses:
                    rec["aux_loss"] = round(float(torch.stack(aux_losses).mean().item()), 6)
                    aux_losses.clear()
                if seen_m:  # root-mean-square position error of the batches, cm
                    sq = torch.stack(seen_m).float().square().mean().sqrt()
                    rec["perception_cm"] = round(100 * float(sq.item()), 3)
                    seen_m.clear()
                log_file.write(json.dumps(rec) + "\n")
                log_file.flush()
                bar.set_postfix(loss=f"{last_loss:.4f}")
                log.debug("train %s: %s", info.name, rec)
                if curve is not None:
                    for point in curve.poll():
                        log_file.write(json.dumps(point) + "\n")
                        log_file.flush()
            evaluate = curve is not None and curve.due(time.perf_counter() - t0)
            if main and (step % tc.save_every == 0 or step == tc.steps or late or evaluate):
                newest = str(trainer.save(ckpt_root, info))
                write_train_json(out, info)
                if evaluate:
                    curve.start(Path(newest), step, seconds_before + time.perf_counter() - t0)
                prune_checkpoints(out, tc.keep_checkpoints)
            if late and step < tc.steps:
                log.info(
                    "train %s: train.max_minutes=%g reached at step %d of %d; a re-run goes on",
                    info.name,
                    tc.max_minutes,
                    step,
                    tc.steps,
                )
                break
        if curve is not None:
            last = Path(newest) if newest else None
            points = curve.finish(last, step, seconds_before + time.perf_counter() - t0)
            for point in [*points, *curve.poll(wait=True)]:
                log_file.write(json.dumps(point) + "\n")
                log_file.flush()
    seconds = time.perf_counter() - t0
    done = step - resumed_from
    return TrainResult(
        step=step,
        resumed_from=resumed_from,
        loss=last_loss,
        seconds=round(seconds, 3),
        steps_per_s=round(done / seconds, 3) if done and seconds > 0 else 0.0,
        checkpoint=newest,
    )


def checkpoint_of(out: Path) -> tuple[Path | None, int]:
    """The newest checkpoint of ``policy/<name>`` and its step (None, 0 without one)."""
    from factory.policy.checkpoint import last_checkpoint

    ckpt = last_checkpoint(out)
    return (ckpt, checkpoint_step(ckpt)) if ckpt is not None else (None, 0)


def dataset_root(run_dir: Path, configured: str | None) -> Path:
    """``train.dataset`` or ``<run_dir>/dataset/merged``."""
    return Path(configured) if configured else Path(run_dir) / "dataset" / "merged"
