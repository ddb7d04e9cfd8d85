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
class AssetsConfig:
    """The asset library (``factory.assets``).

    Attributes:
        backend: ``procedural`` (offline generators), ``mesh_library`` or ``trellis``.
        library_dir: mesh library folder with ``metadata.json`` (``mesh_library``).
        trellis_url: text-to-3D endpoint (``trellis``).
        trellis_timeout: seconds per request.
        trellis_retries: retries after a failed request.
        fallback: fall back to ``procedural`` when the backend fails (logged, recorded).
    """

    backend: str = "procedural"
    library_dir: str | None = None
    trellis_url: str = "http://127.0.0.1:8000/generate"
    trellis_timeout: float = 120.0
    trellis_retries: int = 2
    fallback: bool = True


@dataclass
class GenerateConfig:
    """``stage=generate``: scenes from text requests with the scene agent.

    Attributes:
        prompts: requests, e.g. ``["a cozy bedroom", "a cyberpunk game den"]``.
        prompts_file: a text file with one request per line (``#`` starts a comment).
        task: a robot task ("pick up the mug and put it in the bowl"); alone it is the prompt.
        scenes_per_prompt: scenes per request (seeds ``seed + 1000 * i + k``).
        agent: ``heuristic`` (offline, deterministic per seed) or ``llm``.
        physics_critic: judge every on-top placement in simulation (the paper's critic).
        max_objects: stop adding objects past this count.
        render: write the five renders of each scene.
        transport: how the agent reaches the tools: ``direct`` (in-process calls) or ``mcp``
            (an MCP client session to an in-process MCP server).
        llm_base_url, llm_model: the OpenAI-compatible endpoint of ``agent=llm`` (or the
            environment's ``FACTORY_LLM_BASE_URL`` / ``FACTORY_LLM_MODEL``).
        llm_timeout: seconds per LLM request; llm_retries: retries per request.
        llm_fallback: when the LLM endpoint fails, build the scene with the heuristic agent
            (logged and recorded in report.json) instead of failing.
        image: an image of a room; a VLM describes it and the description is the request.
        vlm_base_url, vlm_model: the OpenAI-compatible VLM endpoint; when set, the VLM also
            critiques each scene's renders and its suggestions are applied once.
    """

    prompts: list[str] = field(default_factory=list)
    prompts_file: str | None = None
    task: str | None = None
    scenes_per_prompt: int = 1
    agent: str = "heuristic"
    physics_critic: bool = True
    max_objects: int = 120
    render: bool = True
    transport: str = "direct"
    llm_base_url: str | None = None
    llm_model: str | None = None
    llm_timeout: float = 60.0
    llm_retries: int = 2
    llm_fallback: bool = True
    image: str | None = None
    vlm_base_url: str | None = None
    vlm_model: str | None = None


@dataclass
class AugmentConfig:
    """``stage=augment``: task-consistent variants of every scene in the run.

    Attributes:
        levels: any of ``layout``, ``category``, ``configuration`` (composed in that order).
        variants_per_scene: variants made per parent scene.
        task_objects: ids of the task-relevant objects; empty: those with a task role.
        physics_critic: judge re-placed objects in simulation while making a variant.
        render: write each kept variant's renders.
    """

    levels: list[str] = field(default_factory=lambda: ["configuration"])
    variants_per_scene: int = 3
    task_objects: list[str] = field(default_factory=list)
    physics_critic: bool = True
    render: bool = True


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
class SimConfig:
    """Batched physics and the stability protocol (the paper's thresholds by default).

    Attributes:
        backend: ``auto`` (warp with CUDA, else cpu), ``cpu``, ``warp`` or ``mjx``.
        nthread: CPU backend threads (0: one per core).
        duration: simulated time per check (s).
        max_translation: an object that moved farther is unstable (m).
        max_rotation_deg: an object that turned more is unstable (deg).
        penetration_tol: candidates starting deeper in each other are invalid (m).
        resettle: accept an unstable candidate if its settled pose is stable on a second run.
        mjx_max_free_bodies: the mjx backend refuses larger models.
        timestep: simulation step of the checks (s); empty keeps the scene model's (2 ms).
    """

    backend: str = "auto"
    nthread: int = 0
    duration: float = 2.0
    max_translation: float = 0.2
    max_rotation_deg: float = 8.0
    penetration_tol: float = 0.01
    resettle: bool = True
    mjx_max_free_bodies: int = 8
    timestep: float | None = None


@dataclass
class ValidateConfig:
    """``stage=validate``: metrics per scene; optional repair.

    Attributes:
        collision_tol: objects interpenetrating deeper than this collide (m).
        trimesh: also run the paper's trimesh ray test for collisions.
        repair: settle unstable objects or remove them (and colliding ones), recording it.
        max_repair_rounds: repair rounds per scene.
    """

    collision_tol: float = 0.01
    trimesh: bool = True
    repair: bool = False
    max_repair_rounds: int = 3


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
class DemosConfig:
    """``stage=demos``: planned, recorded robot demonstrations in every scene (task=...).

    Attributes:
        episodes_per_scene: successful episodes wanted per scene.
        attempts: tries per episode (new object poses and seeds) before it counts as failed.
        batch: episodes planned and executed together (one work item: a scene and up to this
            many of its episode slots).
        workers: processes running work items in parallel (0: one per core; 1: this process).
        nthread: simulation threads per worker (0: the cores divided among the workers).
        randomize: new task-object poses per episode (configuration-level randomization).
        fps: recording rate (Hz).
        width, height: image size (px).
        cameras: ``left``, ``right`` (third-person views of the table), ``wrist``.
        depth: ``uint16_mm`` or ``float32`` (metres).
        render: record images (off: states and robot signals only).
        backend: execution backend: ``cpu`` (mujoco.batch).
        plan_timeout: seconds per RRTConnect query.
        speed: share of the Panda's velocity limit for free motions (acceleration and jerk
            use 0.6 and 0.4 of it).
        max_grasps: grasp candidates tried per episode.
        sleep: let bodies at rest sleep (MuJoCo island sleeping; about 4x faster execution).
            Recorded states replay images exactly either way; stepping the physics from a
            recorded state reproduces the next one exactly only with ``sleep=false`` (sleep
            timers are not part of MuJoCo's state), within ~1e-5 with it.
    """

    episodes_per_scene: int = 4
    attempts: int = 3
    batch: int = 16
    workers: int = 1
    nthread: int = 0
    randomize: bool = True
    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: list[str] = field(default_factory=lambda: ["left", "right", "wrist"])
    depth: str = "uint16_mm"
    render: bool = True
    backend: str = "cpu"
    plan_timeout: float = 5.0
    speed: float = 0.5
    max_grasps: int = 12
    sleep: bool = True


@dataclass
class DatasetConfig:
    """``stage=dataset``: episode stores -> LeRobot v3 datasets, merged across shards.

    Attributes:
        repo_id: the dataset's LeRobot repo id (``<user>/<name>``).
        out: output folder; empty means ``<run_dir>/dataset`` (``shards/``, ``merged/``).
        vcodec: video codec of the camera streams (``h264``, ``hevc``, ``libsvtav1``); depth is
            always lossless RGB h264.
        crf: quality of the camera streams (lower is better and larger; 0-51 for h264).
        preset: x264/x265 speed preset (``ultrafast`` ... ``veryslow``).
        video_file_mb: episodes are appended to one video file per camera until it reaches this
            size (MB). lerobot re-muxes the whole file for every appended episode, so writing
            slows down with larger files (its default, 200 MB, made 32 episodes 10 % slower).
        workers: processes writing one shard (its episodes split into that many parts, joined
            by lerobot's aggregator); the SLURM array script sets it to the task's CPUs.
    """

    repo_id: str = "factory/demos"
    out: str | None = None
    vcodec: str = "h264"
    crf: int = 23
    preset: str = "ultrafast"
    video_file_mb: int = 4
    workers: int = 1


@dataclass
class AllConfig:
    """``stage=all``: the stages to run, in order."""

    stages: list[str] = field(default_factory=lambda: ["ingest", "compile", "validate", "render"])


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
        task: the robot task of ``stage=demos`` (``pick_place``).
    """

    stage: str = "list"
    run_dir: str | None = None
    profile: str = "default"
    seed: int = 0
    force: bool = False
    log_level: str = "INFO"
    task: str = "pick_place"
    shard: ShardConfig = field(default_factory=ShardConfig)
    ingest: IngestConfig = field(default_factory=IngestConfig)
    assets: AssetsConfig = field(default_factory=AssetsConfig)
    generate: GenerateConfig = field(default_factory=GenerateConfig)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    compile: CompileConfig = field(default_factory=CompileConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    validate: ValidateConfig = field(default_factory=ValidateConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    export: ExportConfig = field(default_factory=ExportConfig)
    demos: DemosConfig = field(default_factory=DemosConfig)
    dataset: DatasetConfig = field(default_factory=DatasetConfig)
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
