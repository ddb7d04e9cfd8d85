"""One set-up search per scene and run: its choices recorded in the run folder.

Every process of ``stage=demos`` that records in a scene sets it up: on a GPU node the main
process and each of the 15 planner processes, at the same moment. For the articulated tasks the
set-up is a search (parts, base spots, the whole motion planned from each, the cameras aimed):
10-25 s of a core each on the busy node, 66 s for the first scene of the 2026-11-29 H200 run,
sixteen times over. :func:`recorded_setup` lets the first process search, under a lock, and
record its choices (for ``open`` and ``close``
:class:`~factory.tasks.articulated.plan.SetupHint`: part, objects cleared, base spot, cameras;
``place_inside`` adds its container) in ``<run_dir>/cache/setups/<scene>-<key>.json``; the
others wait for the lock, read the record and compose the same set-up without searching. A
scene the search finds unusable is recorded too (its reason), so the others refuse it at once
with the same message.

The record's name holds a digest of everything the search depends on (the scene file, the
task's settings, :data:`RECORD_VERSION`): another scene file or setting searches again. Where the
run folder cannot be written (a read-only copy), every process searches, as before.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from factory.errors import TaskError

__all__ = ["RECORD_VERSION", "record_path", "recorded_setup"]

log = logging.getLogger(__name__)

RECORD_VERSION = 1
"""Part of every record's key: raised when the search would choose otherwise for the same
inputs (old records are then not read)."""

SetupT = TypeVar("SetupT")


def record_path(run_dir: str | Path, scene_id: str, key: dict[str, Any]) -> Path:
    """Where the set-up record of ``scene_id`` for ``key`` (the search's settings) lives: its
    name ends with a digest of the scene's file, ``key`` and :data:`RECORD_VERSION`."""
    run = Path(run_dir)
    scene_file = run / "scenes" / scene_id / "scene.json"
    h = hashlib.sha256(scene_file.read_bytes())
    h.update(json.dumps({**key, "record_version": RECORD_VERSION}, sort_keys=True).encode())
    return run / "cache" / "setups" / f"{scene_id}-{h.hexdigest()[:16]}.json"


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Holds an exclusive lock on ``path`` + ``.lock`` (released when the process dies)."""
    with open(path.with_suffix(".lock"), "a+") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def recorded_setup(
    run_dir: str | Path,
    scene_id: str,
    key: dict[str, Any],
    search: Callable[[dict[str, Any] | None], SetupT],
    hint_of: Callable[[SetupT], dict[str, Any]],
) -> SetupT:
    """The scene's set-up: searched by the first process (``search(None)``) and recorded, or
    composed from the record (``search(hint)``).

    Args:
        run_dir, scene_id: the run and the scene.
        key: the settings the search depends on besides the scene file (JSON values).
        search: sets the scene up, searching without a hint, composing the hint's choices with
            one.
        hint_of: a set-up's choices (JSON values; e.g.
            :meth:`~factory.tasks.articulated.plan.SetupHint.to_json`).

    Raises:
        TaskError: the scene cannot host the task (searched now or recorded so).
    """
    from factory.store import atomic_write_json

    def from_record(record: dict[str, Any]) -> SetupT:
        if record.get("error"):
            raise TaskError(record["error"])
        return search(record["hint"])

    try:
        path = record_path(run_dir, scene_id, key)
        if path.is_file():  # written whole (atomically): no lock needed to read it
            return from_record(json.loads(path.read_text()))
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = _locked(path)
        lock.__enter__()
    except OSError as e:
        log.debug("scene %s: no set-up record (%s): searching", scene_id, e)
        return search(None)
    try:
        if path.is_file():  # another process searched while this one waited
            record = json.loads(path.read_text())
        else:
            try:
                setup = search(None)
            except TaskError as e:
                atomic_write_json(path, {"schema_version": 1, "scene": scene_id, "error": str(e)})
                raise
            record = {"schema_version": 1, "scene": scene_id, "hint": hint_of(setup)}
            atomic_write_json(path, record)
            return setup
    finally:
        lock.__exit__(None, None, None)
    return from_record(record)
