"""The :class:`Task` protocol: the hooks that the task-agnostic machinery calls.

The machinery is written once and takes a task: scene generation, augmentation and validation
ask it what a scene must hold (:meth:`Task.claims`, :meth:`Task.scene_check`); ``stage=demos``
(one stage, one CPU item loop, one GPU pipeline) asks it to plan and record episodes; the
LeRobot export takes its features; the evaluation env its set-up, observations, actions and
success check. Hooks are grouped by the floor that calls them; a hook's heavy imports happen
inside it, so that the lower floors can hold a task without loading its planner.

A task class sets :attr:`Task.name` (its registry key, :data:`factory.tasks.TASKS`) and
:attr:`Task.description`, and fills the hooks; like ManiSkill's ``_load_scene`` /
``_initialize_episode`` / ``evaluate``, each hook is one question about the task.

A task is one package (``factory/tasks/<name>/``): ``task.py`` holds the class, cheap to
import, and the hooks that read data of a heavier floor default to the package's module of
that floor (:meth:`Task.part`): ``demos.py`` (``demo_scene``), ``dataset.py`` (``LAYOUT``,
``ROBOT_TYPE``, ``features``, ``arrays_of``, ``columns``, ``card``) and ``env.py``
(``OBSERVATIONS``, ``action_bounds``); a task overrides a hook where it needs more.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:
    from types import ModuleType

    from factory.schema import Scene

__all__ = ["Task"]


class Task:
    """A robot task (subclass per task; one instance per process,
    :func:`~factory.tasks.get_task`)."""

    name: ClassVar[str]
    """Registry key: ``task=<name>`` on the command line, ``task.kind`` in ``scene.json``."""

    description: ClassVar[str]
    """One line: what the robot does (``stage=list`` and the run report show it)."""

    def part(self, module: str) -> ModuleType:
        """The task package's module ``module`` (``demos``, ``dataset``, ``env``), imported on
        first use: where the hooks' defaults read the task's data and functions."""
        package = type(self).__module__.rpartition(".")[0]
        return importlib.import_module(f"{package}.{module}")

    # -- scenes: generation, augmentation, validation (floors 4-5) -----------------------------

    def claims(self, scene: Scene) -> bool:
        """Whether ``scene`` was made for this task (by default: its ``task.kind`` names it)."""
        return scene.task is not None and scene.task.kind == self.name

    def matches_request(self, spec: dict[str, Any]) -> bool:
        """Whether a parsed request's task asks for this task: the fields of a ``TaskSpec``
        (:mod:`factory.scenes.task_read`: ``pick``, ``target``, ``source``, ``travel``, ...)
        or a ``PartSpec`` (:mod:`factory.scenes.part_read`: ``action``, ``role``,
        ``category``, ...); the scene agent writes the first matching task's name as the
        scene's ``task.kind``."""
        return False

    request_verbs: ClassVar[tuple[str, ...]] = ()
    """Verbs of a request that asks the task to move a part of an articulated object ("open",
    "opens", "shut", ...): the request parser reads "<verb> the <part> [of the <object>]" with
    them (:mod:`factory.scenes.part_read`); none by default."""

    articulated_assets: ClassVar[bool] = False
    """A scene made for the task needs articulated furniture (doors and drawers that move):
    ``stage=generate`` builds its assets articulated (``assets.articulated``) whatever the
    setting says, and logs it."""

    def feasibility(self, scene: Scene, assets_root: Path | None) -> dict[str, Any] | None:
        """The task's feasibility critic: whether ``scene``, made for this task, can host its
        episodes, as ``{"reason": "" (it can) or why not, "detail": one line, ...}``; None:
        the task has no such critic (by default; a task that drives its base is judged by
        its route, :mod:`factory.nav.route`). ``stage=generate``'s last step makes another
        attempt with another seed when it fails (:mod:`factory.scenes.finish`), and
        ``stage=validate`` reports it (``validate.checks.task``)."""
        return None

    example_request: ClassVar[str | None] = None
    """A request whose generated scene suits the task (``stage=generate``), or None."""

    example_scene: ClassVar[str | None] = None
    """A small scene made for the task, bundled with the package: its ``scene.json``'s folder
    below ``factory/data/`` (:meth:`example_scene_path`), or None. A task gives an example
    request or scene (or both): the registry's smoke test records, exports and replays an
    episode in it."""

    def example_scene_path(self) -> Path | None:
        """The bundled example scene's ``scene.json`` (None without one)."""
        if self.example_scene is None:
            return None
        return Path(__file__).resolve().parent.parent / "data" / self.example_scene / "scene.json"

    drives_base: ClassVar[bool] = False
    """The robot drives between supports: a scene made for the task needs a route for its base
    (:mod:`factory.nav.route`: checked by the generation critic, ``stage=validate`` and the
    configuration variants)."""

    # -- demos: stage=demos, one CPU item loop and one GPU pipeline (floor 7) ------------------
    # The machinery (factory.demos: slots, seeds, retries, executors, writers, statistics) asks
    # the task for a scene set up to record (demo_scene: set-up, planner, what an episode is
    # stored as) and runs its plans the way demo_execution says.

    demo_execution: ClassVar[str]
    """How ``stage=demos`` executes the task's plans, a key of
    :data:`factory.demos.execution.EXECUTIONS`: ``batch``: open-loop control sequences run
    together on a batch of worlds by the executors of :mod:`factory.demos.execute`
    (``mujoco.batch`` on the CPU; physics and images on MuJoCo Warp's worlds with the GPU
    executor); ``episode``: the task simulates each episode itself, one at a time
    (:class:`~factory.demos.record.scene.SimulatingScene`), and the GPU executor only draws
    the recorded states."""

    def demo_scene(self, env: Any, scene_id: str, plan: bool = True) -> Any:
        """Scene ``scene_id`` of the run set up to record the task's episodes: a
        :class:`~factory.demos.record.scene.DemoScene` (a
        :class:`~factory.demos.record.scene.SimulatingScene` for ``demo_execution =
        "episode"``).

        Args:
            env: the stage's settings (a :class:`~factory.demos.record.slots.StageEnv`: run
                directory, ``demos.*``, task, root seed).
            scene_id: the scene.
            plan: with its planner; False in a process that only records (the GPU pipeline's
                main process).

        Raises:
            FactoryError: the scene cannot host the task (the scene's
                ``failures.scene_unusable``).
        """
        return self.part("demos").demo_scene(env, scene_id, plan)

    # -- dataset: the LeRobot export (floor 8) --------------------------------------------------
    # One export path (factory.dataset) writes every task: the features below, then a video of
    # each camera of the episodes (observation.images.<camera>, observation.depth.<camera>) and
    # the instruction; extras/ and meta/factory.json are the export's.

    def dataset_layout(self) -> str:
        """The layout of the task's datasets, ``layout`` in their ``meta/factory.json``:
        datasets of one layout have the same features, and one dataset holds one layout
        (:mod:`factory.dataset.layout`; a ``meta/factory.json`` without ``layout`` is of the
        default task's). The mixed-layout errors call the robot's base by it ("fixed base")."""
        return self.part("dataset").LAYOUT

    def robot_type(self) -> str:
        """lerobot's ``robot_type`` of the task's datasets."""
        return self.part("dataset").ROBOT_TYPE

    def dataset_features(self) -> dict[str, dict[str, Any]]:
        """The task's LeRobot features other than the cameras' (key -> ``dtype``, ``shape``,
        ``names``), in the dataset's order; a feature of shape (1,) is a scalar column."""
        return self.part("dataset").features()

    def episode_arrays(self, n_frames: int) -> dict[str, tuple[int, ...]]:
        """The arrays an episode of the task holds besides its cameras', and their shapes for
        ``n_frames`` frames: the export refuses an episode whose arrays differ, naming one."""
        return self.part("dataset").arrays_of(n_frames)

    def episode_columns(self, info: Any, arrays: Any, scene_json: bytes) -> dict[str, Any]:
        """The values of :meth:`dataset_features` of one episode: numpy arrays (F, *shape).

        Args:
            info: the episode's ``EpisodeInfo``.
            arrays: its stored arrays (a zarr group; :meth:`episode_arrays` checked).
            scene_json: the ``scene.json`` it was recorded in.

        Raises:
            StoreError: values the features cannot hold (names the episode and the fix).
        """
        return self.part("dataset").columns(info, arrays, scene_json)

    def dataset_meta(self) -> dict[str, Any]:
        """The keys the task adds to ``meta/factory.json`` (a merge keeps the first shard's)."""
        return {}

    def dataset_card(
        self, meta: dict[str, Any], cameras: list[str], rgb: dict[str, Any]
    ) -> tuple[str, list[str]]:
        """The task's part of its dataset card (markdown): the opening paragraph, and the list
        items after the task, episodes and seeds (what each feature and ``extras/`` hold).

        Args:
            meta: the dataset's ``meta/factory.json``.
            cameras: its camera names.
            rgb: the RGB codec settings (``codec``, ``pix_fmt``).
        """
        return self.part("dataset").card(meta, cameras, rgb)

    def card_tags(self) -> tuple[str, ...]:
        """Tags the task's dataset cards add to the factory's."""
        return ()

    # -- policy: the evaluation env, training inputs, lerobot plugin (floor 9) ------------------

    # One env (factory.policy.vector_env.PickPlaceVecEnv) runs every task: the episodes of one
    # scene, their records, observation buffers, outcomes and videos; the gymnasium envs, the
    # lerobot plugin (one gym id per task) and stage=eval sit on it. The task sets the scene up
    # (env_scene), says what the env observes and how it acts (env_observations, env_cameras,
    # env_action_bounds) and simulates its episodes as stage=demos does: its worlds stepped
    # together on one batch by the env (factory.policy.batch_sim) after its env_rules, or its
    # own simulation (env_sim).

    env_max_steps: ClassVar[int] = 400
    """Frames before an episode in the env is truncated, where nothing else says."""

    robot_kind: ClassVar[str] = ""
    """The task's robot in a word, as the evaluation's errors call it and its datasets
    (``fixed-base``, ``mobile``)."""

    def env_cameras(self) -> tuple[str, ...]:
        """Every camera the env can observe, in the order it observes them."""
        raise NotImplementedError

    def fisheye_cameras(self) -> tuple[str, ...]:
        """The robot's fisheye cameras: recorded besides ``demos.cameras``, their images
        ``width`` square (none by default)."""
        return ()

    def env_state_dim(self) -> int:
        """Size of the task's ``observation.environment_state`` (0, default: it has none)."""
        return 0

    def calibrated_cameras(self, cameras: Sequence[str]) -> tuple[str, ...]:
        """Of the recorded ``cameras``, in their order, those fixed in the scene whose
        calibration (pose in the robot's base frame, vertical field of view) the task's episodes
        record (``EpisodeInfo.camera_poses``), its datasets hold and its env observes
        (``observation.camera_poses``, :mod:`factory.demos.record.calibration`); none by
        default."""
        return ()

    def camera_calibration(
        self, setup: Any, cameras: Sequence[str]
    ) -> tuple[dict[str, list[float]], dict[str, float]]:
        """The calibration of :meth:`calibrated_cameras` of ``cameras`` in a scene set up by
        :meth:`env_scene` (the rig's placement, no appearance jitter): camera -> pose (12:
        position m, rotation rows; the robot's base frame), camera -> vertical field of view
        (deg); empty by default."""
        return {}, {}

    def env_observations(self) -> dict[str, tuple[tuple[int, ...], str]]:
        """The env's observations besides the cameras' and the environment state, in the
        dataset's order: key -> (shape, dtype) of one env's."""
        return dict(self.part("env").OBSERVATIONS)

    def env_action_bounds(self) -> tuple[Any, Any]:
        """The action's lowest and highest values (float32 arrays of its size)."""
        return self.part("env").action_bounds()

    def env_scene(self, run_dir: Path, scene_id: str, dc: Any) -> tuple[Any, Any]:
        """Scene ``scene_id`` of the run composed with the robot exactly as ``stage=demos``
        records it with the demos settings ``dc``, and its planner (the privileged agent).

        Raises:
            TaskError: the scene cannot host the task.
        """
        raise NotImplementedError

    def env_instruction(self, setup: Any) -> str:
        """The task's language instruction in a scene set up by :meth:`env_scene` (as the
        demos record it)."""
        raise NotImplementedError

    def env_sim(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any | None:
        """The task's own simulation of ``num_envs`` episodes of a scene (a
        :class:`~factory.policy.vector_env.TaskSim`), for a task that simulates its episodes
        itself; None (default): the env steps its worlds together on one batch
        (:class:`~factory.policy.batch_sim.BatchSim`) after :meth:`env_rules`.

        Args:
            setup, planner: of :meth:`env_scene`.
            num_envs: episodes run at once.
            spec: what the env observes (:class:`~factory.policy.obs_spec.ObsSpec`).
            interpolate: the controller's first-order hold of the targets over a frame.
        """
        return None

    def env_rules(
        self, setup: Any, planner: Any, num_envs: int, spec: Any, interpolate: bool
    ) -> Any:
        """The task's rules for a batch of its worlds (a
        :class:`~factory.policy.batch_sim.BatchRules`: initial configurations, controller, contacts,
        when an episode ends), for a task without :meth:`env_sim`; arguments as there."""
        raise NotImplementedError

    def claims_features(self, features: Any) -> bool:
        """Whether a policy that reads ``features`` (its input feature names) was trained on
        the task's datasets (no task claiming them: the default task's)."""
        return False

    def subtasks(self) -> tuple[str, ...]:
        """The task's sub-tasks in order (the env's ``subtask_index``; an evaluation's
        ``per_subtask`` results); none by default."""
        return ()

    def eval_identity(self) -> dict[str, Any]:
        """What the task adds to an evaluation's identity (``run.json``: a re-run with
        another resumes nothing)."""
        return {}

    def eval_notes(self) -> dict[str, Any]:
        """What the task adds to an evaluation's ``results.json``."""
        return {}
