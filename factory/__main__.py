"""``python -m factory stage=<name> [key=value ...]``: the command line.

The config is composed with Hydra from the structured schema (``factory/config.py``) and the
YAML overrides under ``conf/``, converted to typed dataclasses and dispatched to a stage. The
working directory is never changed and nothing is written outside ``run_dir``.

Bad input (unknown stage, unknown key, bad value, a failing stage) ends with one line
``factory: error: ...`` on stderr and exit status 2 (1 for an unexpected crash).
``-m``/``--multirun`` hands the command to Hydra's own runner (sweeps, launchers).

The terminal is quiet by default: third-party output goes to the stage's log file under
``run_dir/logs/`` and every stage ends with a table of what it produced (:mod:`factory.runner`).
``-v``/``--verbose`` means ``log_level=DEBUG``: everything comes back to the terminal.
"""

from __future__ import annotations

import errno
import logging
import sys
from pathlib import Path
from typing import Any

CONF_DIR = Path(__file__).resolve().parent.parent / "conf"

USAGE = """\
usage: python -m factory stage=<name> [run_dir=PATH] [profile=small|default|full] [key=value ...]

A GPU-parallel batch data factory: physically validated MuJoCo scenes, demonstrations, datasets.

{stages}

common keys:
  run_dir=PATH         the run directory (required by every stage but list)
  profile=NAME         small | default | full
  shard.index=K shard.count=N
                       work on shard K of N (default: SLURM_ARRAY_TASK_ID/COUNT, else 0 of 1)
  force=true           redo finished items
  log_level=DEBUG, -v  everything on the terminal (default: factory's lines, progress bars
                       and a summary table per stage; the rest goes to run_dir/logs/)

examples:
  python -m factory stage=all profile=small run_dir=runs/small
  python -m factory stage=ingest run_dir=runs/r1 ingest.source=path/to/sage_scene.zip
  python -m factory stage=render run_dir=runs/r1 render.width=1024 render.height=768
  python -m factory stage=list --cfg job      # print the composed config
"""


class UsageError(Exception):
    """A problem with the command line itself."""


FREE_FORM = ("train.options",)
"""Keys whose value is a free-form mapping (any policy type, any field): an override adds keys
to it, so it is applied with Hydra's ``++`` (add or merge) instead of failing as unknown."""


def _free_form(arg: str) -> str:
    key = arg.split("=", 1)[0]
    if any(key == k or key.startswith(k + ".") for k in FREE_FORM):
        return "++" + arg
    return arg


def _parse(argv: list[str]) -> tuple[list[str], str | None]:
    overrides, cfg_mode, verbose = [], None, False
    it = iter(argv)
    for arg in it:
        if arg in ("-v", "--verbose"):
            verbose = True
        elif arg == "--cfg":
            cfg_mode = next(it, "job")
        elif arg.startswith("--cfg="):
            cfg_mode = arg.split("=", 1)[1]
        elif arg.startswith("-"):
            raise UsageError(f"unknown option {arg!r} (see python -m factory --help)")
        elif "=" not in arg:
            raise UsageError(
                f"argument {arg!r} is not key=value; did you mean stage={arg}? "
                "(see python -m factory --help)"
            )
        else:
            overrides.append(_free_form(arg))
    if verbose:  # the last value of a key wins
        overrides.append("log_level=DEBUG")
    return overrides, cfg_mode


def _composition_message(exc: BaseException) -> str:
    """One line from Hydra/OmegaConf's composition errors."""
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError, OmegaConfBaseException

    cause: BaseException | None = exc
    while cause is not None:
        unknown = isinstance(cause, ConfigKeyError | ConfigAttributeError) or " not in '" in str(
            cause
        )
        full_key = getattr(cause, "full_key", None)
        if unknown and full_key:
            return (
                f"unknown config key {full_key!r}: check the spelling "
                "(python -m factory stage=list --cfg job prints every key)"
            )
        if isinstance(cause, OmegaConfBaseException) and getattr(cause, "full_key", None):
            first = str(cause).splitlines()[0]
            return f"bad value for {cause.full_key!r}: {first}"
        cause = cause.__cause__ or cause.__context__
    text = " ".join(str(exc).split())
    if "Could not find 'profile/" in text:
        name = text.split("Could not find 'profile/", 1)[1].split("'", 1)[0]
        return f"unknown profile {name!r}: choose small, default or full"
    return text


def compose(overrides: list[str]) -> Any:
    """Composes the config (a typed :class:`~factory.config.FactoryConfig`) from overrides."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from omegaconf import OmegaConf

    from factory.config import register_configs

    register_configs()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = hydra_compose(config_name="config", overrides=overrides)
        return OmegaConf.to_object(cfg)
    except Exception as e:  # Hydra raises several unrelated types here
        raise UsageError(_composition_message(e)) from None
    finally:
        GlobalHydra.instance().clear()


def execute(cfg: Any) -> dict[str, Any]:
    """Runs ``cfg.stage`` (the typed config) and returns its summary."""
    from factory.context import StageContext
    from factory.runner import run_stage, setup_logging
    from factory.sim.gl import configure_gl
    from factory.stages import check_stage
    from factory.store import RunStore, resolve_shard

    check_stage(cfg.stage)
    setup_logging(cfg.log_level)
    configure_gl(cfg.render.gl)  # before anything imports mujoco
    from factory.sim.kernel_cache import configure_kernel_cache

    configure_kernel_cache(cfg.sim.kernel_cache)  # before anything imports warp
    shard = resolve_shard(cfg.shard.index, cfg.shard.count)
    store = None if cfg.run_dir in (None, "") else RunStore(cfg.run_dir)
    return run_stage(cfg.stage, StageContext(cfg=cfg, store=store, shard=shard))


def _multirun(argv: list[str]) -> int:
    """Hands ``-m`` sweeps (and launchers such as submitit) to Hydra's own runner."""
    import hydra
    from omegaconf import DictConfig, OmegaConf

    from factory.config import register_configs

    register_configs()

    @hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
    def _app(cfg: DictConfig) -> None:
        execute(OmegaConf.to_object(cfg))

    verbose = ("-v", "--verbose")
    sys.argv = [sys.argv[0], *("log_level=DEBUG" if a in verbose else a for a in argv)]
    _app()
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if any(a in ("-h", "--help") for a in argv):
        from factory.stages import stage_table

        print(USAGE.format(stages=stage_table()))
        return 0
    if any(a in ("-m", "--multirun") for a in argv):
        return _multirun(argv)
    from factory.errors import FactoryError

    try:
        overrides, cfg_mode = _parse(argv)
        cfg = compose(overrides)
        if cfg_mode is not None:
            from omegaconf import OmegaConf

            print(OmegaConf.to_yaml(OmegaConf.structured(cfg)), end="")
            return 0
        execute(cfg)
    except (UsageError, FactoryError) as e:
        msg = " ".join(str(e).split())
        print(f"factory: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("factory: interrupted; finished items are kept, re-run to resume", file=sys.stderr)
        return 130
    except OSError as e:
        if e.errno not in (errno.ENOSPC, errno.EDQUOT):
            raise
        where = f" writing {e.filename}" if e.filename else ""
        print(
            f"factory: error: {e.strerror}{where}: free space there, or point run_dir (or "
            "dataset.out) at another disk, and re-run; finished items are kept and the "
            "half-written one was removed",
            file=sys.stderr,
        )
        return 2
    finally:
        logging.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
