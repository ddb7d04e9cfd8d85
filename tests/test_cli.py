"""The real command line on the small profile, and a one-line error for each bad input."""

from __future__ import annotations

import json
import re
import shutil
import zipfile
from pathlib import Path

import pytest

from factory.schema.sage import scene_to_sage
from factory.stages import STAGES

pytestmark = pytest.mark.slow


def _one_line_error(out) -> str:
    assert out.returncode == 2, (out.returncode, out.stdout, out.stderr)
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("factory: error:")]
    assert len(lines) == 1, out.stderr
    assert "Traceback" not in out.stderr
    return lines[0]


def test_help_and_list(cli) -> None:
    out = cli("--help")
    assert out.returncode == 0
    for stage in ("list", "ingest", "compile", "render", "export", "all"):
        assert stage in out.stdout
    out = cli("stage=list")
    assert out.returncode == 0 and "ingest" in out.stdout and "small" in out.stdout
    from factory.tasks import tasks

    for task in tasks():  # every registered task, with what it does
        assert f"{task.name}  " in out.stdout and task.description in out.stdout


def test_small_profile_end_to_end(cli, tmp_path: Path) -> None:
    run = tmp_path / "run"
    stages = "all.stages=[ingest,compile,validate,render]"
    out = cli("stage=all", "profile=small", f"run_dir={run}", stages)
    assert out.returncode == 0, out.stderr
    scene_dir = run / "scenes" / "kitchen_pick_place"
    assert (scene_dir / "scene.json").is_file() and (scene_dir / "model.xml").is_file()
    for view in ("top", "corner_0", "corner_1", "corner_2", "corner_3"):
        assert (scene_dir / "renders" / f"{view}.png").stat().st_size > 1000
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["schema_version"] == 1 and manifest["config"]["profile"] == "small"
    assert all(manifest["stages"][s]["status"] == "done" for s in ("ingest", "compile", "render"))
    assert not list(Path.cwd().glob("outputs"))  # Hydra wrote nothing to the cwd
    # idempotent: a re-run skips everything and changes nothing
    before = {p: p.stat().st_mtime_ns for p in scene_dir.rglob("*") if p.is_file()}
    again = cli("stage=all", "profile=small", f"run_dir={run}", stages)
    assert again.returncode == 0, again.stderr
    after = {p: p.stat().st_mtime_ns for p in scene_dir.rglob("*") if p.is_file()}
    assert before == after
    shards = json.loads((run / "manifest.json").read_text())["stages"]["render"]["shards"]
    assert shards["0-of-1"]["result"]["skipped"] == 1


def test_sage_zip_ingest_compile_export(cli, tmp_path: Path, sage_package: Path, sage_dict) -> None:
    archive = tmp_path / "scene.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        for p in sage_package.rglob("*"):
            if p.is_file():
                zf.write(p, p.relative_to(sage_package))
    run = tmp_path / "run"
    out = cli(
        "stage=all",
        "profile=small",
        f"run_dir={run}",
        "all.stages=[ingest,compile,validate,render]",
        f"ingest.source={archive}",
        "render.views=[top]",
    )
    assert out.returncode == 0, out.stderr
    assert (run / "scenes" / sage_dict["id"] / "renders" / "top.png").is_file()
    assert not list((run / ".tmp").iterdir())  # the extraction folder is cleaned up
    out = cli("stage=export", f"run_dir={run}", f"export.out={tmp_path / 'exp'}")
    assert out.returncode == 0, out.stderr
    exported = tmp_path / "exp" / sage_dict["id"]
    assert json.loads((exported / f"{sage_dict['id']}.json").read_text()) == sage_dict
    for ply in (sage_package / "objects").glob("*"):
        assert (exported / "objects" / ply.name).read_bytes() == ply.read_bytes()


def test_multirun_writes_only_under_run_dir(cli, tmp_path: Path) -> None:
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    run = tmp_path / "run"
    out = cli("-m", "stage=ingest", f"run_dir={run}", "seed=1,2", cwd=cwd)
    assert out.returncode == 0, out.stderr
    assert list(cwd.iterdir()) == []
    assert (run / "scenes" / "kitchen_pick_place" / "scene.json").is_file()


def test_shards_from_slurm_variables(cli, tmp_path: Path, example_scene_path: Path) -> None:
    src = tmp_path / "src"
    for i in range(5):
        data = json.loads(example_scene_path.read_text())
        data["id"] = f"kitchen_{i}"
        (src / data["id"]).mkdir(parents=True)
        (src / data["id"] / "scene.json").write_text(json.dumps(data))
    run = tmp_path / "run"
    for task in range(2):
        env = {"SLURM_ARRAY_TASK_ID": str(task), "SLURM_ARRAY_TASK_COUNT": "2"}
        out = cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}", env=env)
        assert out.returncode == 0, out.stderr
    assert sorted(p.name for p in (run / "scenes").iterdir()) == [f"kitchen_{i}" for i in range(5)]
    shards = json.loads((run / "manifest.json").read_text())["stages"]["ingest"]["shards"]
    assert {k: v["result"]["done"] for k, v in shards.items()} == {"0-of-2": 3, "1-of-2": 2}


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["stage=nope"], "unknown stage 'nope'"),
        (["stage=list", "colour=red"], "unknown config key 'colour'"),
        (["stage=list", "render.widht=3"], "unknown config key 'render.widht'"),
        (["stage=list", "render.width=wide"], "bad value for 'render.width'"),
        (["stage=list", "profile=huge"], "unknown profile 'huge'"),
        (["stage=compile"], "needs a run directory"),
        (["compile"], "not key=value"),
        (["stage=list", "--frobnicate"], "unknown option"),
        (["stage=ingest", "run_dir=RUN", "shard.index=3", "shard.count=2"], "shard.index"),
        (["stage=compile", "run_dir=RUN"], "does not exist: start the run"),
        (["stage=ingest", "run_dir=RUN", "ingest.source=/no/such/path"], "does not exist"),
        (["stage=ingest", "run_dir=RUN", "ingest.examples=[nowhere]"], "unknown example"),
    ],
)
def test_bad_command_lines(cli, tmp_path: Path, args: list[str], match: str) -> None:
    args = [a.replace("RUN", str(tmp_path / "run")) for a in args]
    assert match in _one_line_error(cli(*args))


BAD_FILES = {
    "truncated": ('{"schema_version": 1, "id": "k", "rooms": [{"id": ', "truncated or corrupt"),
    "malformed": ("{not json", "truncated or corrupt"),
    "version": ('{"schema_version": 9, "id": "k", "rooms": []}', "schema_version is 9"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_scene_files_leave_nothing_behind(cli, tmp_path: Path, case: str) -> None:
    text, match = BAD_FILES[case]
    src = tmp_path / "scene.json"
    src.write_text(text)
    run = tmp_path / "run"
    assert match in _one_line_error(cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}"))
    assert not (run / "scenes").exists()


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["rooms"][0]["dimensions"].update(width=-4.0), "must be > 0"),
        (lambda d: d["rooms"][1]["objects"][0]["position"].update(x=99.0), "outside every room"),
        (lambda d: d["rooms"][0]["objects"][2].update(place_id="ghost"), "'ghost' does not exist"),
        (lambda d: d["rooms"][0]["objects"][0].update(id="../escape"), "contains a path"),
    ],
    ids=["negative-dimension", "outside-rooms", "missing-support", "path-in-id"],
)
def test_bad_sage_layouts(cli, tmp_path: Path, sage_dict, edit, match: str) -> None:
    edit(sage_dict)
    src = tmp_path / "layout.json"
    src.write_text(json.dumps(sage_dict))
    run = tmp_path / "run"
    assert match in _one_line_error(cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}"))
    assert not (run / "scenes").exists() and not (run / "assets").exists()


def test_unsafe_zip_is_refused(cli, tmp_path: Path) -> None:
    archive = tmp_path / "evil.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("layout.json", "{}")
        zf.writestr("../../escaped.txt", "gotcha")
    run = tmp_path / "run"
    line = _one_line_error(cli("stage=ingest", f"run_dir={run}", f"ingest.source={archive}"))
    assert "unsafe path" in line
    assert not list(tmp_path.rglob("escaped.txt"))
    assert not (run / "scenes").exists()


def test_changed_scene_needs_force(cli, tmp_path: Path, example_scene_path: Path) -> None:
    run = tmp_path / "run"
    src = tmp_path / "kitchen"
    shutil.copytree(example_scene_path.parent, src)
    assert cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}").returncode == 0
    data = json.loads((src / "scene.json").read_text())
    data["description"] = "changed"
    (src / "scene.json").write_text(json.dumps(data))
    line = _one_line_error(cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}"))
    assert "force=true" in line
    stored = json.loads((run / "scenes" / data["id"] / "scene.json").read_text())
    assert stored["description"] != "changed"  # the existing scene is untouched
    out = cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}", "force=true")
    assert out.returncode == 0


def test_sage_export_matches_sage_dict_api(sage_dict) -> None:
    from factory.schema.sage import sage_to_scene

    assert scene_to_sage(sage_to_scene(json.loads(json.dumps(sage_dict)))) == sage_dict


def test_validate_and_repair(cli, tmp_path: Path, example_scene_path: Path) -> None:
    d = json.loads(example_scene_path.read_text())
    d["id"] = "broken"
    objs = {o["id"]: o for o in d["objects"]}
    objs["mug"]["position"]["z"] = 0.95
    objs["plate"]["position"]["z"] = 0.87
    src = tmp_path / "broken"
    src.mkdir()
    (src / "scene.json").write_text(json.dumps(d))
    run = tmp_path / "run"
    assert cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}").returncode == 0
    out = cli("stage=validate", f"run_dir={run}", "sim.backend=cpu")
    assert out.returncode == 0, out.stderr
    assert "stability %" in out.stdout and "broken" in out.stdout
    summary = json.loads((run / "validate" / "summary.json").read_text())
    assert summary["total"]["collision_pct"] > 0 and summary["total"]["stability_pct"] < 100
    before = (run / "scenes" / "broken" / "scene.json").read_text()
    out = cli("stage=validate", f"run_dir={run}", "validate.repair=true")
    assert out.returncode == 0, out.stderr
    report = json.loads((run / "scenes" / "broken" / "report.json").read_text())["validate"]
    actions = {(c["action"], c["object"]) for h in report["repair"] for c in h["changes"]}
    assert ("remove", "plate") in actions and ("settle", "mug") in actions
    assert report["metrics"]["collision"]["ratio"] == 0.0
    assert report["metrics"]["stability"]["ratio"] == 1.0
    after = json.loads((run / "scenes" / "broken" / "scene.json").read_text())
    assert after != json.loads(before) and "plate" not in {o["id"] for o in after["objects"]}


def test_validate_scene_that_does_not_compile(cli, tmp_path: Path, example_scene_path) -> None:
    run = tmp_path / "run"
    d = json.loads(example_scene_path.read_text())
    d["id"] = "bad_mesh"
    mug = next(o for o in d["objects"] if o["id"] == "mug")
    mug["asset"] = {
        "backend": "mesh_library",
        "asset_id": "broken",
        "source": "",
        "source_id": "",
        "scale": {"x": 1.0, "y": 1.0, "z": 1.0},
    }
    src = tmp_path / "src"
    src.mkdir()
    (src / "scene.json").write_text(json.dumps(d))
    assets = run / "assets" / "broken"
    assets.mkdir(parents=True)
    (assets / "visual.obj").write_text("this is not a mesh\n")
    (assets / "meta.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "asset_id": "broken",
                "backend": "mesh_library",
                "visual": "visual.obj",
                "extents": [0.1, 0.1, 0.1],
            }
        )
    )
    assert cli("stage=ingest", f"run_dir={run}", f"ingest.source={src}").returncode == 0
    line = _one_line_error(cli("stage=validate", f"run_dir={run}"))
    assert "bad_mesh" in line and "does not compile" in line
    assert not (run / "scenes" / "bad_mesh" / "report.json").exists()


@pytest.mark.slow
def test_small_profile_main_job(small_run) -> None:
    """The README's main job (run once per session by the ``small_run`` fixture): a generated
    kitchen, validated, with recorded demonstrations, written as a LeRobot dataset, a policy
    trained on it for a few steps and evaluated in closed loop, the report."""
    run, out = small_run.run_dir, small_run.out
    manifest = json.loads((run / "manifest.json").read_text())
    stages = ("generate", "validate", "demos", "dataset", "train", "eval", "report")
    assert all(manifest["stages"][s]["status"] == "done" for s in stages)
    results = json.loads((run / "eval" / "diffusion_state" / "results.json").read_text())
    assert results["episodes"] == 2 and results["training_data"]["episodes"] == 2
    (scene_dir,) = (run / "scenes").iterdir()
    assert scene_dir.name.startswith("kitchen")
    summary = json.loads((run / "episodes" / "summary-0-of-1.json").read_text())
    assert summary["episodes_stored"] == 2, summary
    episodes = sorted(p.name for p in (run / "episodes" / "shard-0.zarr").iterdir() if p.is_dir())
    assert episodes == [f"{scene_dir.name}-ep000", f"{scene_dir.name}-ep001"]
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata("factory/demos", root=run / "dataset" / "merged")
    assert meta.total_episodes == 2 and meta.total_frames > 0
    assert "observation.images.wrist" in meta.video_keys
    # the GPU data path (train.loader=device) runs here on CPU tensors
    train_log = (run / "logs" / "train-0-of-1.log").read_text()
    assert "batches gathered on cpu (train.loader=device)" in train_log
    # quiet terminal: factory's lines only, the summary table last, the rest in the logs
    outside = _lines_from_outside_factory(out.stdout, out.stderr)
    assert len(outside) == 0, "\n".join(outside)
    lines = out.stderr.splitlines()
    start = max(i for i, ln in enumerate(lines) if ln.startswith("stage=all done in "))
    table = lines[start + 1 :]
    assert table and all(ln.startswith("  ") for ln in table), out.stderr[-2000:]
    assert [ln.split()[0] for ln in table if not ln.startswith("   ")][:7] == list(stages)
    assert table[-1].split()[0] == "logs" and table[-1].endswith("/logs/")
    dataset_log = (run / "logs" / "dataset-0-of-1.log").read_text()
    assert "[libx264" in dataset_log and "INFO root: " in dataset_log  # x264's, lerobot's lines


_LOG_LINE = re.compile(r"^\d\d:\d\d:\d\d (?:DEBUG|INFO|WARNING|ERROR|CRITICAL) (\S+): ")
_TQDM_BAR = re.compile(r"^(?:[a-z]+)(?: [^:|]*)?: +\d+%\|.*\|")
"""factory's bars are named after their stage (``demos``, ``dataset shard-0``)."""
_VALIDATE_TABLE = re.compile(
    r"^(?:scene\s+#objects\b.*|\s*\S+\s+\d+\s+\d+\.\d(?:\s+\d+\.\d)*"
    r"|\w+ check: \d+ passed.*|  \S+: [a-z_]+)$"  # the scene checks' lines (route, task)
)


def _lines_from_outside_factory(stdout: str, stderr: str) -> list[str]:
    """The terminal lines not factory's: on stderr, factory's are log lines of the ``factory``
    loggers, progress bars and summary tables (a ``stage ... done in`` title, then rows two
    spaces in); on stdout, stage=validate's metrics table."""
    outside = [ln for ln in stdout.splitlines() if not _VALIDATE_TABLE.match(ln)]
    in_table = False
    for line in stderr.splitlines():
        if re.match(r"^stage[ =]\S+ done in [\d.]+ s\b.*:$", line):
            in_table = True
            continue
        if in_table and line.startswith("  "):
            continue
        in_table = False
        log = _LOG_LINE.match(line)
        if log and (log.group(1) == "factory" or log.group(1).startswith("factory.")):
            continue
        bar = _TQDM_BAR.match(line.split("\r")[-1])
        if bar and line.split("\r")[-1].split()[0].rstrip(":") in STAGES:
            continue
        outside.append(line)
    return outside


def test_free_form_keys_take_new_keys_from_the_command_line(cli) -> None:
    """``train.options={act: {...}}`` adds keys to a free-form mapping (Hydra's ``++``), where a
    plain override of a structured key would be refused as unknown."""
    from factory.__main__ import _parse

    args = ["train.options={act: {chunk_size: 4}}", "train.options.x.y=1", "seed=3"]
    overrides, _ = _parse(args)
    assert overrides == ["++" + args[0], "++" + args[1], "seed=3"]
    out = cli("stage=list", "--cfg", "job", args[0])
    assert out.returncode == 0, out.stderr
    assert "chunk_size: 4" in out.stdout


@pytest.mark.slow
def test_summary_paths_with_relative_run_dir(small_run, cli, tmp_path: Path, monkeypatch) -> None:
    """With a relative ``run_dir``, the summary table's paths are the files' own (no
    ``runs/small/runs/small/...``): the report stage through the CLI on a copy of the README
    run, and the row of the train stage."""
    from factory.policy.train_stage import _produced
    from factory.store import RunStore, Shard
    from factory.summary import stage_rows

    shutil.copytree(small_run.run_dir, tmp_path / "runs" / "small")
    out = cli("stage=report", "run_dir=runs/small", cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    rows = [ln.split() for ln in out.stderr.splitlines() if ln.startswith("  report ")]
    assert rows and rows[-1][-1] == "runs/small/report.html", out.stderr[-1000:]
    monkeypatch.chdir(tmp_path)
    store = RunStore(Path("runs/small"))
    result = {"produced": [_produced(store.root / "policy" / "diffusion_state")]}
    (train,) = stage_rows("train", result, store, Shard(0, 1), log=False)
    assert train.path == "runs/small/policy/diffusion_state/checkpoints/"
