"""Quiet terminal: factory's records reach it, third-party output goes to the stage's log file."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from factory.console import FILE_ONLY, TerminalFilter, is_verbose, stderr_to, terminal

# A real stage run by the real runner, in a fresh process: the stage writes to descriptor 2
# from C level and from a child process, logs through third-party loggers, warns and prints to
# sys.stderr; the test checks what reached the process's stderr (the terminal) and the log.
STAGE_SCRIPT = textwrap.dedent(
    """
    import logging, os, subprocess, sys, warnings
    from factory import stages
    from factory.config import FactoryConfig
    from factory.context import StageContext
    from factory.runner import run_stage, setup_logging
    from factory.store import RunStore, Shard

    def chatter(ctx):
        os.write(2, b"c-level chatter\\n")
        subprocess.run(["sh", "-c", "echo child chatter >&2"], check=True)
        logging.getLogger("lerobot").info("third-party info")
        logging.info("root-logger info")
        warnings.warn("a third-party warning")
        print("sys.stderr chatter", file=sys.stderr)
        logging.getLogger("factory.test").info("factory line")
        if os.environ.get("FAIL"):
            raise RuntimeError("boom")
        return {"produced": [{"what": "files", "count": 2, "path": "out", "detail": "tested"}]}

    stages.STAGES["chatter"] = "__main__:chatter"
    run_dir, level = sys.argv[1], sys.argv[2]
    setup_logging(level)
    cfg = FactoryConfig(stage="chatter", run_dir=run_dir, log_level=level)
    try:
        run_stage("chatter", StageContext(cfg=cfg, store=RunStore(run_dir), shard=Shard(0, 1)))
    except RuntimeError:
        print("after the failure", file=sys.stderr)
    os.write(2, b"descriptor 2 restored\\n")
    """
)

CHATTER = (
    "c-level chatter",
    "child chatter",
    "third-party info",
    "root-logger info",
    "a third-party warning",
    "sys.stderr chatter",
)


def _run_stage(tmp_path: Path, level: str, fail: bool = False) -> tuple[str, str]:
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    env = {"FAIL": "1"} if fail else {}
    out = subprocess.run(
        [sys.executable, "-c", STAGE_SCRIPT, str(run), level],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, **env},
    )
    assert out.returncode == 0, out.stderr
    return out.stderr, (run / "logs" / "chatter-0-of-1.log").read_text()


def test_filter_passes_factory_records_and_errors() -> None:
    def record(name: str, level: int, **extra: object) -> logging.LogRecord:
        rec = logging.LogRecord(name, level, __file__, 1, "msg", None, None)
        rec.__dict__.update(extra)
        return rec

    keep = TerminalFilter().filter
    assert keep(record("factory", logging.INFO))
    assert keep(record("factory.demos.stage", logging.DEBUG))
    assert not keep(record("factory_other", logging.INFO))
    assert not keep(record("root", logging.INFO))
    assert not keep(record("py.warnings", logging.WARNING))
    assert not keep(record("OpenGL.acceleratesupport", logging.WARNING))
    assert keep(record("lerobot", logging.ERROR))
    assert not keep(record("factory", logging.INFO, **FILE_ONLY))
    assert is_verbose("DEBUG") and is_verbose("debug")
    assert not is_verbose("INFO") and not is_verbose("nonsense")


def test_stage_output_goes_to_its_log(tmp_path: Path) -> None:
    terminal_text, log = _run_stage(tmp_path, "INFO")
    for text in CHATTER:
        assert text not in terminal_text, terminal_text
        assert text in log, (text, log)
    lines = terminal_text.splitlines()
    assert "INFO factory.test: factory line" in lines[1], lines
    assert lines[2].startswith("stage chatter done in")
    assert lines[3].split() == ["chatter", "2", "files,", "tested", f"{tmp_path}/run/out"]
    assert lines[4].split()[0] == "log" and lines[4].endswith("chatter-0-of-1.log")
    assert lines[-1] == "descriptor 2 restored"
    assert "done in" in log and "'produced'" in log  # the full result, in the log only


def test_failing_stage_restores_descriptor_2(tmp_path: Path) -> None:
    terminal_text, log = _run_stage(tmp_path, "INFO", fail=True)
    assert not any(text in terminal_text for text in CHATTER), terminal_text
    assert terminal_text.splitlines()[-2:] == ["after the failure", "descriptor 2 restored"]
    assert "stage chatter failed" in log and "RuntimeError: boom" in log  # with the traceback
    assert "stage chatter failed" not in terminal_text


def test_verbose_brings_everything_back(tmp_path: Path) -> None:
    terminal_text, log = _run_stage(tmp_path, "DEBUG")
    for text in CHATTER:
        assert text in terminal_text, (text, terminal_text)
    assert "stage chatter done in" in terminal_text
    assert "root-logger info" in log


def test_stderr_to_nests_and_restores(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "x.log"
    with stderr_to(log):
        outer = terminal()
        with stderr_to(tmp_path / "inner.log"):
            assert terminal() is outer  # the outer redirection is kept
        os.write(2, b"to the log\n")
        print("to the terminal", file=terminal(), flush=True)
    assert terminal() is sys.stderr
    assert log.read_text() == "to the log\n"
    assert not (tmp_path / "inner.log").exists()
    assert "to the terminal" in capfd.readouterr().err


def test_verbose_flag_means_log_level_debug() -> None:
    from factory.__main__ import _parse, compose

    overrides, _ = _parse(["stage=list", "log_level=WARNING", "-v"])
    assert overrides[-1] == "log_level=DEBUG"
    assert compose(overrides).log_level == "DEBUG"
    assert _parse(["--verbose", "stage=list"])[0] == ["stage=list", "log_level=DEBUG"]
    assert compose(["stage=list"]).log_level == "INFO"
