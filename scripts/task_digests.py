"""Digests of fixed-seed runs of the demos, dataset, train and eval stages, to compare a tree
before and after a refactor bit for bit.

Only the command line is used (``python -m factory ...`` in a subprocess, with this
interpreter, this environment and this working directory), and the outputs are read with zarr,
pyarrow, numpy and json directly, so the script works against any tree whose CLI and output
formats are the same, wherever its modules live. Which tree runs is whichever ``import factory``
finds (``PYTHONPATH=/path/to/tree``, or the editable install); the JSON records it
(``_meta.factory_file``).

Cases (each into a fresh run dir ``<work>/<case>/run``, the same path every time):

* ``a``: ``pick_place``, CPU executor, ``stage=all profile=small`` (the README's run: generate,
  validate, demos, dataset, train, eval of the trained policy, report), then ``stage=eval`` with
  ``eval.policy=replay`` and ``eval.policy=planner``.
* ``b``: ``pick_place`` with ``demos.executor=warp`` (Warp's CPU device without CUDA): the
  small profile's kitchen, 2 episodes at 64 x 64, the dataset, eval replay and planner.
* ``c``: ``mobile_pick_place``, CPU executor, on the hand-built living room of
  ``tests/demos/test_mobile_pick_place.py`` (``_living_room()``, embedded below as its
  ``scene.json``): 2 episodes at 32 x 32 and 5 fps, the dataset, eval replay and planner, a tiny
  state policy (3 steps) and its eval.
* ``d``: ``mobile_pick_place`` with ``demos.executor=warp`` (MuJoCo Warp renders, on Warp's CPU
  device here) on a generated living room (the request of
  ``tests/demos/test_recording_render_warp.py``, no physics critic): 2 episodes at 32 x 32 and
  5 fps, the dataset, eval replay.

What is digested (SHA-256; paths inside outputs are written relative to the run dir as
``<run_dir>``, JSON is hashed with sorted keys):

* ``inputs``: each scene's ``scene.json`` and ``model.xml`` (outside the refactor; a change
  here explains changes downstream).
* ``episodes``: per zarr shard and stored episode, every array's bytes (sorted by name, with
  dtype, shape, chunks and attributes) and the episode attributes, whole and per key.
* ``demos_summary``: each ``episodes/summary-*.json`` as written.
* ``dataset``: per LeRobot root (``dataset/merged`` and each ``dataset/shards/*``): the content
  of every parquet file column by column (values, list lengths, nulls) and the file bytes, the
  ``meta/*.json`` files, the card ``README.md``, each video's bytes and decoded frames (PyAV;
  the depth videos are lossless, so their frames are the data even if the bytes move) and the
  ``extras/`` (``states.npz`` arrays, JSON, ``model.xml``, assets).
* ``train``: per policy, ``train.json``, ``train_log.jsonl`` (loss and lr per logged step) and
  every checkpoint file (safetensors bytes, JSON content), the ``last`` link's target.
* ``eval``: per evaluated policy, ``results.json``, each ``episodes.jsonl`` record, ``run.json``
  and each video's frame count and size.
* ``_unstable`` (written, reported by ``--compare``, not judged): what differs between two runs
  of the baseline itself. The eval videos' bytes: ``factory.policy.eval.write_video`` (PyAV
  h264, veryfast) gave different mp4 bytes for bit-identical frames in the mobile case; and the
  rollouts of case c's tiny trained policy (its actions differed in every process, with the
  checkpoint bit-identical; stage=eval sets no torch seed), of which only the episode count,
  seeds, step limit and ``run.json`` are compared.

Dropped because they measure time, not behaviour (``DROPPED`` below): the episode attribute
``plan_seconds``, the demos summary's ``seconds``, eval ``results.json``'s ``seconds``,
``train_log.jsonl``'s ``seconds`` and ``steps_per_s``. Not read at all: ``manifest.json``,
``logs/``, ``report.html``, ``validate/``, the scenes' ``report.json``, ``.stamps`` and
``renders/``, the run's ``assets/`` (generation, outside the refactor; the dataset's extras hold
the assets the episodes use).

Usage::

    PYTHONPATH=path/to/other/checkout python scripts/task_digests.py --out DIR [--cases a,b,c,d]
    python scripts/task_digests.py --compare DIR1 DIR2

``--out`` writes ``DIR/<case>.json`` and the command output to ``<work>/<case>/logs/``;
``--compare`` prints identical/different per case and per key (and the differing leaves) and
exits 1 when anything differs.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

EPISODE_DROP = ["plan_seconds"]
SUMMARY_DROP = ["seconds"]
RESULTS_DROP = ["seconds"]
TRAIN_LOG_DROP = ["seconds", "steps_per_s"]
DROPPED = {
    "episode attributes (episodes/shard-*.zarr/<episode>)": EPISODE_DROP,
    "demos summary (episodes/summary-*.json)": SUMMARY_DROP,
    "eval results (eval/<policy>/results.json)": RESULTS_DROP,
    "train log (policy/<name>/train_log.jsonl)": TRAIN_LOG_DROP,
}
NOT_READ = [
    "manifest.json",
    "logs/",
    "report.html",
    "validate/",
    "scenes/<id>/report.json, .stamps/, renders/",
    "assets/ (the run's asset library; dataset extras/assets are digested)",
]
RUN_DIR_TOKEN = "<run_dir>"
UNSTABLE = "_unstable"
"""Top-level key of what differs between two runs of the same tree (found by running the
baseline repeatedly): written for inspection, reported by ``--compare`` but not judged."""

# ---------------------------------------------------------------- the cases

SEEDS = ["seed=0", "train.seed=0", "eval.seed=0"]
SMALL = ["profile=small", *SEEDS]
WARP_B = [
    "demos.executor=warp",
    "demos.episodes_per_scene=2",
    "demos.width=64",
    "demos.height=64",
]
MOBILE = [
    "task=mobile_pick_place",
    *SEEDS,
    "demos.episodes_per_scene=2",
    "demos.width=32",
    "demos.height=32",
    "demos.fps=5",
    "demos.workers=1",
]
TINY_DIFFUSION = (
    "train.options={diffusion: {horizon: 8, n_action_steps: 4, down_dims: [16, 32], "
    "diffusion_step_embed_dim: 16, num_inference_steps: 3}}"
)
LIVING_REQUEST = (
    "a living room where the robot moves the coke can from the coffee table to the desk"
)


def _wall(i: int, a: tuple[float, float], b: tuple[float, float]) -> dict[str, Any]:
    return {
        "id": f"w{i}",
        "start": {"x": a[0], "y": a[1], "z": 0.0},
        "end": {"x": b[0], "y": b[1], "z": 0.0},
        "height": 2.5,
        "thickness": 0.1,
        "material": "drywall",
        "extras": {},
    }


def _object(
    oid: str,
    pos: tuple[float, float, float],
    dims: tuple[float, float, float],
    mass: float,
    role: str | None,
    support: str | None = None,
) -> dict[str, Any]:
    return {
        "id": oid,
        "room_id": "living",
        "category": oid,
        "position": dict(zip("xyz", pos, strict=True)),
        "dimensions": dict(zip(("width", "length", "height"), dims, strict=True)),
        "rotation": {"x": 0.0, "y": 0.0, "z": 0.0},
        "description": "",
        "placement": {
            "kind": "on_top" if support else "floor",
            "support_id": support,
            "location": "top",
            "guidance": "",
            "constraints": [],
        },
        "asset": None,
        "physics": {"mass": mass, "friction": 0.6, "static": False},
        "appearance": {"rgba": None, "metallic": None, "roughness": None},
        "license": "",
        "task_role": role,
        "extras": {},
    }


_CORNERS = [(0.0, 0.0), (6.0, 0.0), (6.0, 5.0), (0.0, 5.0)]
LIVING_ROOM_SCENE: dict[str, Any] = {
    # scene_to_json(_living_room()) of tests/demos/test_mobile_pick_place.py at f31f945: a
    # 6 x 5 m walled room, a can on a coffee table, a desk 3.3 m away (place target)
    "id": "living",
    "rooms": [
        {
            "id": "living",
            "room_type": "living_room",
            "position": {"x": 0, "y": 0, "z": 0},
            "dimensions": {"width": 6.0, "length": 5.0, "height": 2.7},
            "walls": [_wall(i, _CORNERS[i], _CORNERS[(i + 1) % 4]) for i in range(4)],
            "doors": [],
            "windows": [],
            "floor_material": "hardwood",
            "ceiling_height": 2.7,
            "extras": {},
        }
    ],
    "objects": [
        _object("coffee_table", (1.6, 2.5, 0.0), (1.0, 0.6, 0.45), 15.0, None),
        _object("can", (1.6, 2.4, 0.45), (0.066, 0.066, 0.12), 0.3, "pick", "coffee_table"),
        _object("desk", (4.6, 1.2, 0.0), (1.2, 0.6, 0.75), 30.0, "place_target"),
    ],
    "description": "",
    "source": "example",
    "seed": None,
    "task": None,
    "building_style": "",
    "total_area": None,
    "extras": {},
    "schema_version": 1,
}

CASES: dict[str, dict[str, Any]] = {
    "a": {
        "title": "pick_place, CPU executor, stage=all profile=small (README run) "
        "+ eval replay/planner",
        "scene": None,
        "steps": [
            ["stage=all", *SMALL],
            ["stage=eval", *SMALL, "eval.policy=replay"],
            ["stage=eval", *SMALL, "eval.policy=planner"],
        ],
    },
    "b": {
        "title": "pick_place, demos.executor=warp (2 episodes, 64 x 64) + dataset "
        "+ eval replay/planner",
        "scene": None,
        "steps": [
            ["stage=all", *SMALL, "all.stages=[generate,validate,demos,dataset]", *WARP_B],
            ["stage=eval", *SMALL, *WARP_B, "eval.policy=replay"],
            ["stage=eval", *SMALL, *WARP_B, "eval.policy=planner"],
        ],
    },
    "c": {
        "title": "mobile_pick_place, CPU executor, hand-built living room (2 episodes, 32 x 32, "
        "5 fps) + dataset + eval replay/planner + tiny train (3 steps) and its eval",
        "scene": LIVING_ROOM_SCENE,
        "unstable_eval": ["tiny"],
        "steps": [
            ["stage=demos", *MOBILE],
            ["stage=dataset", *MOBILE],
            ["stage=eval", *MOBILE, "eval.policy=replay", "eval.videos=1"],
            [
                "stage=eval",
                *MOBILE,
                "eval.policy=planner",
                "eval.scenes=train",
                "eval.episodes_per_scene=2",
                "eval.videos=1",
            ],
            [
                "stage=train",
                *MOBILE,
                "train.name=tiny",
                "train.steps=3",
                "train.batch_size=4",
                "train.save_every=3",
                "train.log_every=1",
                "train.threads=1",
                "train.device=cpu",
                TINY_DIFFUSION,
            ],
            [
                "stage=eval",
                *MOBILE,
                "eval.policy=tiny",
                "eval.scenes=train",
                "eval.episodes_per_scene=1",
                "eval.max_steps=20",
                "eval.device=cpu",
                "eval.videos=1",
            ],
        ],
    },
    "d": {
        "title": "mobile_pick_place, demos.executor=warp, generated living room (2 episodes, "
        "32 x 32, 5 fps) + dataset + eval replay",
        "scene": None,
        "steps": [
            [
                "stage=all",
                *MOBILE,
                "all.stages=[generate,demos,dataset]",
                f"generate.prompts=[{LIVING_REQUEST}]",
                "generate.physics_critic=false",
                "demos.executor=warp",
            ],
            ["stage=eval", *MOBILE, "demos.executor=warp", "eval.policy=replay", "eval.videos=1"],
        ],
    },
}

# ---------------------------------------------------------------- hashing helpers


def sha_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def canon(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def sha_json(obj: Any) -> str:
    return sha_bytes(canon(obj).encode())


def sha_file(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class Normalizer:
    """Writes the run dir as ``<run_dir>`` in strings and text, so that outputs that name their
    own paths compare across run dirs."""

    def __init__(self, run: Path) -> None:
        self.forms = sorted({str(run), str(run.resolve())}, key=len, reverse=True)

    def text(self, s: str) -> str:
        for form in self.forms:
            s = s.replace(form, RUN_DIR_TOKEN)
        return s

    def file_sha(self, path: Path) -> str:
        """A text file's SHA-256 with the run dir written as ``<run_dir>``."""
        data = path.read_bytes()
        for form in self.forms:
            data = data.replace(form.encode(), RUN_DIR_TOKEN.encode())
        return sha_bytes(data)

    def __call__(self, obj: Any) -> Any:
        if isinstance(obj, str):
            return self.text(obj)
        if isinstance(obj, dict):
            return {self.text(str(k)): self(v) for k, v in obj.items()}
        if isinstance(obj, list | tuple):
            return [self(v) for v in obj]
        return obj


def drop(obj: dict[str, Any], keys: list[str]) -> dict[str, Any]:
    return {k: v for k, v in obj.items() if k not in keys}


def array_digest(a: np.ndarray) -> dict[str, Any]:
    a = np.ascontiguousarray(a)
    return {"dtype": a.dtype.str, "shape": list(a.shape), "sha256": sha_bytes(a.tobytes())}


def keyed_json_digest(obj: Any) -> dict[str, Any]:
    """The whole object's hash and, for a dict, one per top-level key (to see which differs)."""
    out: dict[str, Any] = {"sha256": sha_json(obj)}
    if isinstance(obj, dict):
        out["keys"] = {k: sha_json(obj[k]) for k in sorted(obj)}
    return out


# ---------------------------------------------------------------- episodes (zarr)


def _zarr_arrays(group: Any, prefix: str, out: dict[str, Any]) -> None:
    for name, arr in group.arrays():
        out[prefix + name] = arr
    for name, sub in group.groups():
        _zarr_arrays(sub, f"{prefix}{name}/", out)


def episodes_digest(run: Path, norm: Normalizer) -> dict[str, Any]:
    import zarr

    out: dict[str, Any] = {}
    for store in sorted((run / "episodes").glob("shard-*.zarr")):
        root = zarr.open_group(str(store), mode="r")
        shard: dict[str, Any] = {"attrs": norm(dict(root.attrs)), "episodes": {}}
        for eid in sorted(name for name, _ in root.groups()):
            group = root[eid]
            attrs = norm(drop(dict(group.attrs), EPISODE_DROP))
            arrays: dict[str, Any] = {}
            _zarr_arrays(group, "", arrays)
            digests = {}
            for name in sorted(arrays):
                arr = arrays[name]
                d = array_digest(arr[...])
                d["chunks"] = list(arr.chunks)
                d["attrs_sha256"] = sha_json(dict(arr.attrs))
                digests[name] = d
            episode = {
                "outcome": {
                    k: attrs.get(k)
                    for k in ("success", "failure_reason", "seed", "n_frames", "recorder")
                },
                "attrs": keyed_json_digest(attrs),
                "arrays": digests,
            }
            episode["sha256"] = sha_json({"attrs": episode["attrs"]["sha256"], "arrays": digests})
            shard["episodes"][eid] = episode
        out[store.name] = shard
    return out


def summaries_digest(run: Path, norm: Normalizer) -> dict[str, Any]:
    return {
        p.name: norm(drop(json.loads(p.read_text()), SUMMARY_DROP))
        for p in sorted((run / "episodes").glob("summary-*.json"))
    }


# ---------------------------------------------------------------- dataset (LeRobot)


def column_digest(col: Any) -> dict[str, Any]:
    """A parquet column's content: list lengths at every nesting level, the leaf values'
    bytes (numeric/bool) or JSON (others), and the nulls."""
    import pyarrow as pa
    import pyarrow.compute as pc

    h = hashlib.sha256()
    typ = col.type
    h.update(str(typ).encode())
    arr = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    h.update(np.asarray(arr.is_null().to_numpy(zero_copy_only=False)).tobytes())
    while (
        pa.types.is_list(arr.type)
        or pa.types.is_large_list(arr.type)
        or (pa.types.is_fixed_size_list(arr.type))
    ):
        lengths = pc.list_value_length(arr).fill_null(-1).to_numpy(zero_copy_only=False)
        h.update(np.asarray(lengths, dtype=np.int64).tobytes())
        arr = arr.flatten()
        h.update(np.asarray(arr.is_null().to_numpy(zero_copy_only=False)).tobytes())
    if (
        pa.types.is_integer(arr.type)
        or pa.types.is_floating(arr.type)
        or (pa.types.is_boolean(arr.type))
    ):
        values = np.ascontiguousarray(arr.to_numpy(zero_copy_only=False))
        h.update(values.dtype.str.encode())
        h.update(values.tobytes())
    else:
        h.update(canon(arr.to_pylist()).encode())
    return {"type": str(typ), "sha256": h.hexdigest()}


def parquet_digest(path: Path) -> dict[str, Any]:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {
        "rows": table.num_rows,
        "columns": {name: column_digest(table.column(name)) for name in sorted(table.column_names)},
        "file_sha256": sha_file(path),
    }


def extras_digest(root: Path, norm: Normalizer) -> dict[str, Any]:
    out: dict[str, Any] = {}
    assets = []
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        rel = path.relative_to(root).as_posix()
        if rel.startswith("assets/"):
            assets.append([rel, sha_file(path)])
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as npz:
                out[rel] = {k: array_digest(npz[k]) for k in sorted(npz.files)}
        elif path.suffix == ".json":
            out[rel] = keyed_json_digest(norm(json.loads(path.read_text())))
        else:
            out[rel] = norm.file_sha(path)
    out["assets/*"] = {"files": len(assets), "sha256": sha_json(assets)}
    return out


def video_digest(path: Path) -> dict[str, Any]:
    """The decoded frames (PyAV, rgb24): their count, size and bytes. For the lossless depth
    videos this is the data itself, whatever the container's bytes."""
    import av

    h = hashlib.sha256()
    n, shape = 0, None
    with av.open(str(path)) as container:
        for frame in container.decode(video=0):
            im = frame.to_ndarray(format="rgb24")
            shape = list(im.shape)
            h.update(np.ascontiguousarray(im).tobytes())
            n += 1
    return {"frames": n, "shape": shape, "sha256": h.hexdigest()}


def lerobot_digest(root: Path, norm: Normalizer) -> dict[str, Any]:
    out: dict[str, Any] = {"parquet": {}, "meta": {}, "videos": {}}
    for path in sorted(root.rglob("*.parquet")):
        out["parquet"][path.relative_to(root).as_posix()] = parquet_digest(path)
    for path in sorted((root / "meta").glob("*.json")):
        out["meta"][path.name] = keyed_json_digest(norm(json.loads(path.read_text())))
    if (root / "README.md").is_file():
        out["README.md"] = norm.file_sha(root / "README.md")
    for path in sorted((root / "videos").rglob("*.mp4")) if (root / "videos").is_dir() else []:
        rel = path.relative_to(root / "videos").as_posix()
        out["videos"][rel] = {"file_sha256": sha_file(path), "decoded": video_digest(path)}
    if (root / "extras").is_dir():
        out["extras"] = extras_digest(root / "extras", norm)
    return out


def dataset_digest(run: Path, norm: Normalizer) -> dict[str, Any]:
    base = run / "dataset"
    out: dict[str, Any] = {}
    if (base / "merged").is_dir():
        out["merged"] = lerobot_digest(base / "merged", norm)
    for shard in sorted((base / "shards").glob("*")) if (base / "shards").is_dir() else []:
        out[f"shards/{shard.name}"] = lerobot_digest(shard, norm)
    return out


# ---------------------------------------------------------------- train and eval


def train_digest(run: Path, norm: Normalizer) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pdir in sorted(p for p in (run / "policy").glob("*") if p.is_dir()):
        entry: dict[str, Any] = {}
        if (pdir / "train.json").is_file():
            entry["train.json"] = keyed_json_digest(
                norm(json.loads((pdir / "train.json").read_text()))
            )
        if (pdir / "train_log.jsonl").is_file():
            lines = (pdir / "train_log.jsonl").read_text().splitlines()
            entry["train_log"] = [drop(json.loads(x), TRAIN_LOG_DROP) for x in lines if x.strip()]
        ckpts: dict[str, Any] = {}
        cdir = pdir / "checkpoints"
        for step in sorted(cdir.glob("*")) if cdir.is_dir() else []:
            if step.is_symlink():
                ckpts[step.name] = {"link": os.readlink(step)}
                continue
            files = {}
            for path in sorted(p for p in step.rglob("*") if p.is_file()):
                rel = path.relative_to(step).as_posix()
                if path.suffix == ".json":
                    files[rel] = sha_json(norm(json.loads(path.read_text())))
                else:
                    files[rel] = sha_file(path)
            ckpts[step.name] = files
        entry["checkpoints"] = ckpts
        out[pdir.name] = entry
    return out


def eval_digest(
    run: Path, norm: Normalizer, unstable_policies: tuple[str, ...] = ()
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(compared, unstable): the eval records, and what is not reproducible in the baseline
    itself: the videos' bytes and the rollouts of ``unstable_policies``, of which
    only the episode count, seeds and step limit are compared."""
    out: dict[str, Any] = {}
    unstable: dict[str, Any] = {}
    for edir in sorted(p for p in (run / "eval").glob("*") if p.is_dir()):
        entry: dict[str, Any] = {}
        if (edir / "results.json").is_file():
            entry["results"] = norm(
                drop(json.loads((edir / "results.json").read_text()), RESULTS_DROP)
            )
        if (edir / "episodes.jsonl").is_file():
            lines = (edir / "episodes.jsonl").read_text().splitlines()
            entry["episodes"] = [norm(json.loads(x)) for x in lines if x.strip()]
        if (edir / "run.json").is_file():
            entry["run"] = norm(json.loads((edir / "run.json").read_text()))
        vdir = edir / "videos"
        videos = sorted(vdir.glob("*.mp4")) if vdir.is_dir() else []
        entry["videos"] = {
            p.name: {k: v for k, v in video_digest(p).items() if k != "sha256"} for p in videos
        }
        unstable[edir.name] = {"videos": {p.name: sha_file(p) for p in videos}}
        if edir.name in unstable_policies:
            res = entry.get("results", {})
            unstable[edir.name].update(entry)
            entry = {
                "episodes_count": len(entry.get("episodes", [])),
                "seeds": res.get("seeds"),
                "max_steps": res.get("max_steps"),
                "run": entry.get("run"),
            }
        out[edir.name] = entry
    return out, unstable


def inputs_digest(run: Path, norm: Normalizer) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for sdir in sorted(p for p in (run / "scenes").glob("*") if p.is_dir()):
        entry = {}
        if (sdir / "scene.json").is_file():
            entry["scene.json"] = sha_json(norm(json.loads((sdir / "scene.json").read_text())))
        if (sdir / "model.xml").is_file():
            entry["model.xml"] = norm.file_sha(sdir / "model.xml")
        out[sdir.name] = entry
    return out


def digest_run(run: Path, unstable_policies: tuple[str, ...] = ()) -> dict[str, Any]:
    norm = Normalizer(run)
    sections = {
        "inputs": inputs_digest,
        "episodes": episodes_digest,
        "demos_summary": summaries_digest,
        "dataset": dataset_digest,
        "train": train_digest,
    }
    out = {name: fn(run, norm) for name, fn in sections.items() if (run / _DIRS[name]).exists()}
    if (run / "eval").is_dir():
        out["eval"], out[UNSTABLE] = eval_digest(run, norm, unstable_policies)
    return out


_DIRS = {
    "inputs": "scenes",
    "episodes": "episodes",
    "demos_summary": "episodes",
    "dataset": "dataset",
    "train": "policy",
    "eval": "eval",
}

# ---------------------------------------------------------------- running


def _git(tree: Path, *args: str) -> str:
    out = subprocess.run(["git", "-C", str(tree), *args], capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else ""


def factory_location() -> dict[str, Any]:
    """Which factory the subprocesses import (same interpreter, environment, cwd)."""
    out = subprocess.run(
        [sys.executable, "-c", "import factory; print(factory.__file__)"],
        capture_output=True,
        text=True,
        check=True,
    )
    path = Path(out.stdout.strip())
    tree = path.parent.parent
    return {
        "factory_file": str(path),
        "git_head": _git(tree, "rev-parse", "HEAD"),
        "git_dirty_files": len(_git(tree, "status", "--porcelain").splitlines()),
    }


def run_case(case: str, work: Path) -> dict[str, Any]:
    spec = CASES[case]
    base = work / case
    run = base / "run"
    logs = base / "logs"
    if base.exists():
        shutil.rmtree(base)
    logs.mkdir(parents=True)
    if spec["scene"] is not None:
        sdir = run / "scenes" / spec["scene"]["id"]
        sdir.mkdir(parents=True)
        (sdir / "scene.json").write_text(json.dumps(spec["scene"], indent=2))
    meta: dict[str, Any] = {
        "case": case,
        "title": spec["title"],
        "run_dir": str(run),
        "python": sys.executable,
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        **factory_location(),
        "dropped_fields": DROPPED,
        "not_read": NOT_READ,
        "commands": [],
    }
    start = time.monotonic()
    for k, step in enumerate(spec["steps"]):
        argv = [sys.executable, "-m", "factory", *step, f"run_dir={run}"]
        t0 = time.monotonic()
        print(f"[{case}] {' '.join(argv[1:])}", flush=True)
        with (logs / f"{k}.out").open("w") as out, (logs / f"{k}.err").open("w") as err:
            proc = subprocess.run(argv, stdout=out, stderr=err, env=os.environ.copy())
        seconds = round(time.monotonic() - t0, 1)
        meta["commands"].append({"argv": argv[1:], "rc": proc.returncode, "seconds": seconds})
        print(f"[{case}]   rc={proc.returncode} in {seconds} s", flush=True)
        if proc.returncode != 0:
            tail = (logs / f"{k}.err").read_text()[-3000:]
            meta["error"] = f"step {k} failed (rc {proc.returncode}): {tail}"
            break
    meta["run_seconds"] = round(time.monotonic() - start, 1)
    t0 = time.monotonic()
    result = {"_meta": meta, **digest_run(run, tuple(spec.get("unstable_eval", ())))}
    meta["digest_seconds"] = round(time.monotonic() - t0, 1)
    return result


# ---------------------------------------------------------------- comparing


def flatten(obj: Any, prefix: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    if isinstance(obj, dict) and obj:
        out: dict[tuple[str, ...], Any] = {}
        for k, v in obj.items():
            out.update(flatten(v, (*prefix, str(k))))
        return out
    if isinstance(obj, list) and obj:
        out = {}
        for i, v in enumerate(obj):
            out.update(flatten(v, (*prefix, f"[{i}]")))
        return out
    return {prefix: obj}


def _short(v: Any) -> str:
    s = json.dumps(v) if not isinstance(v, str) else v
    return s if len(s) <= 70 else s[:67] + "..."


def _diff(a: Any, b: Any) -> tuple[list[tuple[str, ...]], dict[Any, Any], dict[Any, Any]]:
    fa, fb = flatten(a), flatten(b)
    keys = sorted(set(fa) | set(fb))
    return [k for k in keys if fa.get(k, "<missing>") != fb.get(k, "<missing>")], fa, fb


def compare(dir1: Path, dir2: Path, max_lines: int, cases: list[str] | None = None) -> int:
    names = sorted({p.stem for p in dir1.glob("*.json")} | {p.stem for p in dir2.glob("*.json")})
    if cases:
        names = [n for n in names if n in cases]
    any_diff = False
    for name in names:
        p1, p2 = dir1 / f"{name}.json", dir2 / f"{name}.json"
        if not (p1.is_file() and p2.is_file()):
            print(f"case {name}: only in {dir1 if p1.is_file() else dir2}")
            any_diff = True
            continue
        a, b = json.loads(p1.read_text()), json.loads(p2.read_text())
        ma, mb = a.pop("_meta", {}), b.pop("_meta", {})
        ua, ub = a.pop(UNSTABLE, {}), b.pop(UNSTABLE, {})
        for m, d in ((ma, dir1), (mb, dir2)):
            if m.get("error"):
                print(f"case {name}: {d} recorded an error: {m['error'][:300]}")
        diff, fa, fb = _diff(a, b)
        keys = sorted(set(fa) | set(fb))
        verdict = "IDENTICAL" if not diff else f"DIFFERENT ({len(diff)} of {len(keys)} values)"
        print(f"case {name}: {verdict}")
        for m, d in ((ma, dir1), (mb, dir2)):
            print(
                f"  {d}: {m.get('factory_file')} @ {str(m.get('git_head'))[:7]}"
                f" (+{m.get('git_dirty_files')} changed files), run {m.get('run_seconds')} s"
            )
        any_diff |= bool(diff)
        for section in sorted({k[0] for k in keys}):
            n = sum(1 for k in keys if k[0] == section)
            nd = sum(1 for k in diff if k[0] == section)
            state = f"DIFFERENT ({nd} of {n} values)" if nd else f"identical ({n} values)"
            print(f"  {section:14s} {state}")
        for k in diff[:max_lines]:
            va, vb = fa.get(k, "<missing>"), fb.get(k, "<missing>")
            print(f"    {' / '.join(k)}: {_short(va)} -> {_short(vb)}")
        if len(diff) > max_lines:
            print(f"    ... {len(diff) - max_lines} more (--max-lines)")
        udiff, _, _ = _diff(ua, ub)
        if ua or ub:
            print(
                f"  {UNSTABLE:14s} not judged (varies between runs of one tree):"
                f" {len(udiff)} of {len(flatten(ua) | flatten(ub))} values differ"
            )
    return 1 if any_diff else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, help="write <out>/<case>.json")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated (a,b,c,d)")
    parser.add_argument(
        "--work", type=Path, default=Path("/tmp/task_digests"), help="run dirs: <work>/<case>/run"
    )
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("DIR1", "DIR2"))
    parser.add_argument("--max-lines", type=int, default=40, help="differing leaves shown per case")
    args = parser.parse_args(argv)
    args.cases_given = any(a.startswith("--cases") for a in (argv or sys.argv[1:]))
    if args.compare:
        chosen = [c.strip() for c in args.cases.split(",")] if args.cases_given else None
        return compare(*args.compare, args.max_lines, chosen)
    if args.out is None:
        parser.error("--out or --compare is required")
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        parser.error(f"unknown case(s) {unknown}; known: {sorted(CASES)}")
    args.out.mkdir(parents=True, exist_ok=True)
    failed = False
    for case in cases:
        result = run_case(case, args.work)
        (args.out / f"{case}.json").write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
        meta = result["_meta"]
        failed |= "error" in meta
        print(
            f"[{case}] {'FAILED' if 'error' in meta else 'done'}: run {meta['run_seconds']} s,"
            f" digest {meta['digest_seconds']} s -> {args.out / f'{case}.json'}",
            flush=True,
        )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
