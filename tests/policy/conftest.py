"""A small recorded run shared by the policy tests: one kitchen with demos and a dataset, and a
second (held-out) kitchen without demos."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from robot_models import require_robot_models

REPO = Path(__file__).resolve().parents[2]
EPISODES = 3


def factory_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m factory`` in a subprocess (one torch thread)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "factory", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
        timeout=900,
    )


@pytest.fixture(scope="session")
def policy_run(tmp_path_factory: pytest.TempPathFactory, make_kitchen) -> Path:
    """``run/`` with scenes ``kitchen_a`` (3 recorded demos at 32x32 px, left + wrist cameras,
    in ``dataset/merged``) and ``kitchen_b`` (the same room, added after the dataset: held out)."""
    if not os.environ.get("FACTORY_ROBOT_CACHE"):  # the GPU machine reads the exported robot
        require_robot_models()
    pytest.importorskip("lerobot")
    from factory.schema import scene_to_json

    run = tmp_path_factory.mktemp("policy") / "run"
    scene = make_kitchen(run / "assets", scene_id="kitchen_a")
    (run / "scenes" / "kitchen_a").mkdir(parents=True)
    (run / "scenes" / "kitchen_a" / "scene.json").write_text(scene_to_json(scene))
    common = [f"run_dir={run}", "demos.width=32", "demos.height=32", "demos.cameras=[left,wrist]"]
    out = factory_cli("stage=demos", *common, f"demos.episodes_per_scene={EPISODES}")
    assert out.returncode == 0, out.stderr[-3000:]
    out = factory_cli("stage=dataset", *common)
    assert out.returncode == 0, out.stderr[-3000:]
    held = replace(scene, id="kitchen_b")
    (run / "scenes" / "kitchen_b").mkdir(parents=True)
    (run / "scenes" / "kitchen_b" / "scene.json").write_text(scene_to_json(held))
    return run


@pytest.fixture(scope="session")
def pcli():
    """``pcli(*args)``: the command line in a subprocess with one torch thread."""
    return factory_cli


@pytest.fixture(scope="session")
def n_recorded() -> int:
    """Episodes recorded in ``policy_run``'s ``kitchen_a``."""
    return EPISODES


TINY_DIFFUSION: dict[str, Any] = {
    "diffusion": {
        "horizon": 8,
        "n_action_steps": 4,
        "down_dims": [16, 32],
        "diffusion_step_embed_dim": 16,
        "num_inference_steps": 3,
        "spatial_softmax_num_keypoints": 4,
    }
}


@pytest.fixture(scope="session")
def tiny_options() -> dict[str, Any]:
    """``train.options`` of a tiny diffusion policy (seconds to train a few steps on a CPU)."""
    return TINY_DIFFUSION
