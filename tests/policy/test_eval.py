"""``stage=eval``: replay and planner rollouts, results, resume, and the bad-input errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from robot_models import require_robot_models

require_robot_models()
pytest.importorskip("lerobot")

from factory.policy.env import EVAL_SEED_OFFSET
from factory.policy.eval import read_records, summarize, wilson


def _results(run: Path, name: str) -> dict:
    return json.loads((run / "eval" / name / "results.json").read_text())


def test_wilson_interval() -> None:
    lo, hi = wilson(45, 90)
    assert lo == pytest.approx(0.39884, abs=1e-5) and hi == pytest.approx(0.60116, abs=1e-5)
    assert wilson(0, 10)[0] == 0.0 and wilson(10, 10)[1] == 1.0
    assert wilson(0, 0) == (0.0, 1.0)
    r = summarize(
        [
            {"scene": "a", "seed": 1, "success": True, "reason": ""},
            {"scene": "a", "seed": 2, "success": False, "reason": "slip"},
            {"scene": "b", "seed": 3, "success": False, "reason": "slip"},
        ],
        "p",
        "planner",
        None,
        1.0,
    )
    assert r["success_rate"] == pytest.approx(1 / 3) and r["failures"] == {"slip": 2}
    assert r["per_scene"]["a"]["episodes"] == 2 and r["seeds"] == {"a": [1, 2], "b": [3]}
    assert r["schema_version"] == 1


def test_replay_every_recorded_episode(policy_run: Path, pcli, n_recorded: int) -> None:
    out = pcli("stage=eval", f"run_dir={policy_run}", "eval.policy=replay")
    assert out.returncode == 0, out.stderr[-3000:]
    r = _results(policy_run, "replay")
    assert r["kind"] == "replay" and r["episodes"] == n_recorded
    assert r["success_rate"] == 1.0 and r["failures"] == {}
    assert r["training_data"]["scenes"] == ["kitchen_a"]
    assert r["training_data"]["episodes"] == n_recorded
    assert all(s < EVAL_SEED_OFFSET for s in r["seeds"]["kitchen_a"])  # the demos' own seeds
    lines = read_records(policy_run / "eval" / "replay" / "episodes.jsonl")
    assert len(lines) == n_recorded and all(x["episode_id"] for x in lines)
    # where the time went: the frames stepped and the seconds of each part, logged per unit
    t = r["timing_this_call"]
    assert r["executor"] == "cpu" and t["episodes"] == n_recorded and t["units"] >= 1
    assert t["frames"] > 20 and t["step_s"] > 0 and t["video_s"] > 0 and t["observe_s"] >= 0
    assert "eval replay: scene kitchen_a:" in out.stderr + out.stdout or any(
        "eval replay: scene kitchen_a:" in f.read_text() for f in (policy_run / "logs").glob("*")
    )
    # the units' progress files are gone with their units
    assert not list((policy_run / "eval" / "replay" / "progress").glob("*.json"))
    videos = sorted((policy_run / "eval" / "replay" / "videos").glob("*.mp4"))
    assert len(videos) == 2
    import av

    with av.open(str(videos[0])) as f:
        stream = f.streams.video[0]
        assert (stream.width, stream.height) == (96, 32)
        assert sum(1 for _ in f.decode(stream)) > 20


def test_planner_on_held_out_scene_and_resume(policy_run: Path, pcli) -> None:
    args = [
        "stage=eval",
        f"run_dir={policy_run}",
        "eval.policy=planner",
        "eval.episodes_per_scene=2",
        "eval.videos=1",
    ]
    out = pcli(*args)
    assert out.returncode == 0, out.stderr[-3000:]
    r = _results(policy_run, "planner")
    assert list(r["per_scene"]) == ["kitchen_b"]  # kitchen_a is in the dataset
    assert r["episodes"] == 2 and r["training_data"] is None
    assert all(s >= EVAL_SEED_OFFSET for s in r["seeds"]["kitchen_b"])
    assert r["successes"] >= 1, r  # the privileged agent
    path = policy_run / "eval" / "planner" / "episodes.jsonl"
    first, second = path.read_text().splitlines()
    # killed after one episode, in the middle of writing the second line
    path.write_text(first + "\n" + second[:15])
    again = pcli(*args)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "1 finished before" in again.stderr
    lines = path.read_text().splitlines()
    assert len(lines) == 2 and lines[0] == first
    assert json.loads(lines[1])["seed"] == json.loads(second)["seed"]  # the same configuration
    assert _results(policy_run, "planner")["episodes"] == 2
    # nothing left: a third run only rewrites the results
    third = pcli(*args)
    assert third.returncode == 0 and "2 finished before" in third.stderr
    # another setting on the same results folder is refused unless force=true
    other = pcli(*args, "eval.seed=5")
    assert other.returncode == 2 and "force=true" in other.stderr


def test_worker_processes_give_the_same_episodes(policy_run: Path, pcli) -> None:
    """``eval.workers``: batches spread over spawned processes give the records of one
    process (replay is deterministic), and a trained policy loads and acts in each worker."""
    run = f"run_dir={policy_run}"
    one = pcli("stage=eval", run, "eval.policy=replay", "eval.name=w1", "eval.videos=0")
    assert one.returncode == 0, one.stderr[-3000:]
    two = pcli(
        "stage=eval",
        run,
        "eval.policy=replay",
        "eval.name=w2",
        "eval.workers=2",
        "eval.batch=1",
        "eval.videos=1",
    )
    assert two.returncode == 0, two.stderr[-3000:]
    assert "over 2 worker processes" in two.stderr

    def key(r: dict) -> tuple:
        return (r["episode_id"], r["success"], r["reason"], r["steps"])

    w1 = sorted(key(r) for r in read_records(policy_run / "eval" / "w1" / "episodes.jsonl"))
    w2 = sorted(key(r) for r in read_records(policy_run / "eval" / "w2" / "episodes.jsonl"))
    assert w1 == w2 and len(w1) == 3
    assert len(list((policy_run / "eval" / "w2" / "videos").glob("*.mp4"))) == 1
    # a (barely) trained policy, two workers each loading it
    out = pcli(
        "stage=train",
        run,
        "train.name=tiny",
        "train.steps=2",
        "train.batch_size=2",
        "train.device=cpu",
        "train.options={diffusion: {down_dims: [16, 32], diffusion_step_embed_dim: 16}}",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    out = pcli(
        "stage=eval",
        run,
        "eval.policy=tiny",
        "eval.device=cpu",
        "eval.workers=2",
        "eval.batch=1",
        "eval.episodes_per_scene=2",
        "eval.max_steps=4",
        "eval.videos=0",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    r = _results(policy_run, "tiny")
    assert r["episodes"] == 2 and list(r["per_scene"]) == ["kitchen_b"]
    # a trained policy's act by part: the parts are within its act seconds
    t = r["timing_this_call"]
    parts = [t[k] for k in ("act_convert_s", "act_perception_s", "act_policy_s", "act_ik_s")]
    assert t["act_policy_s"] > 0 and sum(parts) <= t["act_s"] + 1e-3, t
    assert all(
        0 < rec["steps"] <= 4
        for rec in read_records(policy_run / "eval" / "tiny" / "episodes.jsonl")
    )
    bad = pcli("stage=eval", run, "eval.policy=replay", "eval.workers=-1")
    assert bad.returncode == 2 and "eval.workers" in bad.stderr


def test_bad_inputs_write_nothing(policy_run: Path, tmp_path: Path, pcli) -> None:
    run = f"run_dir={policy_run}"
    out = pcli("stage=eval", run, "eval.policy=nonexistent")
    assert out.returncode == 2 and "unknown eval.policy 'nonexistent'" in out.stderr
    assert "replay, planner" in out.stderr
    assert not (policy_run / "eval" / "nonexistent").exists()
    out = pcli("stage=eval", run, "eval.policy=planner", "eval.scenes=somewhere")
    assert out.returncode == 2 and "eval.scenes must be" in out.stderr
    out = pcli("stage=eval", run, "eval.policy=planner", "eval.scenes=[nope]")
    assert out.returncode == 2 and "no scene(s) ['nope']" in out.stderr
    # a run whose every scene is in the dataset has no held-out scene
    small = tmp_path / "run"
    shutil.copytree(policy_run / "scenes" / "kitchen_a", small / "scenes" / "kitchen_a")
    meta = policy_run / "dataset" / "merged" / "meta" / "factory.json"
    (small / "dataset" / "merged" / "meta").mkdir(parents=True)
    shutil.copyfile(meta, small / "dataset" / "merged" / "meta" / "factory.json")
    out = pcli("stage=eval", f"run_dir={small}", "eval.policy=planner")
    assert out.returncode == 2 and "no held-out scenes" in out.stderr
    assert "eval.scenes=train" in out.stderr and len(out.stderr.strip().splitlines()[-1]) < 300
    assert not (small / "eval").exists()


def test_policy_features_the_env_cannot_give(policy_run: Path) -> None:
    """A checkpoint trained on another dataset (a camera this run does not record) fails
    before any rollout."""
    checkpoint = pytest.importorskip("factory.policy.checkpoint")
    from factory.errors import PolicyError
    from factory.policy.eval_stage import _spec_for_policy
    from factory.policy.obs_spec import obs_spec_of_dataset

    spec = obs_spec_of_dataset(policy_run / "dataset" / "merged")
    info = checkpoint.TrainInfo(
        name="other",
        policy_type="diffusion",
        inputs="rgb",
        dataset="elsewhere",
        scenes=["x"],
        episodes=1,
        steps=1,
        fps=20,
        features={"observation.state": [8], "observation.images.right": [32, 32, 3]},
    )
    with pytest.raises(PolicyError):
        _spec_for_policy(info, spec, False)
    # the right camera, but at another image size
    bigger = {"observation.state": [8], "observation.images.wrist": [64, 64, 3]}
    with pytest.raises(PolicyError, match="shape"):
        _spec_for_policy(checkpoint.TrainInfo(**{**info.__dict__, "features": bigger}), spec, False)
    fits = {"observation.state": [8], "observation.images.wrist": [32, 32, 3]}
    ok = checkpoint.TrainInfo(**{**info.__dict__, "features": fits})
    narrowed = _spec_for_policy(ok, spec, False)
    assert narrowed.cameras == ("wrist",) and not narrowed.depth and not narrowed.env_state
    assert spec.pose_cameras == ("left",) and narrowed.pose_cameras == ()  # not read
    assert {"observation.state", "observation.images.wrist"} <= set(spec.keys())


@pytest.mark.slow
def test_replay_of_a_generated_kitchen(pcli, tmp_path: Path) -> None:
    """Acceptance: the recorded actions of every successful demo of a generated kitchen
    succeed again in the env (>= 98 %)."""
    run = tmp_path / "run"
    out = pcli(
        "stage=all",
        "profile=small",
        f"run_dir={run}",
        "all.stages=[generate,validate,demos,dataset]",
        "demos.episodes_per_scene=5",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    out = pcli("stage=eval", "profile=small", f"run_dir={run}", "eval.policy=replay")
    assert out.returncode == 0, out.stderr[-3000:]
    r = _results(run, "replay")
    assert r["episodes"] == 5 and r["success_rate"] >= 0.98, r  # every one


def test_unit_progress_file_and_its_log_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A running unit's progress file (rewritten as frames pass, logged in the main process,
    removed at the end): what a unit that never ends still tells."""
    import logging

    from factory.policy import eval_units
    from factory.policy.eval import BatchTiming, Job
    from factory.policy.eval_units import Unit, UnitProgress, progress_path

    monkeypatch.setattr(eval_units, "PROGRESS_EVERY_S", 0.0)
    monkeypatch.setattr(eval_units, "PROGRESS_LOG_EVERY_S", 0.0)
    unit = Unit("kitchen_x", [Job(scene="kitchen_x", index=30, seed=1)], size=90)
    path = progress_path(tmp_path / "eval" / "mine" / "videos", unit)
    assert path == tmp_path / "eval" / "mine" / "progress" / "kitchen_x-30.json"
    replay = Unit("kitchen_x", [Job(scene="kitchen_x", seed=1, episode_id="kitchen_x/ep_7")], 4)
    assert progress_path(tmp_path / "videos", replay).name == "kitchen_x-kitchen_x_ep_7.json"
    report = UnitProgress(path, unit, 90, 12.5, 684, log_as="mine")
    timing = BatchTiming(frames=7, step_s=1.5, act_s=4.25)
    with caplog.at_level(logging.INFO, logger="factory.policy.eval_units"):
        report.maybe_write(timing)
    got = json.loads(path.read_text())
    assert got["schema_version"] == 1 and got["frames"] == 7 and got["worlds"] == 90
    assert got["setup_s"] == 12.5 and got["act_s"] == 4.25 and got["max_frames"] == 684
    assert "eval mine: scene kitchen_x running: frame 7 of at most 684 on 90 world(s)" in (
        caplog.text
    )
    assert "act 4.2" in caplog.text or "act 4.3" in caplog.text
    report.close()
    assert not path.exists()


@pytest.mark.parametrize(
    ("device", "visible", "want"),
    [
        ("auto", "0,1", ["0", "1"]),
        ("cuda", "GPU-a, GPU-b, GPU-c", ["GPU-a", "GPU-b", "GPU-c"]),
        ("auto", "1", []),  # one GPU: every worker on it
        ("cpu", "0,1", []),
        ("cuda:1", "0,1", []),  # a GPU named: kept
        ("auto", "", []),
    ],
)
def test_worker_gpus(device: str, visible: str, want: list[str]) -> None:
    """Evaluation workers spread over the visible GPUs, one each in turn."""
    from factory.policy.eval_units import worker_gpus

    assert worker_gpus(device, visible) == want


def test_each_worker_takes_the_next_gpu(monkeypatch: pytest.MonkeyPatch) -> None:
    """The pool's initializer gives the k-th worker the (k mod n)-th GPU, before CUDA starts."""
    import multiprocessing
    import os
    from types import SimpleNamespace

    from factory.policy import eval_units

    started = multiprocessing.get_context("spawn").Value("i", 0)
    settings = SimpleNamespace(kind="planner")
    seen = []
    for _ in range(3):
        monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
        eval_units._init_worker(settings, 1, ["4", "7"], started)  # type: ignore[arg-type]
        seen.append(os.environ["CUDA_VISIBLE_DEVICES"])
    assert seen == ["4", "7", "4"]
