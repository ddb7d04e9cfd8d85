"""A real single-node SLURM cluster: demos + per-shard export as a 2-task array job, then the
merge (stage=dataset).

The test installs Debian's slurm and munge packages (root or sudo needed, as for
``scripts/setup.sh``), starts munged, slurmctld and slurmd with a throw-away configuration,
submits ``scripts/slurm/stage_array.sbatch`` and checks the merged LeRobot dataset.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from factory.schema import scene_to_json

REPO = Path(__file__).resolve().parent.parent


def _root_cmd() -> list[str] | None:
    if os.geteuid() == 0:
        return []
    if shutil.which("sudo") and subprocess.run(["sudo", "-n", "true"]).returncode == 0:
        return ["sudo", "-n"]
    return None


def _sh(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    out = subprocess.run(cmd, text=True, capture_output=True, **kw)
    if out.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed ({out.returncode}): {out.stderr[-2000:]}")
    return out


@pytest.fixture
def slurm(tmp_path: Path):
    """A running single-node cluster; yields the environment to submit with."""
    root = _root_cmd()
    if root is None or not shutil.which("apt-get"):
        pytest.skip("needs root (or sudo) and apt-get to install slurm")
    if not (shutil.which("slurmctld") and shutil.which("sbatch") and shutil.which("munged")):
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        _sh([*root, "apt-get", "update", "-qq"], env=env)
        _sh(
            [
                *root,
                "apt-get",
                "install",
                "-y",
                "-qq",
                "--no-install-recommends",
                "slurmctld",
                "slurmd",
                "slurm-client",
                "munge",
            ],
            env=env,
        )
    _sh([*root, "install", "-d", "-o", "munge", "-g", "munge", "-m", "0755", "/run/munge"])
    if subprocess.run(["munge", "-n"], capture_output=True).returncode != 0:
        _sh([*root, "runuser", "-u", "munge", "--", "/usr/sbin/munged"])
    d = tmp_path / "slurm"
    for sub in ("state", "spool", "log"):
        (d / sub).mkdir(parents=True)
    host = _sh(["hostname", "-s"]).stdout.strip()
    conf = d / "slurm.conf"
    conf.write_text(
        f"""ClusterName=ci
SlurmctldHost=localhost
SlurmUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/log/slurmctld.log
SlurmdLogFile={d}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count()} RealMemory=1024 State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
"""
    )
    env = {**os.environ, "SLURM_CONF": str(conf)}
    _sh([*root, "env", f"SLURM_CONF={conf}", "slurmctld"])
    _sh([*root, "env", f"SLURM_CONF={conf}", "slurmd"])
    try:
        for _ in range(240):
            state = subprocess.run(
                ["sinfo", "-h", "-o", "%t"], env=env, capture_output=True, text=True
            ).stdout.strip()
            if state == "idle":
                break
            time.sleep(0.5)
        else:
            pytest.fail(f"the SLURM node never became idle (state {state!r})")
        yield env
    finally:
        subprocess.run(
            [*root, "env", f"SLURM_CONF={conf}", "scontrol", "shutdown"], capture_output=True
        )


def test_demos_array_job_then_dataset(slurm, tmp_path: Path, make_kitchen, cli, capsys) -> None:
    run = tmp_path / "run"
    assets = run / "assets"
    for k in range(2):
        scene = make_kitchen(assets, seed=3 + k, scene_id=f"kitchen_{k}")
        (run / "scenes" / scene.id).mkdir(parents=True)
        (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    env = {**slurm, "FACTORY_PYTHON": sys.executable}
    submit = _sh(
        [
            "sbatch",
            "--parsable",
            "--array=0-1",
            "--cpus-per-task=1",
            "--mem=256M",
            f"--output={out_dir}/%x-%A_%a.out",
            str(REPO / "scripts" / "slurm" / "stage_array.sbatch"),
            "all",
            str(run),
            "all.stages=[demos,dataset]",  # each task records and exports its own shard
            "profile=small",
            "demos.episodes_per_scene=1",
            "demos.width=32",
            "demos.height=32",
        ],
        env=env,
        cwd=REPO,
    )
    job = submit.stdout.strip()
    deadline = time.time() + 600
    while time.time() < deadline:
        queued = _sh(["squeue", "-h", "-j", job], env=env).stdout.strip()
        if not queued:
            break
        time.sleep(1)
    logs = sorted(out_dir.glob(f"factory-{job}_*.out"))
    with capsys.disabled():
        print(f"\nSLURM array job {job}:")
        for log in logs:
            lines = log.read_text().splitlines()
            print(f"--- {log.name}")
            print("\n".join(line for line in lines if "factory" in line)[-1500:])
    assert [p.name for p in logs] == [f"factory-{job}_0.out", f"factory-{job}_1.out"]
    manifest = json.loads((run / "manifest.json").read_text())
    shards = manifest["stages"]["demos"]["shards"]
    assert {k: v["status"] for k, v in shards.items()} == {"0-of-2": "done", "1-of-2": "done"}
    shards = manifest["stages"]["dataset"]["shards"]
    assert {k: v["result"]["exported"] for k, v in shards.items()} == {"0-of-2": 1, "1-of-2": 1}
    for k in range(2):
        zarr_dir = run / "episodes" / f"shard-{k}.zarr"
        assert [p.name for p in zarr_dir.iterdir() if p.is_dir()] == [f"kitchen_{k}-ep000"]
        shard_meta = run / "dataset" / "shards" / f"shard-{k}" / "meta" / "factory.json"
        assert json.loads(shard_meta.read_text())["episodes"][0]["episode_id"] == (
            f"kitchen_{k}-ep000"
        )
    # the merge step finds every shard exported and only merges
    out = cli("stage=dataset", f"run_dir={run}")
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads((run / "manifest.json").read_text())["stages"]["dataset"]["shards"]
    assert result["0-of-1"]["result"]["exported"] == 0
    meta = json.loads((run / "dataset" / "merged" / "meta" / "factory.json").read_text())
    assert [e["episode_id"] for e in meta["episodes"]] == ["kitchen_0-ep000", "kitchen_1-ep000"]
    info = json.loads((run / "dataset" / "merged" / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 2 and info["robot_type"] == "franka_panda"


def test_hydra_submitit_launcher(slurm, tmp_path: Path, make_kitchen, cli) -> None:
    """The same cluster through Hydra's launcher: ``-m ... hydra/launcher=factory_slurm``."""
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    run = tmp_path / "run"
    for k in range(2):
        scene = make_kitchen(run / "assets", seed=3 + k, scene_id=f"kitchen_{k}")
        (run / "scenes" / scene.id).mkdir(parents=True)
        (run / "scenes" / scene.id / "scene.json").write_text(scene_to_json(scene))
    # No accounting database here: submitit asks sacct, so answer from squeue.
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    sacct = bin_dir / "sacct"
    sacct.write_text(
        "#!/bin/bash\n"
        'ids=$(printf "%s\\n" "$@" | sed -n "s/^-j//p;/^[0-9]/p" | head -1)\n'
        'for a in "$@"; do case $a in -j*) ids=${a#-j};; esac; done\n'
        'echo "JobID|State|NodeList"\n'
        'squeue -h --states=all -j "$ids" -o "%i|%T|%N" 2>/dev/null\n'
    )
    sacct.chmod(0o755)
    env = {**slurm, "PATH": f"{bin_dir}:{os.environ['PATH']}"}
    out = cli(
        "-m",
        "stage=compile",
        f"run_dir={run}",
        "shard.count=2",
        "shard.index=0,1",
        "hydra/launcher=factory_slurm",
        "hydra.launcher.mem_gb=0",
        "hydra.launcher.cpus_per_task=1",
        "hydra.launcher.timeout_min=10",
        env=env,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    shards = json.loads((run / "manifest.json").read_text())["stages"]["compile"]["shards"]
    assert {k: v["status"] for k, v in shards.items()} == {"0-of-2": "done", "1-of-2": "done"}
    assert (run / "scenes" / "kitchen_0" / "model.xml").is_file()
    assert (run / "scenes" / "kitchen_1" / "model.xml").is_file()
    # the two jobs ran through SLURM (submitit's per-job logs)
    logs = sorted(p.name for p in (run / "logs" / "multirun").rglob("*_log.out"))
    assert len(logs) == 2, logs
