"""The run directory: layout, atomic writes, manifest, item stamps and shards.

Layout (``<run_dir>/``)::

    manifest.json             schema_version, factory version, git sha, config, stage status
    assets/<asset_id>/        content-addressed assets (meta.json, meshes, textures)
    scenes/<scene_id>/        scene.json, model.xml, renders/, report.json, .stamps/
    episodes/shard-<k>.zarr   raw demonstrations
    lerobot/<name>/           LeRobot datasets
    policy/<name>/            checkpoints and evaluations
    logs/                     one log file per stage and shard

Every file is written atomically (temporary file in the same folder, ``fsync``, rename), so a
killed stage never leaves a half-written file behind. A finished work item records a *stamp*
(``.stamps/<step>.json``) holding the hash of its inputs; re-running a stage skips items whose
stamp matches, which makes stages idempotent and resumable.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import logging
import os
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from factory.errors import ConfigError, StoreError
from factory.schema import Scene, check_id, load_scene, scene_to_json

log = logging.getLogger(__name__)

MANIFEST_SCHEMA_VERSION = 1
STAMP_SCHEMA_VERSION = 1

T = TypeVar("T")


# --------------------------------------------------------------------------------------------
# Atomic writes


def _file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


_FILE_MODE = _file_mode()


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` atomically (temp file + fsync + rename).

    The file gets the usual permissions (``0o666`` less the umask).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, _FILE_MODE)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Writes UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, data: Any) -> Path:
    """Writes ``data`` as indented JSON atomically (NaN is refused)."""
    return atomic_write_text(path, json.dumps(data, indent=2, allow_nan=False) + "\n")


def atomic_copy(src: str | Path, dst: str | Path) -> Path:
    """Copies a file atomically."""
    return atomic_write_bytes(dst, Path(src).read_bytes())


@contextlib.contextmanager
def file_lock(path: str | Path) -> Iterator[None]:
    """An exclusive advisory lock (``flock``) on ``path``, for read-modify-write of shared files.

    Works across processes on one machine and on NFS with lock support (SLURM array tasks).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# --------------------------------------------------------------------------------------------
# Shards


@dataclass(frozen=True)
class Shard:
    """This process's share of the work: items ``i`` with ``i % count == index`` (0-based)."""

    index: int = 0
    count: int = 1

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ConfigError(f"shard.count must be >= 1, got {self.count}")
        if not 0 <= self.index < self.count:
            raise ConfigError(
                f"shard.index must be in [0, {self.count - 1}] for shard.count={self.count}, "
                f"got {self.index}"
            )

    @property
    def name(self) -> str:
        return f"{self.index}-of-{self.count}"

    def select(self, items: Sequence[T], key: Any = None) -> list[T]:
        """This shard's items: sorted by ``key`` (default: the items), then every count-th.

        The split is deterministic and independent of input order, and the shards of one
        ``count`` partition the items exactly.
        """
        order = sorted(items, key=key) if key is not None else sorted(items)  # type: ignore[type-var]
        return order[self.index :: self.count]


def resolve_shard(index: int | None, count: int | None, env: dict[str, str] | None = None) -> Shard:
    """The shard from explicit values, else from SLURM's array variables, else ``0 of 1``.

    ``SLURM_ARRAY_TASK_ID`` is taken relative to ``SLURM_ARRAY_TASK_MIN`` so that arrays such as
    ``--array=1-4`` work.
    """
    env = dict(os.environ) if env is None else env

    def _int(name: str) -> int | None:
        raw = env.get(name)
        if raw is None or raw == "":
            return None
        try:
            return int(raw)
        except ValueError:
            raise ConfigError(f"{name}={raw!r} is not an integer") from None

    if count is None:
        count = _int("SLURM_ARRAY_TASK_COUNT") or 1
    if index is None:
        task = _int("SLURM_ARRAY_TASK_ID")
        index = 0 if task is None else task - (_int("SLURM_ARRAY_TASK_MIN") or 0)
    return Shard(index=index, count=count)


# --------------------------------------------------------------------------------------------
# Run store


@functools.cache
def git_sha() -> str | None:
    """The factory checkout's commit (full hex), or None outside a git checkout."""
    here = Path(__file__).resolve().parent.parent
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.stdout.strip() or None if out.returncode == 0 else None


class RunStore:
    """Paths and bookkeeping of one run directory.

    Args:
        run_dir: the run directory (created on first write).
    """

    def __init__(self, run_dir: str | Path) -> None:
        if run_dir is None or str(run_dir).strip() == "":
            raise ConfigError("run_dir is required: pass run_dir=PATH")
        self.root = Path(run_dir)
        if self.root.exists() and not self.root.is_dir():
            raise StoreError(f"run_dir {self.root} exists and is not a directory")

    # ---- layout
    @property
    def manifest_path(self) -> Path:
        return self.root / "manifest.json"

    @property
    def scenes_dir(self) -> Path:
        return self.root / "scenes"

    @property
    def assets_dir(self) -> Path:
        return self.root / "assets"

    @property
    def logs_dir(self) -> Path:
        return self.root / "logs"

    def scene_dir(self, scene_id: str) -> Path:
        return self.scenes_dir / check_id(scene_id, "scene id")

    def scene_json(self, scene_id: str) -> Path:
        return self.scene_dir(scene_id) / "scene.json"

    def model_xml(self, scene_id: str) -> Path:
        return self.scene_dir(scene_id) / "model.xml"

    def renders_dir(self, scene_id: str) -> Path:
        return self.scene_dir(scene_id) / "renders"

    def report_json(self, scene_id: str) -> Path:
        return self.scene_dir(scene_id) / "report.json"

    def asset_dir(self, asset_id: str) -> Path:
        return self.assets_dir / check_id(asset_id, "asset id")

    def episodes_shard(self, shard: Shard) -> Path:
        return self.root / "episodes" / f"shard-{shard.index}.zarr"

    # ---- scenes
    def scene_ids(self) -> list[str]:
        """Ids of scenes that have a ``scene.json`` (sorted)."""
        if not self.scenes_dir.is_dir():
            return []
        return sorted(p.parent.name for p in self.scenes_dir.glob("*/scene.json"))

    def load_scene(self, scene_id: str) -> Scene:
        return load_scene(self.scene_json(scene_id))

    def save_scene(self, scene: Scene) -> Path:
        """Writes ``scenes/<id>/scene.json`` atomically."""
        return atomic_write_text(self.scene_json(scene.id), scene_to_json(scene))

    # ---- stamps (idempotent items)
    def _stamp_path(self, item_dir: Path, step: str) -> Path:
        return item_dir / ".stamps" / f"{step}.json"

    def is_done(self, item_dir: Path, step: str, inputs_digest: str) -> bool:
        """Whether ``step`` finished for this item with the same inputs."""
        path = self._stamp_path(item_dir, step)
        try:
            data = json.loads(path.read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            return False
        return bool(
            data.get("schema_version") == STAMP_SCHEMA_VERSION
            and data.get("inputs") == inputs_digest
            and all((item_dir / o).exists() for o in data.get("outputs", []))
        )

    def mark_done(
        self, item_dir: Path, step: str, inputs_digest: str, outputs: Sequence[str] = ()
    ) -> None:
        """Records that ``step`` finished (call after all outputs are written)."""
        atomic_write_json(
            self._stamp_path(item_dir, step),
            {
                "schema_version": STAMP_SCHEMA_VERSION,
                "step": step,
                "inputs": inputs_digest,
                "outputs": list(outputs),
                "finished": time.time(),
            },
        )

    # ---- manifest
    def read_manifest(self) -> dict[str, Any]:
        """The manifest, or an empty one if the run is new.

        Raises:
            StoreError: the manifest is corrupt or of another schema version.
        """
        try:
            data = json.loads(self.manifest_path.read_text())
        except FileNotFoundError:
            return {"schema_version": MANIFEST_SCHEMA_VERSION, "stages": {}}
        except json.JSONDecodeError as e:
            raise StoreError(
                f"{self.manifest_path} is corrupt ({e.msg}); move it away to start the run afresh"
            ) from None
        if data.get("schema_version") != MANIFEST_SCHEMA_VERSION:
            raise StoreError(
                f"{self.manifest_path} has schema_version {data.get('schema_version')!r}, this "
                f"factory reads {MANIFEST_SCHEMA_VERSION}: use a new run_dir"
            )
        return data

    def update_manifest(self, **changes: Any) -> dict[str, Any]:
        """Read-modify-write of the manifest under a file lock; returns the new manifest."""
        with file_lock(self.root / ".manifest.lock"):
            data = self.read_manifest()
            data.update(changes)
            atomic_write_json(self.manifest_path, data)
            return data

    def record_stage(
        self, stage: str, shard: Shard, status: str, config: dict[str, Any], **info: Any
    ) -> None:
        """Records a stage's status for one shard (``running``, ``done`` or ``failed``)."""
        from factory import __version__

        with file_lock(self.root / ".manifest.lock"):
            data = self.read_manifest()
            data.setdefault("created", time.time())
            data["factory_version"] = __version__
            data["git_sha"] = git_sha()
            data["config"] = config
            stages = data.setdefault("stages", {})
            entry = stages.setdefault(stage, {"shards": {}})
            entry["shards"][shard.name] = {"status": status, "time": time.time(), **info}
            states = {s["status"] for s in entry["shards"].values()}
            entry["status"] = (
                "failed" if "failed" in states else "running" if "running" in states else "done"
            )
            atomic_write_json(self.manifest_path, data)
