"""Typed configuration (Hydra structured configs). No logic beyond registration.

``conf/config.yaml`` and the files under ``conf/`` only override these defaults; an unknown key
anywhere is an error.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ShardConfig:
    """Which share of the work items this process does.

    Unset values default from ``SLURM_ARRAY_TASK_ID`` / ``SLURM_ARRAY_TASK_COUNT``, else 0 of 1.
    """

    index: int | None = None
    count: int | None = None


@dataclass
class IngestConfig:
    """``stage=ingest``: bring scenes into the run directory.

    Attributes:
        source: a ``scene.json``, a SAGE layout JSON, a packed SAGE folder or zip, or a folder
            of any of these; empty means the bundled example scenes named in ``examples``.
        examples: bundled example scenes (``factory/data/examples/<name>``).
    """

    source: str | None = None
    examples: list[str] = field(default_factory=lambda: ["kitchen_pick_place"])


@dataclass
class CompileConfig:
    """``stage=compile``: scene -> MjSpec -> ``model.xml``.

    Attributes:
        ceiling: add a ceiling slab per room (off by default so top views see inside).
        timestep: simulation step (s).
        offscreen_size: offscreen framebuffer (px, square) written into the model.
    """

    ceiling: bool = False
    timestep: float = 0.002
    offscreen_size: int = 1280


@dataclass
class RenderConfig:
    """``stage=render``: top-down and four corner views (PNG) of each scene.

    Attributes:
        width, height: image size (px).
        views: which views to write (``top``, ``corner_0`` .. ``corner_3``).
        gl: OpenGL backend: ``auto`` (EGL, then OSMesa), ``egl``, ``osmesa``, ``glfw``.
    """

    width: int = 640
    height: int = 480
    views: list[str] = field(
        default_factory=lambda: ["top", "corner_0", "corner_1", "corner_2", "corner_3"]
    )
    gl: str = "auto"


@dataclass
class ExportConfig:
    """``stage=export``: write scenes back out in another format.

    Attributes:
        format: ``sage`` (SAGE's packed layout: ``<id>.json`` + ``objects/*.ply``).
        out: output folder; empty means ``<run_dir>/export/<format>``.
    """

    format: str = "sage"
    out: str | None = None


@dataclass
class AllConfig:
    """``stage=all``: the stages to run, in order."""

    stages: list[str] = field(default_factory=lambda: ["ingest", "compile", "render"])


@dataclass
class FactoryConfig:
    """The root config of ``python -m factory``.

    Attributes:
        stage: which stage to run (``python -m factory stage=list`` lists them).
        run_dir: the run directory every stage reads from and writes to (required by stages
            that touch data; never the working directory implicitly).
        profile: the profile name (set by ``profile=small|default|full``).
        seed: the root random seed.
        force: redo finished items instead of skipping them.
        log_level: ``DEBUG``, ``INFO``, ``WARNING`` or ``ERROR``.
    """

    stage: str = "list"
    run_dir: str | None = None
    profile: str = "default"
    seed: int = 0
    force: bool = False
    log_level: str = "INFO"
    shard: ShardConfig = field(default_factory=ShardConfig)
    ingest: IngestConfig = field(default_factory=IngestConfig)
    compile: CompileConfig = field(default_factory=CompileConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    export: ExportConfig = field(default_factory=ExportConfig)
    all: AllConfig = field(default_factory=AllConfig)


def register_configs() -> None:
    """Registers the structured configs with Hydra's ConfigStore (idempotent)."""
    from hydra.core.config_store import ConfigStore
    from omegaconf import OmegaConf

    ConfigStore.instance().store(name="factory_schema", node=FactoryConfig)
    # ``${factory_sweep_dir:${run_dir}}``: where Hydra's multirun bookkeeping goes.
    OmegaConf.register_new_resolver("factory_sweep_dir", _sweep_dir, replace=True)


def _sweep_dir(run_dir: str | None) -> str:
    import tempfile

    return f"{run_dir}/logs/multirun" if run_dir else f"{tempfile.gettempdir()}/factory-multirun"
