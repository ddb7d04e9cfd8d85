"""What reaches the user's terminal, and what goes to the stage's log file instead.

Quiet by default. While a stage runs (:func:`stderr_to`, used by :mod:`factory.runner`), file
descriptor 2 points at the stage's log file ``run_dir/logs/<stage>-<shard>.log``, so whatever
third-party code writes to stderr lands there: C libraries (ffmpeg/x264 encoder statistics, GL
notices), Python writes to ``sys.stderr`` and progress bars of libraries (lerobot, datasets),
and worker processes, which inherit the descriptor. Factory's own terminal output goes to
:func:`terminal`, a duplicate of the descriptor the process started with:

* log records through :class:`TerminalHandler` with :class:`TerminalFilter`: the ``factory``
  logger hierarchy at the configured level, and ERROR and up of any other logger (the stage
  log file gets every record, and ``warnings`` through ``logging.captureWarnings``);
* factory's progress bars: ``tqdm(..., file=terminal(), disable=None)``;
* the runner's summary tables (:mod:`factory.summary`).

``log_level=DEBUG`` (``-v``) turns the quiet mode off: every record and every write reaches the
terminal, as without this module (the log file still gets every record).

Only the standard library is imported here.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

FACTORY_LOGGER = "factory"
"""The logger hierarchy that is factory's own (``factory``, ``factory.demos.stage``, ...)."""

OTHERS_LEVEL = logging.ERROR
"""Records of other loggers reach the terminal from this level up (an error there may be why
a stage fails); below it they go to the stage log file only."""

FILE_ONLY: dict[str, Any] = {"terminal": False}
"""``log.info(..., extra=FILE_ONLY)``: a factory record for the log file, not the terminal."""

_terminal: TextIO | None = None
"""The terminal stream while :func:`stderr_to` is active, else None (then ``sys.stderr``)."""


def is_verbose(level: str) -> bool:
    """Whether ``level`` (a logging level name, any case) brings everything to the terminal."""
    number = logging.getLevelName(level.upper())
    return isinstance(number, int) and number <= logging.DEBUG


def terminal() -> TextIO:
    """The stream that reaches the user's terminal (the process's original stderr).

    Inside :func:`stderr_to` it is a duplicate of the original descriptor 2; outside it is
    ``sys.stderr``. Resolve it when writing, not once: it changes as stages start and end.
    """
    return _terminal if _terminal is not None else sys.stderr


class TerminalFilter(logging.Filter):
    """Passes factory's records, and other loggers' records at :data:`OTHERS_LEVEL` and up.

    A record logged with ``extra=FILE_ONLY`` never passes (it is meant for the log file).
    """

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "terminal", True) is False:
            return False
        name = record.name
        if name == FACTORY_LOGGER or name.startswith(FACTORY_LOGGER + "."):
            return True
        return record.levelno >= OTHERS_LEVEL


class TerminalHandler(logging.StreamHandler):
    """A stream handler that writes to :func:`terminal` as it is at each record."""

    def __init__(self) -> None:
        super().__init__(terminal())

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = terminal()  # under the handler's lock (Handler.handle holds it)
        super().emit(record)

    def flush(self) -> None:
        self.acquire()
        try:
            self.stream = terminal()
            super().flush()
        finally:
            self.release()


def _flush_stderr() -> None:
    with contextlib.suppress(Exception):  # a closed or replaced sys.stderr has nothing to keep
        sys.stderr.flush()


@contextlib.contextmanager
def stderr_to(path: Path) -> Iterator[None]:
    """Points file descriptor 2 at ``path`` (appending) while the block runs; restores it after.

    Everything written to descriptor 2 in the meantime, by this process's C libraries, by
    ``sys.stderr`` (whose descriptor is 2) and by child processes started meanwhile, is
    appended to ``path``; :func:`terminal` returns a stream on the original descriptor. The
    original descriptor is restored on the way out, on exceptions too. Nested use keeps the
    outer redirection. Where descriptor 2 cannot be duplicated (closed), nothing is redirected.

    Args:
        path: the log file (created if missing; the stage's ``logging.FileHandler`` appends to
            the same file).
    """
    global _terminal
    if _terminal is not None:
        yield
        return
    _flush_stderr()
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    try:
        target = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    except OSError:
        os.close(saved)
        raise
    encoding = getattr(sys.stderr, "encoding", None) or "utf-8"
    stream = open(  # noqa: SIM115 - closed in the finally below
        saved, "w", encoding=encoding, errors="backslashreplace", buffering=1, closefd=False
    )
    try:
        os.dup2(target, 2)
    finally:
        os.close(target)
    _terminal = stream
    try:
        yield
    finally:
        _flush_stderr()
        os.dup2(saved, 2)
        _terminal = None
        with contextlib.suppress(Exception):
            stream.close()
        os.close(saved)
