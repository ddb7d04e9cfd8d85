"""Where Warp keeps the kernels it compiles (``sim.kernel_cache``), and what is there.

MuJoCo Warp's kernels (physics, the batch renderer) and the factory's own are compiled by Warp
on first use and kept in Warp's kernel cache; a bare machine spends minutes compiling before
its first GPU episode, a machine with the cache filled seconds. ``sim.kernel_cache`` names the
folder (``~`` expanded; created): a shared file system keeps one cache for a cluster's nodes,
or a job can point at node-local scratch. Empty: ``WARP_CACHE_PATH`` where set, else Warp's
default under the user's cache folder (``~/.cache/warp/<version>`` on Linux).

The setting travels as ``WARP_CACHE_PATH``, which Warp reads when it initialises, so the
worker processes a stage spawns use the same folder. This module imports nothing heavy: the
command line calls :func:`configure_kernel_cache` before anything imports MuJoCo or Warp.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from factory.errors import ConfigError

log = logging.getLogger(__name__)

ENV = "WARP_CACHE_PATH"


def configure_kernel_cache(path: str | None) -> Path | None:
    """Points Warp's kernel cache at ``path`` (``sim.kernel_cache``) for this process and its
    children; None or empty leaves Warp's choice. Returns the folder set, or None.

    Raises:
        ConfigError: the folder cannot be created (names the setting).
    """
    if not path:
        return None
    folder = Path(os.path.expanduser(str(path))).resolve()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(
            f"sim.kernel_cache={path!r}: cannot create {folder} ({e.strerror}): choose a "
            "writable folder, or leave it empty for Warp's default"
        ) from None
    os.environ[ENV] = str(folder)
    return folder


def kernel_cache_dir(wp: object | None = None) -> str:
    """The kernel cache Warp uses (after ``wp.init()`` when ``wp`` is given), else the one it
    will use: ``WARP_CACHE_PATH`` or Warp's default."""
    configured = getattr(getattr(wp, "config", None), "kernel_cache_dir", None)
    if configured:
        return str(configured)
    if os.environ.get(ENV):
        return os.path.realpath(os.environ[ENV])
    return str(Path("~/.cache/warp").expanduser())


def cached_modules(folder: str) -> int:
    """Compiled modules in a kernel cache folder: its ``wp_*`` entries, and those of its
    version folders (Warp keeps ``<WARP_CACHE_PATH>/<version>/``); 0 if it is absent."""
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return 0
    count = sum(1 for p in entries if p.name.startswith("wp_"))
    for sub in entries:
        if sub.is_dir() and not sub.name.startswith("wp_"):
            count += sum(1 for p in sub.iterdir() if p.name.startswith("wp_"))
    return count
