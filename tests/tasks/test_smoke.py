"""Every registered task end to end on the CPU, through the real command line: its bundled
example scene, one recorded episode (``stage=demos``), the LeRobot export (``stage=dataset``)
and the episode replayed in the evaluation env (``stage=eval eval.policy=replay``)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from robot_models import require_robot_models

from factory.tasks import TASKS, get_task

require_robot_models()
pytest.importorskip("ompl")
pytest.importorskip("lerobot")

SMALL = (
    "demos.episodes_per_scene=1",
    "demos.width=32",
    "demos.height=32",
    "demos.fps=5",
    "demos.workers=1",
    "eval.policy=replay",
    "eval.scenes=train",
    "eval.videos=0",
)


@pytest.fixture(scope="module")
def task_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """name -> a run directory holding the task's run (made on first use)."""
    return {}


def task_run(name: str, runs: dict[str, Path], root: Path, run_cli) -> Path:
    """The run of task ``name``: its example scene (bundled, or generated from its example
    request), one episode, the dataset, the replay. ``run_cli`` is the ``cli`` fixture."""
    if name in runs:
        return runs[name]
    task = get_task(name)
    run = root / name
    src = task.example_scene_path()
    if src is not None:  # the bundled scene, else one generated from the example request
        shutil.copytree(src.parent, run / "scenes" / src.parent.name)
        first = []
    else:
        first = ["generate", "validate"]
        run.mkdir(parents=True)
    out = run_cli(
        "stage=all",
        "profile=small",
        f"all.stages=[{','.join([*first, 'demos', 'dataset', 'eval'])}]",
        f"run_dir={run}",
        f"task={name}",
        f"generate.prompts=[{task.example_request!r}]",
        *SMALL,
        env={"OMP_NUM_THREADS": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    runs[name] = run
    return run


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TASKS))
def test_task_records_exports_and_replays(
    name: str, task_runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory, cli
) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.demos.record.episodes import EpisodeStore

    run = task_run(name, task_runs, tmp_path_factory.mktemp("tasks"), cli)
    store = EpisodeStore(run / "episodes" / "shard-0.zarr")
    (eid,) = store.episode_ids()
    info = store.info(eid)
    assert info.task == name and info.success
    data = LeRobotDataset("factory/demos", root=run / "dataset" / "merged", video_backend="pyav")
    assert data.meta.total_episodes == 1 and data.meta.total_frames == info.n_frames
    actions = np.stack([data[i]["action"].numpy() for i in (0, info.n_frames - 1)])
    assert np.isfinite(actions).all()
    results = json.loads((run / "eval" / "replay" / "results.json").read_text())
    assert results["episodes"] == 1 and results["success_rate"] == 1.0, results
