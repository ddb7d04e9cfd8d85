"""The task registry: every task resolves, lazily, and no code outside ``factory/tasks/`` tests
a task's name."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import factory
from factory.errors import ConfigError
from factory.tasks import DEFAULT_TASK, TASKS, get_task, task_for_scene, task_names, tasks
from factory.tasks.base import Task

ROOT = Path(factory.__file__).parent

DEFAULTS = {
    "schema/scene.py": "the scene schema's default task.kind (schema/ imports nothing of ours)",
}
"""Files outside ``factory/tasks/`` allowed to spell a task's name, and why."""


@pytest.mark.parametrize("name", list(TASKS))
def test_every_task_resolves(name: str) -> None:
    task = get_task(name)
    assert isinstance(task, Task) and task.name == name and task.description
    assert get_task(name) is task  # one instance per process
    assert type(task).__module__.startswith(f"factory.tasks.{name}.")


@pytest.mark.parametrize("name", list(TASKS))
def test_task_class_is_cheap(name: str) -> None:
    """A task class loads none of the heavy libraries (``stage=list`` and generation hold it)."""
    code = (
        f"import sys; from factory.tasks import get_task; get_task({name!r}); "
        "print(sorted(m for m in ('mujoco', 'torch', 'ompl', 'numpy') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("name", list(TASKS))
def test_task_fills_the_hooks(name: str) -> None:
    """Every task answers the hooks of each floor (their defaults read its package's
    ``demos``, ``dataset`` and ``env`` modules) consistently."""
    from factory.demos.execution import EXECUTIONS

    task = get_task(name)
    assert task.demo_execution in EXECUTIONS
    assert callable(task.part("demos").demo_scene)
    layouts = [t.dataset_layout() for t in tasks()]
    assert len(set(layouts)) == len(layouts)  # a dataset's layout names its task
    assert task.robot_type() and task.robot_kind
    features = task.dataset_features()
    assert {"observation.state", "action"} <= set(features)
    arrays = task.episode_arrays(5)
    assert arrays and all(shape[0] == 5 for shape in arrays.values())
    assert arrays["action"][1] == features["action"]["shape"][0]
    low, high = task.env_action_bounds()
    assert low.shape == high.shape == tuple(features["action"]["shape"]) and (low <= high).all()
    observations = task.env_observations()
    assert observations["observation.state"][0] == tuple(features["observation.state"]["shape"])
    assert set(task.fisheye_cameras()) <= set(task.env_cameras())
    assert set(task.calibrated_cameras(task.env_cameras())) <= set(task.env_cameras())


def test_unknown_task_lists_the_choices() -> None:
    with pytest.raises(ConfigError, match="unknown task 'pick_plcae': choose one of pick_place"):
        get_task("pick_plcae")
    assert task_names() == list(TASKS) and [t.name for t in tasks()] == list(TASKS)
    assert DEFAULT_TASK in TASKS


def test_registry_imports_no_task() -> None:
    """Importing the registry (as generation and validation do) loads no task package."""
    code = (
        "import sys, factory.tasks; "
        "print(sorted(m for m in sys.modules if m.startswith('factory.tasks.')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_task_for_scene() -> None:
    from factory.schema.scene import Scene
    from factory.schema.scene import Task as SceneTask

    scene = Scene(id="s", rooms=[], objects=[])
    assert task_for_scene(scene).name == DEFAULT_TASK
    for name in TASKS:
        scene.task = SceneTask(kind=name, instruction="")
        assert task_for_scene(scene).name == name


def _string_constants(tree: ast.AST) -> list[tuple[int, str]]:
    """String constants that are not docstrings."""
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docstrings
    ]


def test_no_task_name_outside_tasks() -> None:
    """No module outside ``factory/tasks/`` spells a registered task's name in code (a test of
    the name, a constant, a dict key): it asks the task (``factory.tasks.get_task``)."""
    names = set(TASKS)
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith("tasks/") or rel in DEFAULTS:
            continue
        for line, value in _string_constants(ast.parse(path.read_text(), rel)):
            if value in names:
                found.append(f"factory/{rel}:{line}: {value!r}")
    assert not found, "task names tested outside factory/tasks/: " + ", ".join(found)


def test_the_name_finder_finds_one() -> None:
    tree = ast.parse('"""doc"""\nif cfg.task == "pick_place":\n    pass\n')
    assert _string_constants(tree) == [(2, "pick_place")]


@pytest.mark.parametrize("name", list(TASKS))
def test_example_is_made_for_its_task(name: str) -> None:
    """A task's example request asks for it; its example scene is claimed by it."""
    from factory.scenes.brain_steps import task_kind
    from factory.scenes.request import parse_task
    from factory.schema import scene_from_json

    task = get_task(name)
    path = task.example_scene_path()
    assert task.example_request or path, f"{name}: give an example request or scene"
    if task.example_request:
        spec = parse_task(task.example_request)
        assert spec is not None and task_kind(spec.__dict__) == name
    if path is not None:
        scene = scene_from_json(path.read_text())
        assert task.claims(scene) and task_for_scene(scene) is task
