"""Typed configuration (Hydra structured configs). No logic beyond registration.

``conf/config.yaml`` and the files under ``conf/`` only override these defaults; an unknown key
anywhere is an error.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from factory.tasks import DEFAULT_TASK


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
        texture_size: size (px) of the procedural assets' textures (64, 128, 256 or 512).
        real_meshes: with the procedural backend, use the textured real meshes that installed
            packages ship with a licence (robosuite's can, bottle, milk, cereal, bread, lemon)
            where one matches the request; ``false``: procedural only.
        articulated: build articulated categories (a cabinet's drawer and door) with moving
            links and joints (``meta.articulation``); ``false``: as one rigid body, closed.
            Other categories are the same either way.
    """

    backend: str = "procedural"
    library_dir: str | None = None
    trellis_url: str = "http://127.0.0.1:8000/generate"
    trellis_timeout: float = 120.0
    trellis_retries: int = 2
    fallback: bool = True
    texture_size: int = 256
    real_meshes: bool = True
    articulated: bool = False


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
        final_check: the last step simulates the whole scene under ``stage=validate``'s
            protocol and repairs it (removes the smaller of two colliding objects, settles or
            removes unstable ones), so that the scene leaves generation valid
            (:mod:`factory.scenes.finish`).
        task_attempts: attempts (seeds ``seed + a * 7919``) at a scene made for a task until
            the task's feasibility critic accepts it; when none does, the scene is not
            written and its ``report.json`` lists each attempt's reason.
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
    final_check: bool = True
    task_attempts: int = 4


@dataclass
class AugmentConfig:
    """``stage=augment``: task-consistent variants of every scene in the run.

    Attributes:
        levels: any of ``layout``, ``category``, ``configuration`` (composed in that order).
        variants_per_scene: variants made per parent scene.
        task_objects: ids of the task-relevant objects; empty: those with a task role.
        physics_critic: judge re-placed objects in simulation while making a variant.
        render: write each kept variant's renders.
        min_distance: configuration variants of a scene differ by at least this move of one
            task object (m), or by ``min_yaw_deg``.
        min_yaw_deg: ... or by at least this turn of one task object (deg).
        batch: candidate rows per batched physics check; 0: by backend (cpu: as many as the
            count needs, at least 4; GPU backends: 2,048 to 8,192).
    """

    levels: list[str] = field(default_factory=lambda: ["configuration"])
    variants_per_scene: int = 3
    task_objects: list[str] = field(default_factory=list)
    physics_critic: bool = True
    render: bool = True
    min_distance: float = 0.03
    min_yaw_deg: float = 15.0
    batch: int = 0


@dataclass
class CompileConfig:
    """``stage=compile``: scene -> MjSpec -> ``model.xml``.

    Attributes:
        ceiling: add a ceiling slab per room (off by default so top views see inside).
        timestep: simulation step (s).
        offscreen_size: offscreen framebuffer (px, square) written into the model.
        textures: procedural textures on floors, walls, ceilings and asset parts (false:
            flat colours).
        texture_size: size (px) of floor, wall and ceiling textures (64, 128, 256 or 512).
        lights: room lighting: ceiling lights per room and a light in every lamp (false: the
            lighting before issue 17, a headlight and a sun).
        light_mesh_edge: longest edge (m) of the visual meshes drawn; longer ones are split so
            that the CPU's OpenGL renderer (lighting per vertex) and MuJoCo Warp's (per ray)
            draw alike (``factory.sim.lit_mesh``); ``0`` (the default): the meshes as built.
            Like the other ``compile.*`` keys it applies where the run's compile options are
            used (``stage=compile``, the generated ``model.xml``, validation); the demos and
            the envs compile their models with the defaults.
    """

    ceiling: bool = False
    timestep: float = 0.002
    offscreen_size: int = 1280
    textures: bool = True
    texture_size: int = 256
    lights: bool = True
    light_mesh_edge: float = 0.0


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
        mjx_max_free_bodies: the mjx backend's JAX implementation (used without CUDA) refuses
            larger models; on CUDA it runs MJX's Warp implementation, for any model.
        timestep: simulation step of the checks (s); empty keeps the scene model's (2 ms).
        sleep: the warp backend lets bodies at rest sleep (MuJoCo island sleeping) and stops a
            batch once all its worlds sleep; ``false`` gives the strict protocol (every step
            of every body), which the benchmark compares it with.
        kernel_cache: the folder where Warp keeps the GPU kernels it compiles (created; ``~``
            expanded), for this stage and the processes it starts: a shared folder spares
            every node of a cluster the minutes of compiling a bare machine spends. Empty:
            ``WARP_CACHE_PATH`` where set, else Warp's default under the user's cache folder
            (``~/.cache/warp``). :mod:`factory.sim.kernel_cache`.
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
    sleep: bool = True
    kernel_cache: str = ""


@dataclass
class ValidateConfig:
    """``stage=validate``: metrics per scene; optional repair.

    Attributes:
        collision_tol: objects interpenetrating deeper than this collide (m).
        trimesh: also run the paper's trimesh ray test for collisions.
        repair: settle unstable objects or remove them (and colliding ones), recording it.
        max_repair_rounds: repair rounds per scene.
        batch_scenes: scenes compiled ahead and checked together: those sharing a layout
            (configuration variants of one scene) run as the candidates of one batched call
            (1: one call per scene).
    """

    collision_tol: float = 0.01
    trimesh: bool = True
    repair: bool = False
    max_repair_rounds: int = 3
    batch_scenes: int = 64


@dataclass
class RenderConfig:
    """``stage=render``: top-down, plan, corner and per-room views (PNG) of each scene.

    Attributes:
        width, height: image size (px).
        views: which views to write (``top``, ``plan`` (orthographic floor plan),
            ``corner_0`` .. ``corner_3``, ``rooms`` (one ``room_<id>`` per room of a home),
            ``room_<id>``).
        gl: OpenGL backend: ``auto`` (EGL, then OSMesa), ``egl``, ``osmesa``, ``glfw``.
    """

    width: int = 640
    height: int = 480
    views: list[str] = field(
        default_factory=lambda: [
            "top",
            "plan",
            "corner_0",
            "corner_1",
            "corner_2",
            "corner_3",
            "rooms",
        ]
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
class AppearanceConfig:
    """``demos.appearance``: appearance randomisation per episode (domain randomisation for
    policy data), drawn from the episode's seed and recorded in its metadata
    (``EpisodeInfo.appearance``). The task objects and the robot never change.

    Attributes:
        enabled: randomise (off: every episode sees the scene's own look).
        colors: tint background objects, floors and walls (``color_jitter``).
        textures: dress a share (``texture_swap``) of the background objects in the materials
            (textures and colours) of another object of the scene.
        lights: move the ceiling lights (``light_pos``) and scale the intensity
            (``light_intensity``) and colour (``light_color``) of every light.
        camera: move the recording cameras (``camera_pos``) and turn them
            (``camera_angle``).
        color_jitter: largest relative change of a colour channel (0.15: x0.85 .. x1.15,
            a common factor for brightness and a smaller one per channel).
        texture_swap: share of the background objects that wear another object's materials.
        light_pos: largest horizontal shift of a ceiling light (m).
        light_intensity: largest relative change of a light's intensity.
        light_color: largest warm/cool shift of a light's colour (relative, red against
            blue).
        camera_pos: largest shift of a camera along each axis (m).
        camera_angle: largest rotation of a camera (deg).
        scene_camera_pos: largest shift (m) of a camera placed in the scene (on a static body:
            ``left``, ``right``; not one riding on the robot) where larger than
            ``camera_pos`` (0: ``camera_pos``). Such cameras' poses are recorded per episode
            (their calibration), so a wider range teaches a perception many viewpoints.
        scene_camera_angle: largest rotation (deg) of a camera placed in the scene where larger
            than ``camera_angle`` (0: ``camera_angle``).
    """

    enabled: bool = True
    colors: bool = True
    textures: bool = True
    lights: bool = True
    camera: bool = True
    color_jitter: float = 0.15
    texture_swap: float = 0.3
    light_pos: float = 0.3
    light_intensity: float = 0.3
    light_color: float = 0.1
    camera_pos: float = 0.01
    camera_angle: float = 1.5
    scene_camera_pos: float = 0.0
    scene_camera_angle: float = 0.0


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
        appearance: appearance randomisation per episode (colours, textures, lights, camera
            poses; :class:`AppearanceConfig`, on by default; both executors apply it: the
            ``warp`` executor sets each world's copy of the changed model fields when an
            episode starts in it, so images and metadata match the ``cpu`` executor's).
        shadows: the recording's images have the ceiling lights' shadows (MuJoCo's shadow
            maps cost about 2.5x the rendering time per image on a CPU, so they are off by
            default; scene renders have them).
        fps: recording rate (Hz).
        width, height: image size (px).
        cameras: ``left``, ``right`` (third-person views of the table), ``wrist``.
        depth: ``uint16_mm`` or ``float32`` (metres).
        render: record images (off: states and robot signals only).
        executor: where episodes are executed and recorded: ``cpu`` (``mujoco.batch`` threads
            and EGL/OSMesa rendering in ``workers`` processes), ``warp`` (the GPU: the
            episodes of a scene as worlds of one MuJoCo Warp model, rendered by its batch
            renderer; ``workers`` processes plan), ``auto`` (``warp`` when CUDA is present).
        gpu_batch: most worlds per GPU call of the ``warp`` executor; a call packs a scene's
            episodes onto its worlds back to back (a world starts its next episode as soon as
            its last one ends), so it may run more episodes than worlds.
        gpu_retries: where the ``warp`` executor runs a scene's episodes that failed in
            execution, with their next seeds: ``cpu`` (the planner processes execute and
            record them with the CPU executor while the GPU goes on to the next scene; their
            metadata says ``recorder: cpu``) or ``gpu`` (one more small GPU call per scene,
            which costs the GPU 6-14 s for 2-19 episodes).
        gpu_tail: share of a scene's planned episodes, the longest, that the ``warp``
            executor leaves to the planner processes' CPU executor (with
            ``gpu_retries=cpu``; 0: none). A GPU call lasts as long as its longest episode
            and a period costs nearly the same for 500 worlds as for 1,000, so the rare long
            plans (a kitchen's longest of 1,536 ran 24 s against a median of 9 s) would set
            the length of the whole call; without them the call is shorter and has more
            worlds.
        gpu_images_on_device: the ``warp`` executor keeps a call's images on the device and
            copies them to host memory at the end of the call (one call's recordings in host
            memory at a time, so calls of ~1,000 worlds fit); false copies every frame to the
            host as it is drawn (docs/DEMOS.md has both modes' measured rates).
        episode_physics: where the ``warp`` executor simulates the episodes of the tasks that
            simulate their own (``demo_execution = "episode"``): ``auto`` (MuJoCo Warp in the
            main process where the task's scene can record an episode from simulated states:
            ``open``, ``close``; else the CPU), ``warp`` (MuJoCo Warp; an error for a task
            that cannot) or ``cpu`` (the planner processes simulate each episode on the CPU and
            the GPU only draws it; :mod:`factory.demos.episode_physics`).
        plan_timeout: seconds per RRTConnect query.
        speed: share of the Panda's velocity limit for free motions (acceleration and jerk
            use 0.6 and 0.4 of it).
        max_grasps: grasp candidates tried per episode.
        grasp_facing: weight of the preference for grasps on the side of the object facing the
            robot, held in one of the gripper's two symmetric orientations. Demos that grasp
            the same way each time are what an imitation policy can learn (random rim points
            around a mug taught it every azimuth at once); 0 keeps the geometric ranking.
        sleep: let bodies at rest sleep (MuJoCo island sleeping; about 4x faster execution).
            Recorded states replay images exactly either way; stepping the physics from a
            recorded state reproduces the next one exactly only with ``sleep=false`` (sleep
            timers are not part of MuJoCo's state), within ~1e-5 with it.
        freeze_beyond: objects whose footprint stays farther than this from the robot's base
            (m, horizontally; the arm reaches 0.86 m), and floor furniture, are simulated
            static, without a free joint: a kitchen's 350 degrees of freedom become a few
            dozen, which is what makes the GPU executor fast (its cost grows with the degrees
            of freedom of every world, asleep or not). The task objects, and whatever stands
            on a movable object left free, stay free. ``0`` keeps every object free.
        lookalike_radius: other movable objects of the pick object's or the target's category
            within this distance of the robot's base (m, horizontally) leave the scene with
            what stands on them (``task=pick_place``), so that "the mug" is the one mug near
            the robot, as an image policy must see it. ``0`` keeps them.
    """

    episodes_per_scene: int = 4
    attempts: int = 3
    batch: int = 16
    workers: int = 1
    nthread: int = 0
    randomize: bool = True
    appearance: AppearanceConfig = field(default_factory=AppearanceConfig)
    shadows: bool = False
    fps: float = 20.0
    width: int = 128
    height: int = 128
    cameras: list[str] = field(default_factory=lambda: ["left", "right", "wrist"])
    depth: str = "uint16_mm"
    render: bool = True
    executor: str = "auto"
    gpu_batch: int = 512
    gpu_retries: str = "cpu"
    gpu_tail: float = 0.01
    gpu_images_on_device: bool = True
    episode_physics: str = "auto"
    plan_timeout: float = 5.0
    speed: float = 0.5
    max_grasps: int = 12
    grasp_facing: float = 1.0
    sleep: bool = True
    freeze_beyond: float = 1.0
    lookalike_radius: float = 1.5


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
class TrainConfig:
    """``stage=train``: a lerobot policy trained on the run's merged dataset.

    Attributes:
        name: the policy's name: ``<run_dir>/policy/<name>/`` (checkpoints, ``train.json``,
            ``train_log.jsonl``); ``stage=eval`` evaluates it by this name.
        policy: lerobot policy type by name (``diffusion``, ``act``, ... any in lerobot's
            registry).
        inputs: ``state`` (joints, gripper, tool pose and the pick and target objects' poses),
            ``rgb`` (the recorded cameras' images + joints, gripper, tool pose) or ``rgbd``
            (RGB and depth of every camera + the same; the paper's setting).
        action: what the model predicts: ``tool`` (the tool pose in the robot's base frame +
            gripper, turned into joint targets by IK at execution; the paper's end-effector actions,
            and what generalises from few demos), ``tool_rel`` (the same with positions relative to
            the tool at each action chunk's start) or ``joint`` (the dataset's 8-D joint-target
            action as it is). ``lerobot-eval`` runs ``tool`` and ``joint`` policies (its env takes
            the policy's action; :mod:`factory.policy.lerobot_plugin`).
        dataset: the merged LeRobot dataset (empty: ``<run_dir>/dataset/merged``).
        scenes: the dataset's scenes trained on: empty (all), a number ``N`` (the first ``N``
            of its scene ids, sorted) or a list of ids; the other scenes' episodes are never
            sampled and their frames not in the statistics (the scaling experiment trains on
            1, 2, 4, ... scenes of one dataset).
        horizon: actions predicted per inference (``horizon``, ACT's ``chunk_size``); 0: the
            policy's default or ``options``.
        n_obs_steps: observation frames per inference; 0: the policy's default.
        n_action_steps: predicted actions executed before the next inference; 0: default.
        steps: optimizer steps in all (a resumed training continues up to it).
        batch_size: samples per step.
        lr: learning rate; 0: the policy's preset.
        seed: seed of initialisation and sampling.
        device: ``auto`` (CUDA when present), ``cpu`` or ``cuda``.
        num_workers: DataLoader processes (0: in the training process).
        loader: ``device`` gathers each batch by index from features and frames held in
            device memory (or pinned host memory where they do not fit), with image
            augmentation on the batch (:mod:`factory.policy.device_batches`); ``dataloader``
            builds samples in Python and collates them (torch's DataLoader, ``num_workers``);
            ``auto``: ``device`` on CUDA when the frames are in memory, else ``dataloader``.
        video_cache: image policies: ``auto`` decodes the videos read into memory once when
            they take less than half of the available memory (uint8 RGB, uint16 depth: 82 kB
            a frame of one camera at 128 x 128), ``memory`` always, ``off`` decodes the frames
            of each sample (lerobot's way: seek and decode, tens of ms a frame).
        threads: torch CPU threads (0: torch's default, ``OMP_NUM_THREADS``).
        save_every: steps between checkpoints (and after the last step).
        log_every: steps between lines of ``train_log.jsonl``.
        keep_checkpoints: newest checkpoints kept.
        max_minutes: wall-clock limit of this call's optimizer steps (0: none): past it the
            training saves a checkpoint and stops early (a re-run continues up to ``steps``),
            for jobs with a time limit.
        augment_images: lerobot's image transforms on RGB (colour jitter, sharpness, small
            affine) and a random 90 % crop where the policy has one (diffusion).
        augment_shading: strength of the shading augmentation of RGB images
            (:mod:`factory.policy.shading`: a smooth gain field of ``1 +- strength``, a gain per
            colour channel, soft highlights; what OpenGL's and MuJoCo Warp's images disagree
            on), 0 (off) to 0.5; independent of ``augment_images``.
        precision: ``auto`` (bf16 autocast on CUDA, fp32 on a CPU), ``bf16`` or ``fp32``; the
            weights, optimizer and checkpoints stay fp32.
        aux_state: weight of an auxiliary loss for image policies of a dataset that records
            the object poses (``observation.environment_state``: the fixed-base task's, and the
            mobile task's exported since it has one): a small head predicts the pick object's
            and target's poses (in the arm's base frame) from the image features, so that the
            encoder learns where the objects are; the head is dropped from the policy (a plain
            lerobot checkpoint). None: 1.0 for ``rgb``/``rgbd`` diffusion, 0 (off) otherwise
            and without the poses.
        ema: decay of an exponential moving average of the weights, saved as the checkpoint's
            policy (the raw weights go to ``training_state`` for resuming). None: 0.999 for
            ``rgb``/``rgbd`` diffusion, 0 (off) otherwise.
        compile: ``torch.compile`` the policy's image encoder and U-Net in place
            (``nn.Module.compile``: the checkpoint's keys do not change) to fuse their
            normalisations and activations; the first step waits for the compiler (about
            2 minutes on a bare H100). None: on for ``rgb``/``rgbd`` diffusion on CUDA.
        eval_every_minutes: the learning curve: every this many minutes of training (0: never)
            the newest weights are evaluated in the held-out scenes by ``stage=eval`` in a
            background process (``eval.*`` settings; ``policy/<name>/curve/<step>/``) while
            training goes on; success against steps and seconds goes into ``train_log.jsonl``
            and the report; the last step is evaluated too.
        eval_episodes: episodes per scene of each learning-curve evaluation.
        gpus: data-parallel processes on one node (``cuda:0`` .. ``cuda:N-1``; with
            ``train.device=cpu``, CPU processes): each trains on its own ``batch_size``
            samples and the gradients are averaged (:mod:`factory.policy.data_parallel`).
        options: policy config fields per type, e.g. ``{diffusion: {down_dims: [64, 128]}}``;
            applied to the type trained, others ignored.
        vision: how an ``rgb``/``rgbd`` policy reads its cameras:
            ``end_to_end`` (lerobot's image encoder inside the policy, trained by the policy's
            loss with ``aux_state``) or ``perception`` (a perception network predicts the object
            poses from the newest frame and lerobot's diffusion policy, the state recipe, acts
            on them: :mod:`factory.policy.perception`; the dataset must record the poses).
        perception_noise_m: ``vision=perception``: standard deviation (m, per axis) of the
            Gaussian offset added to each object's recorded position while the policy trains,
            so that it acts on a perception's errors.
        cameras: the cameras an ``rgb``/``rgbd`` policy reads, e.g. ``[wrist]`` (empty: every
            camera the dataset records); the evaluation renders those only.
        perception_points: ``vision=perception`` with ``rgbd``: the pixels of every camera
            whose pose is known enter the network as points in the robot's base frame, which
            its keypoints read: the wrist camera's (forward kinematics and depth) and, where
            the dataset has ``observation.camera_poses``, the left and right cameras' (their
            recorded calibration; the env observes it too). Mobile datasets have none: the
            wrist camera's points only, the other cameras as images.
        perception_objects: with ``perception_points``, the objects' positions are read from
            the points under two keypoints per point camera, trained to find the pick object
            and the target at their projected pixels (a heatmap loss), weighted across cameras,
            plus a small learned correction; the tool's offsets follow from the wrist camera's
            pose. ``false``: an MLP regresses every value from the features.
    """

    name: str = "${train.policy}_${train.inputs}"
    policy: str = "diffusion"
    inputs: str = "state"
    action: str = "tool"
    dataset: str | None = None
    scenes: Any = None
    horizon: int = 0
    n_obs_steps: int = 0
    n_action_steps: int = 0
    steps: int = 20000
    batch_size: int = 64
    lr: float = 0.0
    seed: int = 0
    device: str = "auto"
    num_workers: int = 0
    loader: str = "auto"
    video_cache: str = "auto"
    threads: int = 0
    save_every: int = 2000
    log_every: int = 100
    keep_checkpoints: int = 2
    max_minutes: float = 0.0
    augment_images: bool = True
    augment_shading: float = 0.0
    precision: str = "auto"
    aux_state: float | None = None
    ema: float | None = None
    compile: bool | None = None
    eval_every_minutes: float = 0.0
    eval_episodes: int = 10
    gpus: int = 1
    options: dict[str, Any] = field(default_factory=dict)
    vision: str = "end_to_end"
    perception_noise_m: float = 0.01
    cameras: list[str] = field(default_factory=list)
    perception_points: bool = True
    perception_objects: bool = True


@dataclass
class EvalConfig:
    """``stage=eval``: closed-loop rollouts in the simulation env, with success rates.

    Attributes:
        policy: what acts: a trained policy's name (``policy/<name>/``; empty: the one
            ``stage=train`` writes, ``train.name``), a path to a lerobot ``pretrained_model``
            folder, ``replay`` (the dataset's recorded actions from each episode's recorded
            initial state: do the env and the data agree?) or ``planner`` (the demos' planner
            on the evaluation configurations: the privileged agent).
        scenes: ``heldout`` (the run's scenes that are not in the training dataset, the
            paper's protocol), ``train`` (the dataset's scenes) or a list of scene ids;
            ``replay`` always replays the dataset's episodes (of these scenes, if a list).
        episodes_per_scene: initial configurations per scene (the paper: 90).
        seed: root of the evaluation seeds (a namespace disjoint from the demos' seeds).
        max_steps: frames per episode before it fails with a time-out (0: 1.5x the longest
            training episode, else 400); replay and planner run their own length.
        batch: episodes of a scene simulated together (0: all of a scene's, at most 16).
        workers: processes that run batches side by side, each with its own simulation,
            renderer and copy of the policy (0: one per 4 cores); image policies are bound by
            rendering on the CPU, so a many-core node evaluates them about ``workers`` times
            faster.
        nthread: simulation threads per process (0: the cores shared among the workers).
        videos: rollouts written as mp4 under ``eval/<policy>/videos``.
        env_state: observe ``observation.environment_state`` even if the policy does not use it.
        interpolate: the env's controller moves the arm target linearly over a frame from the
            previous action with the demos' velocity lead (false: holds each action).
        dataset: the training dataset (default: the policy's, or ``<run_dir>/dataset/merged``).
        device: torch device of a trained policy (``auto``, ``cpu``, ``cuda``).
        name: the results folder ``eval/<name>/`` (empty: the policy's name, ``replay`` or
            ``planner``); another name keeps a second evaluation of the same policy apart
            (e.g. on the training scenes).
        out: the results folder itself (empty: ``<run_dir>/eval/<name>``); the learning curve
            of ``stage=train`` writes under ``policy/<name>/curve/<step>``.
        executor: the env's simulation: ``cpu`` (MuJoCo on the cores, OpenGL cameras) or
            ``warp`` (MuJoCo Warp on the GPU, a scene's episodes as the worlds of one model,
            cameras drawn by its batch renderer; one worker process and ``eval.batch`` all
            of a scene's episodes unless set; the task's checks stay the CPU's:
            :mod:`factory.policy.warp_sim`), or ``warp_opengl`` (a diagnostic: MuJoCo Warp's
            physics, the cameras drawn by OpenGL from each world's state as the CPU env draws
            them: beside ``cpu`` and ``warp`` it tells a renderer's share of a disagreement
            from the physics').
        ensemble: temporal ensembling of a trained diffusion policy's chunks
            (:class:`factory.policy.checkpoint.ChunkEnsemble`): a chunk every
            ``ensemble_every`` frames, each frame's action the mean of every kept chunk's
            prediction for it weighted
            ``exp(-k * age)``, oldest first. None: on with ``k = 0.1`` where it applies
            (diffusion, ``tool`` or ``joint`` actions, not the mobile robot), else off; a
            negative value: off (``n_action_steps`` actions of each chunk, lerobot's way);
            ``k >= 0``: on with this ``k`` (refused where it does not apply).
        ensemble_every: with ensembling, a new chunk every this many frames (1: every frame;
            m: about m times less inference, the kept chunks still averaged every frame;
            default 2: on one state policy 94.4 % held out against 87.8 % every frame, in
            43 % of the time, ``benchmarks/results/policy-ensemble-every-cpu2.json``).
    """

    policy: str = ""
    scenes: Any = "heldout"
    episodes_per_scene: int = 10
    seed: int = 0
    max_steps: int = 0
    batch: int = 0
    workers: int = 1
    nthread: int = 0
    videos: int = 2
    env_state: bool = False
    interpolate: bool = True
    dataset: str | None = None
    device: str = "auto"
    name: str = ""
    out: str = ""
    executor: str = "cpu"
    ensemble: float | None = None
    ensemble_every: int = 2


@dataclass
class ReportConfig:
    """``stage=report``: the run's HTML report, ``<run_dir>/report.html``.

    Attributes:
        embed: images and GIFs as data URIs inside the page (one file to send around); false:
            thumbnails and GIFs written under ``<run_dir>/report_files/`` and linked relatively.
        views: render views shown per scene (``top``, ``corner_0`` .. ``corner_3``).
        max_scenes: scenes (and augmented variants) shown with thumbnails; the validation
            table lists every scene.
        thumb_width: width of the render thumbnails (px).
        gifs: demonstration GIFs made from the recorded frames of stored episodes.
        gif_camera: the camera of the demonstration GIFs (empty: each episode's first).
        gif_fps: frame rate of the GIFs (Hz; frames are subsampled to it).
        gif_size: longest side of a GIF (px).
        eval_videos: rollout videos per evaluated policy shown as GIFs.
    """

    embed: bool = True
    views: list[str] = field(default_factory=lambda: ["top", "corner_0"])
    max_scenes: int = 24
    thumb_width: int = 240
    gifs: int = 4
    gif_camera: str = ""
    gif_fps: float = 10.0
    gif_size: int = 128
    eval_videos: int = 2


@dataclass
class AllConfig:
    """``stage=all``: the stages to run, in order."""

    stages: list[str] = field(
        default_factory=lambda: ["ingest", "compile", "validate", "render", "report"]
    )


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
    task: str = DEFAULT_TASK
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
    train: TrainConfig = field(default_factory=TrainConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    report: ReportConfig = field(default_factory=ReportConfig)
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
