"""Reads a run directory into typed dataclasses for the report.

Everything is read defensively: the formats of the later stages may still change a little, so a
file that is missing is simply absent from the result, and a file that is there but unreadable
or lacks a key is skipped with a note (``RunData.notes``) that the page shows. Nothing here
imports a stage or a heavy library; episode frames and videos are read later by
:mod:`factory.report.gifs`.
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

VIEWS = ("top", "corner_0", "corner_1", "corner_2", "corner_3")
"""Render views a scene may have (``scenes/<id>/renders/<view>.png``)."""


@dataclass
class StageRow:
    """One stage of the manifest.

    Attributes:
        name: the stage; status: ``done``, ``running`` or ``failed`` (the stage's overall).
        seconds: summed over the recorded shards (s); None if none recorded a time.
        shards_done, shards: shards done and recorded; error: the first failed shard's error.
        results: the summaries the shards' stage functions returned (dicts only).
    """

    name: str
    status: str
    seconds: float | None
    shards_done: int
    shards: int
    error: str = ""
    results: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class RunInfo:
    """The run as a whole (``manifest.json``); every field may be empty in an odd run."""

    run_dir: Path
    factory_version: str = ""
    git_sha: str = ""
    created: float | None = None
    profile: str = ""
    seed: int | None = None
    stages: list[StageRow] = field(default_factory=list)


@dataclass
class SceneRow:
    """One scene (generated, ingested or an augmented variant).

    Attributes:
        scene_id: the scene's id (its folder under ``scenes/``).
        source: ``text``, ``augment:<parent>``, ...; parent: the parent of a variant.
        description: the request or description; instruction: the task's instruction.
        room_types: the rooms' types; objects: number of objects (scene.json).
        collision_pct, stability_pct: validation metrics (%), None if not validated.
        renders: view -> PNG path of the renders that exist.
        augment: a variant's ``report.json`` ``augment`` record (levels, index, seed, ...).
    """

    scene_id: str
    source: str = ""
    parent: str | None = None
    description: str = ""
    instruction: str = ""
    room_types: list[str] = field(default_factory=list)
    objects: int | None = None
    collision_pct: float | None = None
    stability_pct: float | None = None
    renders: dict[str, Path] = field(default_factory=dict)
    augment: dict[str, Any] = field(default_factory=dict)


@dataclass
class EpisodeRef:
    """A stored episode whose frames can make a GIF: its store and id."""

    store: Path
    episode_id: str
    scene_id: str


@dataclass
class DemoSummary:
    """``episodes/summary-<k>-of-<n>.json`` of the latest sharding, summed.

    Attributes:
        stored: episodes in the stores; successes: new successful episodes of the last runs;
        attempts: successes plus failed attempts (``scene_unusable`` not counted).
        failures: reason -> count.
        per_scene: scene id -> ``{"episodes": stored, "failures": {reason: n}}``.
        seconds: wall time summed over the shards (s); frames: frames recorded.
        episodes: stored episodes, in store order (for GIFs).
    """

    stored: int = 0
    successes: int = 0
    attempts: int = 0
    failures: dict[str, int] = field(default_factory=dict)
    per_scene: dict[str, dict[str, Any]] = field(default_factory=dict)
    seconds: float = 0.0
    frames: int = 0
    shards: int = 0
    episodes: list[EpisodeRef] = field(default_factory=list)

    @property
    def success_rate(self) -> float | None:
        return self.successes / self.attempts if self.attempts else None


@dataclass
class DatasetInfo:
    """The merged LeRobot dataset.

    Attributes:
        path: the dataset folder; card: its ``README.md`` (markdown) or None.
        info: ``meta/info.json`` (LeRobot's: total_episodes, total_frames, fps, features, ...).
    """

    path: Path
    card: str | None = None
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class LogRow:
    """One logged training step (``train_log.jsonl``): step, loss, learning rate, seconds."""

    step: float
    loss: float
    lr: float | None = None
    seconds: float | None = None


@dataclass
class CurvePoint:
    """One learning-curve evaluation (a ``train_log.jsonl`` line with ``success``): the step
    and training seconds of the checkpoint, its held-out success and 95 % interval."""

    step: float
    success: float
    seconds: float | None = None
    ci95: tuple[float, float] | None = None
    episodes: int = 0


@dataclass
class TrainRun:
    """A trained policy: ``policy/<name>/train.json`` (as read), its loss log and its
    learning curve."""

    name: str
    meta: dict[str, Any] = field(default_factory=dict)
    log: list[LogRow] = field(default_factory=list)
    curve: list[CurvePoint] = field(default_factory=list)


@dataclass
class EvalRun:
    """``eval/<policy>/results.json`` and the rollout videos beside it.

    Attributes:
        name: the folder name; policy, kind: as recorded.
        success_rate: share of successful episodes (0..1); ci95: its 95 % interval.
        episodes, successes: counts; per_scene: scene -> ``{episodes, successes}``.
        failures: reason -> count; videos: ``videos/*.mp4|gif`` paths (sorted).
    """

    name: str
    policy: str
    kind: str
    success_rate: float
    ci95: tuple[float, float] | None
    episodes: int
    successes: int | None
    per_scene: dict[str, dict[str, Any]] = field(default_factory=dict)
    failures: dict[str, int] = field(default_factory=dict)
    videos: list[Path] = field(default_factory=list)
    seconds: float | None = None


@dataclass
class ScalingRow:
    """One point of ``eval/scaling.json``: success rate for a number of scenes and demos."""

    scenes: int
    demos: int
    success_rate: float
    ci95: tuple[float, float] | None = None


@dataclass
class RunData:
    """Everything the report shows; empty lists and None mean "no such data in this run"."""

    info: RunInfo
    scenes: list[SceneRow] = field(default_factory=list)
    variants: list[SceneRow] = field(default_factory=list)
    augment_result: dict[str, Any] = field(default_factory=dict)
    demos: DemoSummary | None = None
    dataset: DatasetInfo | None = None
    policies: list[TrainRun] = field(default_factory=list)
    evals: list[EvalRun] = field(default_factory=list)
    scaling: list[ScalingRow] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------------------------
# Helpers


def _read_json(path: Path, notes: list[str], root: Path) -> Any:
    """The JSON in ``path``, or None (with a note) if it cannot be read."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        notes.append(f"{_rel(path, root)}: unreadable ({type(e).__name__}: {e}); skipped")
        return None


def _rel(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def _num(value: Any) -> float | None:
    """A finite number, or None (bools are not numbers here)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _dict(value: Any) -> dict[str, Any]:
    """``value`` if it is a dict, else an empty one."""
    return value if isinstance(value, dict) else {}


def _int(value: Any) -> int | None:
    num = _num(value)
    return int(num) if num is not None and num == int(num) else None


def _ci(value: Any) -> tuple[float, float] | None:
    if isinstance(value, list | tuple) and len(value) == 2:
        lo, hi = _num(value[0]), _num(value[1])
        if lo is not None and hi is not None:
            return (lo, hi)
    return None


def _counts(value: Any) -> dict[str, int]:
    """A ``{reason: count}`` dict with the non-integer entries dropped."""
    if not isinstance(value, dict):
        return {}
    out = {str(k): n for k, v in value.items() if (n := _int(v)) is not None}
    return dict(sorted(out.items(), key=lambda kv: (-kv[1], kv[0])))


# --------------------------------------------------------------------------------------------
# Sections


def _run_info(root: Path, notes: list[str]) -> RunInfo:
    info = RunInfo(run_dir=root)
    path = root / "manifest.json"
    if not path.is_file():
        notes.append("manifest.json: missing (not a run directory made by factory?)")
        return info
    manifest = _read_json(path, notes, root)
    if not isinstance(manifest, dict):
        return info
    info.factory_version = str(manifest.get("factory_version") or "")
    info.git_sha = str(manifest.get("git_sha") or "")
    info.created = _num(manifest.get("created"))
    config = _dict(manifest.get("config"))
    info.profile = str(config.get("profile") or "")
    info.seed = _int(config.get("seed"))
    for name, rec in _dict(manifest.get("stages")).items():
        if not isinstance(rec, dict):
            continue
        shards = _dict(rec.get("shards"))
        secs = [
            s
            for sh in shards.values()
            if isinstance(sh, dict) and (s := _num(sh.get("seconds"))) is not None
        ]
        errors = [
            str(sh["error"]) for sh in shards.values() if isinstance(sh, dict) and sh.get("error")
        ]
        info.stages.append(
            StageRow(
                name=str(name),
                status=str(rec.get("status") or "?"),
                seconds=sum(secs) if secs else None,
                shards_done=sum(
                    1
                    for sh in shards.values()
                    if isinstance(sh, dict) and sh.get("status") == "done"
                ),
                shards=len(shards),
                error=errors[0] if errors else "",
                results=[
                    sh["result"]
                    for sh in shards.values()
                    if isinstance(sh, dict) and isinstance(sh.get("result"), dict)
                ],
            )
        )
    return info


def _validation(root: Path, notes: list[str]) -> dict[str, dict[str, Any]]:
    """Scene id -> ``validate/summary.json`` row."""
    path = root / "validate" / "summary.json"
    if not path.is_file():
        return {}
    data = _read_json(path, notes, root)
    rows = data.get("scenes") if isinstance(data, dict) else None
    if not isinstance(rows, list):
        if data is not None:
            notes.append("validate/summary.json: no 'scenes' list; validation table skipped")
        return {}
    return {str(r["scene"]): r for r in rows if isinstance(r, dict) and "scene" in r}


def _scene(root: Path, sid: str, validation: dict[str, Any], notes: list[str]) -> SceneRow | None:
    folder = root / "scenes" / sid
    data = _read_json(folder / "scene.json", notes, root)
    if not isinstance(data, dict):
        return None
    row = SceneRow(scene_id=sid, source=str(data.get("source") or ""))
    if row.source.startswith("augment:"):
        row.parent = row.source.split(":", 1)[1]
    row.description = str(data.get("description") or "")
    task = data.get("task")
    if isinstance(task, dict):
        row.instruction = str(task.get("instruction") or "")
    rooms = data.get("rooms")
    if isinstance(rooms, list):
        row.room_types = [str(r.get("room_type", "")) for r in rooms if isinstance(r, dict)]
    objects = data.get("objects")
    row.objects = len(objects) if isinstance(objects, list) else None
    row.renders = {
        v: folder / "renders" / f"{v}.png"
        for v in VIEWS
        if (folder / "renders" / f"{v}.png").is_file()
    }
    val = validation.get(sid)
    report_path = folder / "report.json"
    report = _read_json(report_path, notes, root) if report_path.is_file() else None
    if isinstance(val, dict):
        row.collision_pct = _num(val.get("collision_pct"))
        row.stability_pct = _num(val.get("stability_pct"))
        row.objects = _int(val.get("objects")) or row.objects
    elif isinstance(report, dict) and isinstance(report.get("validate"), dict):
        metrics = report["validate"].get("metrics")
        if isinstance(metrics, dict):
            coll, stab = metrics.get("collision"), metrics.get("stability")
            if isinstance(coll, dict) and (r := _num(coll.get("ratio"))) is not None:
                row.collision_pct = 100.0 * r
            if isinstance(stab, dict) and (r := _num(stab.get("ratio"))) is not None:
                row.stability_pct = 100.0 * r
    if isinstance(report, dict) and isinstance(report.get("augment"), dict):
        row.augment = report["augment"]
    return row


def _scenes(root: Path, notes: list[str]) -> tuple[list[SceneRow], list[SceneRow]]:
    folder = root / "scenes"
    if not folder.is_dir():
        return [], []
    validation = _validation(root, notes)
    scenes: list[SceneRow] = []
    variants: list[SceneRow] = []
    for d in sorted(folder.iterdir()):
        if not (d / "scene.json").is_file():
            continue
        row = _scene(root, d.name, validation, notes)
        if row is not None:
            (variants if row.parent is not None else scenes).append(row)
    return scenes, variants


_SUMMARY = re.compile(r"summary-(\d+)-of-(\d+)\.json")


def _demos(root: Path, notes: list[str]) -> DemoSummary | None:
    folder = root / "episodes"
    if not folder.is_dir():
        return None
    groups: dict[int, list[Path]] = {}
    for p in folder.iterdir():
        m = _SUMMARY.fullmatch(p.name)
        if m:
            groups.setdefault(int(m.group(2)), []).append(p)
    stores = sorted(p for p in folder.glob("shard-*.zarr") if p.is_dir())
    if not groups and not stores:
        return None
    out = DemoSummary()
    if groups:
        # The sharding of the latest demos run (older summaries of another count are stale).
        count = max(groups, key=lambda n: max(p.stat().st_mtime for p in groups[n]))
        if len(groups) > 1:
            notes.append(f"episodes/: summaries of {len(groups)} shard counts; shown: of {count}")
        failures: Counter[str] = Counter()
        for path in sorted(groups[count]):
            data = _read_json(path, notes, root)
            if not isinstance(data, dict):
                continue
            out.shards += 1
            out.stored += _int(data.get("episodes_stored")) or 0
            new = _int(data.get("new_successes")) or 0
            out.successes += new
            fails = _counts(data.get("failures"))
            failures.update(fails)
            out.attempts += new + sum(n for r, n in fails.items() if r != "scene_unusable")
            seconds = data.get("seconds")
            if isinstance(seconds, dict):
                out.seconds += _num(seconds.get("wall")) or 0.0
            out.frames += _int(data.get("frames")) or 0
            scenes = data.get("scenes")
            for sid, rec in (scenes or {}).items() if isinstance(scenes, dict) else ():
                if not isinstance(rec, dict):
                    continue
                s = out.per_scene.setdefault(str(sid), {"episodes": 0, "failures": Counter()})
                s["episodes"] += _int(rec.get("episodes")) or 0
                s["failures"].update(_counts(rec.get("failures")))
                if rec.get("error"):
                    s["error"] = str(rec["error"])
        out.failures = dict(failures.most_common())
        for s in out.per_scene.values():
            s["failures"] = dict(s["failures"].most_common())
    for store in stores:
        for d in sorted(store.iterdir()):
            if d.is_dir() and (d / "zarr.json").is_file():
                sid = d.name.rsplit("-ep", 1)[0]
                out.episodes.append(EpisodeRef(store=store, episode_id=d.name, scene_id=sid))
    if not groups:
        out.stored = len(out.episodes)
        notes.append("episodes/: no summary-<k>-of-<n>.json; success rate and failures unknown")
    return out


def _dataset(root: Path, notes: list[str]) -> DatasetInfo | None:
    path = root / "dataset" / "merged"
    card, info_path = path / "README.md", path / "meta" / "info.json"
    if not card.is_file() and not info_path.is_file():
        return None
    out = DatasetInfo(path=path)
    if card.is_file():
        try:
            out.card = card.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            notes.append(f"dataset/merged/README.md: unreadable ({e}); card skipped")
    if info_path.is_file():
        info = _read_json(info_path, notes, root)
        if isinstance(info, dict):
            out.info = info
    return out


def _train_runs(root: Path, notes: list[str]) -> list[TrainRun]:
    folder = root / "policy"
    if not folder.is_dir():
        return []
    runs: list[TrainRun] = []
    for d in sorted(p for p in folder.iterdir() if p.is_dir()):
        meta_path, log_path = d / "train.json", d / "train_log.jsonl"
        if not meta_path.is_file() and not log_path.is_file():
            continue
        run = TrainRun(name=d.name)
        if meta_path.is_file():
            meta = _read_json(meta_path, notes, root)
            if isinstance(meta, dict):
                run.meta = meta
            elif meta is not None:
                notes.append(f"{_rel(meta_path, root)}: not a JSON object; skipped")
        if log_path.is_file():
            run.log, run.curve = _train_log(log_path, notes, root)
        runs.append(run)
    return runs


def _train_log(path: Path, notes: list[str], root: Path) -> tuple[list[LogRow], list[CurvePoint]]:
    rows: list[LogRow] = []
    curve: list[CurvePoint] = []
    bad = 0
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        notes.append(f"{_rel(path, root)}: unreadable ({e}); loss curve skipped")
        return rows, curve
    for line in lines:
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            bad += 1
            continue
        step = _num(rec.get("step")) if isinstance(rec, dict) else None
        success = _num(rec.get("success")) if isinstance(rec, dict) else None
        if step is not None and success is not None:  # a learning-curve evaluation
            ci = rec.get("ci95")
            ci95 = None
            if isinstance(ci, list) and len(ci) == 2 and all(_num(v) is not None for v in ci):
                ci95 = (float(ci[0]), float(ci[1]))
            episodes = _num(rec.get("episodes"))
            curve.append(
                CurvePoint(step, success, _num(rec.get("seconds")), ci95, int(episodes or 0))
            )
            continue
        loss = _num(rec.get("loss")) if isinstance(rec, dict) else None
        if step is None or loss is None:
            bad += 1
            continue
        rows.append(LogRow(step, loss, _num(rec.get("lr")), _num(rec.get("seconds"))))
    if bad:
        notes.append(f"{_rel(path, root)}: {bad} line(s) without a numeric step and loss skipped")
    return rows, curve


def _evals(root: Path, notes: list[str]) -> list[EvalRun]:
    folder = root / "eval"
    if not folder.is_dir():
        return []
    runs: list[EvalRun] = []
    for d in sorted(p for p in folder.iterdir() if p.is_dir()):
        path = d / "results.json"
        if not path.is_file():
            continue
        data = _read_json(path, notes, root)
        if not isinstance(data, dict):
            continue
        rate, episodes = _num(data.get("success_rate")), _int(data.get("episodes"))
        if rate is None or episodes is None:
            notes.append(
                f"{_rel(path, root)}: no numeric success_rate and episodes; policy skipped"
            )
            continue
        per_scene = data.get("per_scene")
        videos = d / "videos"
        runs.append(
            EvalRun(
                name=d.name,
                policy=str(data.get("policy") or d.name),
                kind=str(data.get("kind") or ""),
                success_rate=rate,
                ci95=_ci(data.get("ci95")),
                episodes=episodes,
                successes=_int(data.get("successes")),
                per_scene={str(k): v for k, v in per_scene.items() if isinstance(v, dict)}
                if isinstance(per_scene, dict)
                else {},
                failures=_counts(data.get("failures")),
                videos=sorted(p for p in videos.glob("*") if p.suffix.lower() in (".mp4", ".gif"))
                if videos.is_dir()
                else [],
                seconds=_num(data.get("seconds")),
            )
        )
    return runs


def _scaling(root: Path, notes: list[str]) -> list[ScalingRow]:
    path = root / "eval" / "scaling.json"
    if not path.is_file():
        return []
    data = _read_json(path, notes, root)
    rows = data.get("rows") if isinstance(data, dict) else data
    if not isinstance(rows, list):
        if data is not None:
            notes.append("eval/scaling.json: no list of rows; scaling skipped")
        return []
    out: list[ScalingRow] = []
    for r in rows:
        if not isinstance(r, dict):
            continue
        scenes, demos, rate = (
            _int(r.get("scenes")),
            _int(r.get("demos")),
            _num(r.get("success_rate")),
        )
        if scenes is None or demos is None or rate is None:
            notes.append(f"eval/scaling.json: a row without scenes, demos and success_rate: {r}")
            continue
        out.append(ScalingRow(scenes, demos, rate, _ci(r.get("ci95"))))
    return sorted(out, key=lambda r: (r.scenes, r.demos))


def collect_run(run_dir: str | Path) -> RunData:
    """Reads everything the report shows from ``run_dir``.

    Args:
        run_dir: the run directory.

    Returns:
        the run's data; sections without files are empty, and files that could not be used are
        named in ``notes``.
    """
    root = Path(run_dir)
    notes: list[str] = []
    data = RunData(info=_run_info(root, notes), notes=notes)
    data.scenes, data.variants = _scenes(root, notes)
    for stage in data.info.stages:
        if stage.name == "augment":
            dropped: Counter[str] = Counter()
            for result in stage.results:
                for key in ("kept", "total"):
                    if (n := _int(result.get(key))) is not None:
                        data.augment_result[key] = data.augment_result.get(key, 0) + n
                dropped.update(_counts(result.get("dropped")))
            data.augment_result["dropped"] = dict(dropped.most_common())
    data.demos = _demos(root, notes)
    data.dataset = _dataset(root, notes)
    data.policies = _train_runs(root, notes)
    data.evals = _evals(root, notes)
    data.scaling = _scaling(root, notes)
    for note in notes:
        log.warning("report: %s", note)
    return data
