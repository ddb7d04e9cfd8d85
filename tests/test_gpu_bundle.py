"""scripts/gpu_bundle.sh and scripts/gpu_install.sh without network or root: the pinned wheel
list, and an install of a tiny hand-made bundle (one pure-Python wheel, a robots folder, split
in two pieces with their md5 file) into a temporary folder."""

from __future__ import annotations

import base64
import hashlib
import importlib.metadata
import io
import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BUNDLE = REPO / "scripts" / "gpu_bundle.sh"
INSTALL = REPO / "scripts" / "gpu_install.sh"


def _run(args: list[str], cwd: Path = REPO) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PY": sys.executable, "PYTHON": sys.executable}
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=60)


def test_list_pins_the_venv_versions():
    r = _run(["bash", str(BUNDLE), "--list"])
    assert r.returncode == 0, r.stderr
    pins = dict(line.split("==") for line in r.stdout.split())
    for name in ("warp-lang", "mujoco-warp", "mujoco-mjx", "lerobot", "mujoco", "pyserial"):
        assert pins[name] == importlib.metadata.version(name), name


def test_bundle_argument_errors():
    r = _run(["bash", str(BUNDLE), "--split", "lots"])
    assert r.returncode == 2 and "not a size" in r.stderr
    r = _run(["bash", str(BUNDLE), "--nope"])
    assert r.returncode == 2 and "--help" in r.stderr


def _wheel(path: Path) -> Path:
    """A minimal pure-Python wheel, tinypkg_fake 0.1 (what pip wheel would write)."""
    files = {
        "tinypkg_fake/__init__.py": b"VALUE = 42\n",
        "tinypkg_fake-0.1.dist-info/METADATA": b"Metadata-Version: 2.1\nName: tinypkg-fake\n"
        b"Version: 0.1\n",
        "tinypkg_fake-0.1.dist-info/WHEEL": b"Wheel-Version: 1.0\nGenerator: test\n"
        b"Root-Is-Purelib: true\nTag: py3-none-any\n",
    }
    record = []
    for name, data in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(data)}")
    record.append("tinypkg_fake-0.1.dist-info/RECORD,,")
    files["tinypkg_fake-0.1.dist-info/RECORD"] = ("\n".join(record) + "\n").encode()
    whl = path / "tinypkg_fake-0.1-py3-none-any.whl"
    with zipfile.ZipFile(whl, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return whl


def _bundle(tmp: Path) -> list[Path]:
    """gpu_bundle.tar's layout, split in two pieces, with gpu_bundle.tar.md5."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w") as tar:
        tar.add(_wheel(tmp), "gpu_bundle/wheels/tinypkg_fake-0.1-py3-none-any.whl")
        robot = tmp / "robot.xml"
        robot.write_text("<mujoco/>\n")
        tar.add(robot, "gpu_bundle/robots/panda-test/robot.xml")
    data = buf.getvalue()
    half = len(data) // 2
    parts = [tmp / "gpu_bundle.tar.part00", tmp / "gpu_bundle.tar.part01"]
    parts[0].write_bytes(data[:half])
    parts[1].write_bytes(data[half:])
    lines = [f"{hashlib.md5(data).hexdigest()}  gpu_bundle.tar"]
    lines += [f"{hashlib.md5(p.read_bytes()).hexdigest()}  {p.name}" for p in parts]
    (tmp / "gpu_bundle.tar.md5").write_text("\n".join(lines) + "\n")
    return parts


def test_install_a_tiny_bundle(tmp_path: Path):
    (tmp_path / "factory").mkdir()  # a checkout's root
    parts = _bundle(tmp_path)
    opts = ["--target", "site", "--keep-transformers", "--no-gl"]
    # pieces given in reverse order: sorted by the script
    r = _run(["bash", str(INSTALL), *opts, parts[1].name, parts[0].name], cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "md5 of 2 file(s) checked" in r.stdout
    envfile = tmp_path / ".gpu" / "env.sh"
    assert r.stdout.strip().splitlines()[-1] == f"source {envfile}"
    assert (tmp_path / "site" / "tinypkg_fake" / "__init__.py").is_file()
    assert (tmp_path / ".gpu" / "robots" / "panda-test" / "robot.xml").is_file()
    env = envfile.read_text()
    for part in (
        f"PYTHONPATH={tmp_path / 'site'}:{tmp_path}",
        "MUJOCO_GL=egl",
        f"FACTORY_ROBOT_CACHE={tmp_path / '.gpu' / 'robots'}",
        "PYTHONUNBUFFERED=1",
        "HF_HUB_OFFLINE=1",
    ):
        assert part in env
    out = subprocess.run(
        [
            "bash",
            "-c",
            f"source {envfile} && {sys.executable} -c 'import tinypkg_fake as t; print(t.VALUE)'",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert out.stdout.strip() == "42", out.stderr

    # a missing piece, a damaged piece, a missing file: one-line errors naming the fix
    r = _run(["bash", str(INSTALL), *opts, parts[0].name], cwd=tmp_path)
    assert r.returncode == 1 and "gpu_bundle.tar.part01 is missing" in r.stderr
    parts[1].write_bytes(parts[1].read_bytes()[:-1] + b"x")
    r = _run(["bash", str(INSTALL), *opts, parts[0].name, parts[1].name], cwd=tmp_path)
    assert r.returncode == 1 and "copy it again" in r.stderr
    r = _run(["bash", str(INSTALL), "gpu_bundle.tar"], cwd=tmp_path)
    assert r.returncode == 1 and "scripts/gpu_bundle.sh" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    r = _run(["bash", str(INSTALL)], cwd=tmp_path)
    assert r.returncode == 2 and "gpu_install.sh gpu_bundle.tar" in r.stderr
