"""The zarr v3 episode store of one shard: ``episodes/shard-<k>.zarr``.

One group per episode (named by its id) holds the arrays of
:data:`factory.schema.episode.EPISODE_ARRAYS`, chunked along time so that frames can be
appended, and its :class:`~factory.schema.episode.EpisodeInfo` as attributes. An episode is
written whole into a staging folder beside the store and renamed into it, so a killed writer
leaves at most a staging folder (removed on the next open) and never a half-written episode.
"""

from __future__ import annotations

import os
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from factory.errors import StoreError
from factory.schema.episode import (
    EPISODE_SCHEMA_VERSION,
    READABLE_EPISODE_VERSIONS,
    EpisodeInfo,
    episode_info_from_dict,
    episode_info_to_dict,
)
from factory.schema.scene import check_id

STORE_KIND = "factory.episodes"
TIME_CHUNK = 32
"""Frames per chunk of every array (images included)."""


def _zarr() -> Any:
    try:
        import zarr
    except ImportError as e:  # pragma: no cover - zarr is part of setup.sh
        raise StoreError(f"episode stores need zarr ({e}): pip install -e '.[data]'") from None
    return zarr


class EpisodeStore:
    """Episodes of one shard.

    Args:
        path: the store folder (``.../shard-<k>.zarr``); created on first write.

    Raises:
        StoreError: the folder exists but is not an episode store of this version.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.staging = self.path.with_name(self.path.name + ".staging")
        if self.path.exists():
            self._check_root()

    def _check_root(self) -> None:
        zarr = _zarr()
        try:
            root = zarr.open_group(str(self.path), mode="r")
        except Exception as e:
            raise StoreError(f"{self.path} is not a zarr episode store: {e}") from None
        attrs = dict(root.attrs)
        version = attrs.get("schema_version")
        if attrs.get("kind") != STORE_KIND or version not in READABLE_EPISODE_VERSIONS:
            raise StoreError(
                f"{self.path}: not a factory episode store of schema_version "
                f"{' or '.join(map(str, READABLE_EPISODE_VERSIONS))} (attributes {attrs}); move "
                "it away or use a new run_dir"
            )

    def _ensure_root(self) -> None:
        if self.path.exists():
            return
        zarr = _zarr()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # one name per process and thread: writer threads may open a new store together
        tmp = self.path.with_name(self.path.name + f".new-{os.getpid()}-{threading.get_ident()}")
        shutil.rmtree(tmp, ignore_errors=True)
        root = zarr.open_group(str(tmp), mode="w", zarr_format=3)
        root.attrs.update({"kind": STORE_KIND, "schema_version": EPISODE_SCHEMA_VERSION})
        try:
            os.rename(tmp, self.path)
        except OSError:  # another process made it first
            shutil.rmtree(tmp, ignore_errors=True)
            self._check_root()

    def clean_staging(self) -> None:
        """Removes episodes left half-written by a killed writer."""
        shutil.rmtree(self.staging, ignore_errors=True)

    def episode_ids(self) -> list[str]:
        """Ids of the complete episodes (sorted)."""
        if not self.path.is_dir():
            return []
        return sorted(
            p.name for p in self.path.iterdir() if p.is_dir() and (p / "zarr.json").is_file()
        )

    def __contains__(self, episode_id: str) -> bool:
        return (self.path / episode_id / "zarr.json").is_file()

    def __len__(self) -> int:
        return len(self.episode_ids())

    def write(self, info: EpisodeInfo, arrays: dict[str, np.ndarray]) -> Path:
        """Writes one episode atomically.

        Args:
            info: its metadata.
            arrays: name -> array (F leading), e.g. ``time``, ``rgb/left``.

        Raises:
            StoreError: the episode exists already, or arrays disagree on F.
        """
        zarr = _zarr()
        eid = check_id(info.episode_id, "episode id")
        if eid in self:
            raise StoreError(f"episode {eid!r} is already in {self.path}")
        frames = {name: len(a) for name, a in arrays.items()}
        if set(frames.values()) != {info.n_frames}:
            raise StoreError(
                f"episode {eid!r}: arrays must all have n_frames={info.n_frames} rows: {frames}"
            )
        self._ensure_root()
        self.staging.mkdir(parents=True, exist_ok=True)
        tmp = self.staging / f"{eid}.{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        group = zarr.open_group(str(tmp), mode="w", zarr_format=3)
        for name, arr in arrays.items():
            arr = np.ascontiguousarray(arr)
            chunks = (min(TIME_CHUNK, max(1, len(arr))), *arr.shape[1:])
            z = group.create_array(name, shape=arr.shape, dtype=arr.dtype, chunks=chunks)
            z[...] = arr
        # One metadata write (attrs.update rewrites the group's zarr.json once per key: 31)
        group.update_attributes(episode_info_to_dict(info))
        try:
            os.rename(tmp, self.path / eid)
        except OSError as e:
            shutil.rmtree(tmp, ignore_errors=True)
            raise StoreError(f"episode {eid!r} could not be stored in {self.path}: {e}") from None
        return self.path / eid

    def info(self, episode_id: str) -> EpisodeInfo:
        """The metadata of one episode."""
        zarr = _zarr()
        if episode_id not in self:
            raise StoreError(f"no episode {episode_id!r} in {self.path}")
        group = zarr.open_group(str(self.path / episode_id), mode="r")
        return episode_info_from_dict(dict(group.attrs))

    def arrays(self, episode_id: str) -> Any:
        """The episode's zarr group (arrays read lazily: ``g["rgb/left"][10]``)."""
        zarr = _zarr()
        if episode_id not in self:
            raise StoreError(f"no episode {episode_id!r} in {self.path}")
        return zarr.open_group(str(self.path / episode_id), mode="r")

    def __iter__(self) -> Iterator[EpisodeInfo]:
        for eid in self.episode_ids():
            yield self.info(eid)
