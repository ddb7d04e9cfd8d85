"""Episode stores -> LeRobot v3 datasets, with lerobot's own writer and aggregator.

One path writes every task's episodes. Features of every frame (:mod:`factory.dataset.features`):

* the task's (:meth:`~factory.tasks.base.Task.dataset_features`, e.g. the state, tool pose and
  action: :mod:`factory.tasks.pick_place.dataset`, :mod:`factory.tasks.mobile_pick_place.dataset`);
* ``observation.camera_poses`` where the episodes record their scene cameras' calibration
  (:func:`~factory.dataset.features.calibrated_cameras`);
* ``observation.images.<camera>`` video (H, W, 3), h264;
* ``observation.depth.<camera>`` video (H, W, 3), lossless RGB h264 packing uint16 millimetres
  as (high byte, low byte, 0); :func:`unpack_depth_mm` turns lerobot's (3, H, W) float tensor
  (or the uint8 image) back into exact millimetres;
* the task string (the episode's instruction).

Frames go through lerobot's ``add_frame``/``save_episode``/``finalize``; the video features are
encoded while frames are added by :mod:`factory.dataset.video` (lerobot's streaming encoder
with a codec per feature), so no frame is written as a PNG on the way.

``extras/<episode_id>/`` beside the data holds the episode's ``scene.json``, the scene's
``model.xml`` (with the meshes it uses under ``extras/assets/``), ``robot.json`` (base
placement, cameras, objects cleared) and ``states.npz`` (MuJoCo integration states, exact
replay); ``meta/factory.json`` names the scenes, seeds, episode ids (by dataset episode index)
and the factory version, with the keys the task adds
(:meth:`~factory.tasks.base.Task.dataset_meta`) and each episode's navigation ``route`` where it
drove one (:mod:`factory.dataset.routes`). One dataset holds one layout
(:mod:`factory.dataset.layout`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from factory.dataset.features import (
    DEPTH_ENCODING,
    calibrated_cameras,
    check_arrays,
    features_for,
    scalar_buffer,
)
from factory.dataset.layout import (
    episode_task,
    layout_of,
    one_layout,
    one_meta_layout,
    task_meta_of,
)
from factory.dataset.routes import ROUTE_KEY, route_entry
from factory.dataset.video import VideoCodec, frame_encoder, lossless_codec, rgb_codec
from factory.demos.record.calibration import (
    CALIBRATION_SIZE,
    CAMERA_POSES_KEY,
    calibration_vector,
)
from factory.errors import StoreError

log = logging.getLogger(__name__)

FACTORY_META = "meta/factory.json"
EXPORT_SCHEMA_VERSION = 6
"""Format of ``meta/factory.json`` and the features (3: ``observation.environment_state``;
4: a mobile episode's entry in ``meta/factory.json`` holds its ``route``; 5:
``observation.camera_poses``; 6: mobile datasets' ``observation.environment_state``)."""
VIDEO_FILE_MB = 4


def depth_mm(depth: np.ndarray) -> np.ndarray:
    """Depth as uint16 millimetres (float metres are rounded to the millimetre)."""
    if depth.dtype == np.uint16:
        return depth
    return np.clip(np.round(np.asarray(depth, np.float64) * 1000.0), 0, 65535).astype(np.uint16)


def pack_depth_mm(mm: np.ndarray) -> np.ndarray:
    """(..., H, W) uint16 millimetres -> (..., H, W, 3) uint8 (high byte, low byte, 0)."""
    mm = np.asarray(mm, np.uint16)
    out = np.zeros((*mm.shape, 3), np.uint8)
    out[..., 0] = mm >> 8
    out[..., 1] = mm & 0xFF
    return out


def unpack_depth_mm(image: Any) -> np.ndarray:
    """Exact depth in millimetres (H, W) uint16 from a packed depth image.

    Args:
        image: (H, W, 3) uint8 as encoded, or lerobot's (3, H, W) float tensor/array in [0, 1].
    """
    arr = image.numpy() if hasattr(image, "numpy") else np.asarray(image)
    if arr.dtype != np.uint8:
        arr = np.round(np.moveaxis(arr, 0, -1) * 255.0).astype(np.uint8)
    return (arr[..., 0].astype(np.uint16) << 8) | arr[..., 1].astype(np.uint16)


def _link_or_copy(src: str, dst: str) -> None:
    """Hard-links a file (assets and extras are never changed in place, only replaced by
    rename, so a link stays what was exported); copies across file systems. A file already
    at ``dst`` (the same asset from another part of a parallel export) is kept if it is the
    same file, else replaced."""
    if os.path.lexists(dst):
        if os.path.exists(dst) and os.path.samefile(src, dst):
            return
        os.unlink(dst)
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _fresh_tmp(dest: Path) -> Path:
    """The temporary sibling folder a dataset for ``dest`` is built in.

    One process at a time writes a given ``dest`` (a shard belongs to one array task, the merge
    to one job), so what a killed earlier writer left (a half-written folder, or the replaced
    dataset it had not yet deleted) is removed here.
    """
    dest.parent.mkdir(parents=True, exist_ok=True)
    for stale in [
        *dest.parent.glob(f".tmp-{dest.name}-*"),
        *dest.parent.glob(f".old-{dest.name}-*"),
    ]:
        log.warning("removing %s, left by an interrupted export", stale)
        shutil.rmtree(stale, ignore_errors=True)
    return dest.with_name(f".tmp-{dest.name}-{os.getpid()}")


def _publish(tmp: Path, dest: Path) -> None:
    """Moves a finished dataset from ``tmp`` to ``dest``, replacing an older one."""
    if dest.exists():
        old = dest.with_name(f".old-{dest.name}-{os.getpid()}")
        os.rename(dest, old)
        os.rename(tmp, dest)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(tmp, dest)


def _factory_meta(
    version: str,
    task: str,
    scenes: set[str],
    episodes: list[dict[str, Any]],
    video: dict[str, Any],
    state_spec: int,
    extra: dict[str, Any] | None,
) -> dict[str, Any]:
    """The content of ``meta/factory.json`` (``extra`` keys added last)."""
    return {
        "schema_version": EXPORT_SCHEMA_VERSION,
        "factory_version": version,
        "task": task,
        "scenes": sorted(scenes),
        "episodes": episodes,
        "depth_unit": "mm",
        "depth_encoding": DEPTH_ENCODING,
        "video": video,
        "state_spec": state_spec,
        **(extra or {}),
    }


class _ExtrasWriter:
    """Writes ``extras/<episode_id>/`` and, once per asset, ``extras/assets/<asset_id>/``.

    A scene's files are read, and its model rewritten, once however many episodes it has.
    """

    def __init__(self, dest: Path, run_dir: Path) -> None:
        self.dest = dest
        self.run_dir = run_dir
        self._scenes: dict[str, tuple[bytes, str | None]] = {}  # scene.json, model.xml
        self._assets: set[str] = set()

    def _scene(self, info: Any) -> tuple[bytes, str | None]:
        if info.scene_id in self._scenes:
            return self._scenes[info.scene_id]
        scene_dir = self.run_dir / "scenes" / info.scene_id
        scene_json = scene_dir / "scene.json"
        if not scene_json.is_file():
            raise StoreError(
                f"episode {info.episode_id!r}: its scene {scene_json} is missing from the run"
            )
        scene = scene_json.read_bytes()
        model = scene_dir / "model.xml"
        model_text = None
        if model.is_file():
            # the run's model.xml finds meshes in ../../assets; here they are in ../assets
            import xml.etree.ElementTree as ET

            root = ET.fromstring(model.read_text())
            compiler = root.find("compiler")
            if compiler is not None:
                for key in ("meshdir", "texturedir"):
                    if compiler.get(key):
                        compiler.set(key, "../assets")
            model_text = ET.tostring(root, encoding="unicode")
            assets = self.run_dir / "assets"
            # floor, wall and ceiling textures live in the run's shared assets/textures/
            for tex in root.iter("texture"):
                file = tex.get("file", "")
                if file.startswith("textures/") and (assets / file).is_file():
                    dst = self.dest / "extras" / "assets" / file
                    if not dst.exists():
                        dst.parent.mkdir(parents=True, exist_ok=True)
                        _link_or_copy(str(assets / file), str(dst))
            for obj in json.loads(scene).get("objects", []):
                aid = (obj.get("asset") or {}).get("asset_id")
                if aid and aid not in self._assets and (assets / aid).is_dir():
                    shutil.copytree(
                        assets / aid,
                        self.dest / "extras" / "assets" / aid,
                        copy_function=_link_or_copy,
                    )
                    self._assets.add(aid)
        self._scenes[info.scene_id] = (scene, model_text)
        return scene, model_text

    def scene_bytes(self, info: Any) -> bytes:
        """The episode's ``scene.json`` as recorded in the run."""
        return self._scene(info)[0]

    def write(self, info: Any, group: Any) -> None:
        """The extras of one episode (``group``: its zarr arrays)."""
        scene, model_text = self._scene(info)
        ep = self.dest / "extras" / info.episode_id
        ep.mkdir(parents=True, exist_ok=True)
        (ep / "scene.json").write_bytes(scene)
        if model_text is not None:
            (ep / "model.xml").write_text(model_text)
        robot = {
            "base": info.robot.__dict__,
            "cameras": info.cameras,
            "cleared": info.cleared,
            "pick_id": info.pick_id,
            "target_id": info.target_id,
            "support_id": info.support_id,
            "seed": info.seed,
            "fps": info.fps,
            "timestep": info.timestep,
            "state_spec": info.state_spec,
        }
        (ep / "robot.json").write_text(json.dumps(robot, indent=1))
        np.savez_compressed(ep / "states.npz", state=group["state"][:], time=group["time"][:])


def _episode_entry(index: int, info: Any) -> dict[str, Any]:
    """An episode's entry in ``meta/factory.json``: its dataset index, id, scene, seed and
    length; an episode that drove a route adds it (:func:`~factory.dataset.routes.route_entry`)."""
    entry: dict[str, Any] = {
        "episode_index": index,
        "episode_id": info.episode_id,
        "scene_id": info.scene_id,
        "seed": info.seed,
        "n_frames": info.n_frames,
    }
    if info.route:
        entry[ROUTE_KEY] = route_entry(info)
    return entry


def export_store(
    store: Any,
    dest: Path,
    repo_id: str,
    run_dir: Path,
    rgb: VideoCodec | None = None,
    version: str = "",
    extra_meta: dict[str, Any] | None = None,
    video_file_mb: int = VIDEO_FILE_MB,
    episode_ids: list[str] | None = None,
) -> dict[str, Any]:
    """Writes every episode of an episode store (or ``episode_ids`` of it, in that order) into
    a new LeRobot dataset at ``dest``.

    The dataset is built in a sibling temporary folder and renamed to ``dest`` at the end, so
    ``dest`` never holds a half-written dataset.

    Args:
        rgb: codec of the camera videos (default :func:`~factory.dataset.video.rgb_codec`);
            depth is always lossless.
        video_file_mb: episodes are appended to a video file until it reaches this size.
            lerobot re-muxes the whole file for each appended episode, so large files make
            writing quadratic in the episodes per shard (lerobot's default is 200 MB).

    Returns:
        the factory metadata written to ``meta/factory.json`` (with ``extra_meta`` added).

    Raises:
        StoreError: an episode has wrong shapes, a scene is missing, or the store is empty.
        MixedLayoutError: the episodes mix layouts (fixed-base and mobile ones).
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ids = store.episode_ids() if episode_ids is None else list(episode_ids)
    if not ids:
        raise StoreError(f"{store.path} holds no episodes: run stage=demos first")
    infos = [store.info(e) for e in ids]
    first = infos[0]
    shape = (first.image_size, first.cameras, first.fps)
    for info in infos[1:]:
        if (info.image_size, info.cameras, info.fps) != shape:
            raise StoreError(
                f"episode {info.episode_id!r} differs from {first.episode_id!r} in image size, "
                "cameras or fps: one dataset needs one shape"
            )
    one_layout(layout_of(i) for i in infos)
    task = episode_task(first)
    calibrated = calibrated_cameras(infos)
    features = features_for(task, first, store.arrays(first.episode_id), calibrated)
    log.info("dataset %s: %s episodes", dest.name, task.name)
    tmp = _fresh_tmp(dest)
    rgb = rgb or rgb_codec()
    codecs = {
        key: lossless_codec() if key.startswith("observation.depth.") else rgb
        for key, ft in features.items()
        if ft["dtype"] == "video"
    }
    ds = LeRobotDataset.create(
        repo_id=repo_id,
        fps=round(first.fps),
        features=features,
        root=tmp,
        robot_type=task.robot_type(),
        use_videos=True,
        vcodec="h264",
        streaming_encoding=True,
    )
    # lerobot's streaming seam: add_frame feeds it, save_episode collects videos and stats
    if not hasattr(ds, "_streaming_encoder"):
        raise StoreError("this lerobot has no streaming encoder: install lerobot 0.4.4")
    ds._streaming_encoder = frame_encoder(round(first.fps), codecs)
    ds.meta.update_chunk_settings(video_files_size_in_mb=video_file_mb)
    extras = _ExtrasWriter(tmp, run_dir)
    episodes = []
    try:
        from tqdm import tqdm

        from factory.console import terminal

        bar = tqdm(
            infos, desc=f"dataset {dest.name}", unit="episode", disable=None, file=terminal()
        )
        for index, info in enumerate(bar):
            group = store.arrays(info.episode_id)
            check_arrays(task, info, group, features)
            columns = task.episode_columns(info, group, extras.scene_bytes(info))
            rgb_frames = {c: group[f"rgb/{c}"][:] for c in info.cameras}
            depth = {c: pack_depth_mm(depth_mm(group[f"depth/{c}"][:])) for c in info.cameras}
            if calibrated:  # the episode's constant calibration, at every frame
                columns[CAMERA_POSES_KEY] = np.broadcast_to(
                    calibration_vector(info.camera_poses, info.camera_fovy, calibrated),
                    (info.n_frames, len(calibrated) * CALIBRATION_SIZE),
                )
            for f in range(info.n_frames):
                frame: dict[str, Any] = {key: col[f] for key, col in columns.items()}
                frame["task"] = info.instruction
                for c in info.cameras:
                    frame[f"observation.images.{c}"] = rgb_frames[c][f]
                    frame[f"observation.depth.{c}"] = depth[c][f]
                ds.add_frame(frame)
            scalar_buffer(ds.episode_buffer, features)
            ds.save_episode()
            extras.write(info, group)
            episodes.append(_episode_entry(index, info))
        ds.finalize()
        meta = _factory_meta(
            version,
            first.task,
            {i.scene_id for i in infos},
            episodes,
            {key: codec.__dict__ for key, codec in codecs.items()},
            first.state_spec,
            {**task.dataset_meta(), **(extra_meta or {})},
        )
        (tmp / FACTORY_META).write_text(json.dumps(meta, indent=1))
    except BaseException:
        ds._streaming_encoder.close()  # joins the encoder threads before the folder goes
        # lerobot's metadata flushes its episode buffer when garbage-collected, which would
        # re-create the folder after it is gone: close its writers and empty the buffer now
        with contextlib.suppress(Exception):
            ds.finalize()
        with contextlib.suppress(Exception):
            ds.meta.metadata_buffer.clear()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _publish(tmp, dest)
    return meta


def _same_calibration(shard_dirs: list[Path]) -> None:
    """Refuses shards of which some hold ``observation.camera_poses`` and others not, or of
    other cameras (lerobot's aggregation would refuse their features in a page-long message).

    Raises:
        StoreError: names two such shards and the fix.
    """
    seen: dict[str, Path] = {}
    for d in shard_dirs:
        feats = json.loads((d / "meta" / "info.json").read_text()).get("features", {})
        names = ",".join((feats.get(CAMERA_POSES_KEY) or {}).get("names") or [])
        seen.setdefault(names, d)
        if len(seen) > 1:
            (a, da), (b, db) = list(seen.items())[:2]
            raise StoreError(
                f"shards {da.name} and {db.name} differ in {CAMERA_POSES_KEY} (the cameras' "
                f"calibration: {'present' if a else 'absent'} and {'present' if b else 'absent'} "
                "or of other cameras): their episodes were recorded by different factory "
                "versions; re-record the older ones with stage=demos force=true, then "
                "stage=dataset force=true"
            )


def merge_datasets(
    shard_dirs: list[Path],
    dest: Path,
    repo_id: str,
    version: str = "",
    video_file_mb: int = VIDEO_FILE_MB,
    extra_meta: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Merges shard datasets (from :func:`export_store`) into one with lerobot's
    ``aggregate_datasets``; extras are combined, ``meta/factory.json`` re-indexed and a dataset
    card (``README.md``) written.

    Built in a temporary folder, checked by loading it, then renamed to ``dest``.

    Raises:
        StoreError: two shards hold the same episode, or a shard is not a finished export.
        MixedLayoutError: shards of different layouts (fixed-base and mobile) are mixed.
    """
    from lerobot.datasets.aggregate import aggregate_datasets
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    from factory.dataset.card import write_card

    metas = []
    for d in shard_dirs:
        path = d / FACTORY_META
        if not path.is_file():
            raise StoreError(f"{d} is not a finished shard dataset (no {FACTORY_META})")
        metas.append(json.loads(path.read_text()))
    one_meta_layout(metas, [str(d) for d in shard_dirs])
    _same_calibration(shard_dirs)
    seen: dict[str, Path] = {}
    for d, meta in zip(shard_dirs, metas, strict=True):
        for ep in meta["episodes"]:
            if ep["episode_id"] in seen:
                raise StoreError(
                    f"episode {ep['episode_id']!r} is in two shards ({seen[ep['episode_id']]} "
                    f"and {d}): shards must not overlap; re-run with one shard layout"
                )
            seen[ep["episode_id"]] = d
    tmp = _fresh_tmp(dest)
    try:
        aggregate_datasets(
            repo_ids=[f"{repo_id}-shard{k}" for k in range(len(shard_dirs))],
            aggr_repo_id=repo_id,
            roots=list(shard_dirs),
            aggr_root=tmp,
            video_files_size_in_mb=video_file_mb,
        )
        episodes = []
        offset = 0
        for d, meta in zip(shard_dirs, metas, strict=True):
            for ep in meta["episodes"]:
                episodes.append({**ep, "episode_index": offset + ep["episode_index"]})
            offset += len(meta["episodes"])
            extras = d / "extras"
            if extras.is_dir():
                shutil.copytree(
                    extras, tmp / "extras", dirs_exist_ok=True, copy_function=_link_or_copy
                )
        check = LeRobotDatasetMetadata(repo_id, root=tmp)
        if check.total_episodes != len(episodes):
            raise StoreError(
                f"merged dataset has {check.total_episodes} episodes, expected {len(episodes)}"
            )
        merged = _factory_meta(
            version,
            metas[0]["task"],
            {s for m in metas for s in m["scenes"]},
            episodes,
            metas[0].get("video", {}),
            metas[0]["state_spec"],
            {
                **task_meta_of(metas[0]),
                "shards": [d.name for d in shard_dirs],
                **(extra_meta or {}),
            },
        )
        (tmp / FACTORY_META).write_text(json.dumps(merged, indent=1))
        write_card(tmp, merged, check)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _publish(tmp, dest)
    return merged
