"""What a stage produced and where to look: the short table the runner prints after a stage.

Convention for stage functions: the result dict (JSON-ready, recorded in the manifest) may hold
``"produced"``, a list of entries

    ``{"what": str, "count": int | None, "path": str, "detail": str (optional)}``

* ``what``: a plural noun phrase, e.g. ``"episodes"``, ``"scenes generated"``; with
  ``count == 1`` its first word is made singular (``"1 episode"``). With ``count`` None the
  phrase stands alone (``"policy checkpoint"``).
* ``path``: the file or folder to look at, absolute or relative to ``run_dir`` (a path built
  from the run directory, such as ``store.root / "policy"``, is given absolute: with a relative
  ``run_dir`` it would otherwise be read as relative to the run directory twice).
* ``detail``: a few more words after a comma (``"479 frames"``, ``"success 90 %"``).

Example: ``{"what": "episodes", "count": 2, "path": "dataset/merged", "detail": "479 frames"}``
prints as ``dataset  2 episodes, 479 frames  runs/small/dataset/merged/``. New stages
(``train``, ``eval``, ``report``) return such a list. For the stages that predate the
convention the entries are derived from the keys they already return (:data:`DERIVED`). A stage
with neither gets one row of its scalar results.

Only the standard library is imported here.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from factory.store import RunStore, Shard

Entry = dict[str, Any]
"""One ``"produced"`` entry: ``what``, ``count``, ``path``, optional ``detail``."""


@dataclass(frozen=True)
class Row:
    """One line of the table: the stage, what it produced (words) and the path to look at."""

    stage: str
    text: str
    path: str
    seconds: float | None = None


def _entry(what: str, count: int | None, path: str | Path, detail: str = "") -> Entry:
    entry: Entry = {"what": what, "count": count, "path": str(path)}
    if detail:
        entry["detail"] = detail
    return entry


def _int(result: Mapping[str, Any], key: str) -> int:
    value = result.get(key, 0)
    return int(value) if isinstance(value, int | float) else 0


def _up_to_date(result: Mapping[str, Any]) -> str:
    skipped = _int(result, "skipped")
    return f"{skipped} up to date" if skipped else ""


def _scenes(verb: str) -> Callable[[Mapping[str, Any], RunStore, Shard], list[Entry]]:
    def derive(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
        details = [_up_to_date(result)]
        if "scenes" in result:
            details.append(f"{_int(result, 'scenes')} in the run")
        detail = ", ".join(d for d in details if d)
        return [_entry(f"scenes {verb}", _int(result, "done"), "scenes/", detail)]

    return derive


def _augment(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    dropped = result.get("dropped") or {}
    n_dropped = sum(dropped.values()) if isinstance(dropped, Mapping) else 0
    details = [f"{n_dropped} dropped" if n_dropped else "", _up_to_date(result)]
    detail = ", ".join(d for d in details if d)
    return [_entry("variants kept", _int(result, "kept"), "scenes/", detail)]


def _compile(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    path = "scenes/*/model.xml"
    return [_entry("models compiled", _int(result, "done"), path, _up_to_date(result))]


def _render(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    path = "scenes/*/renders/"
    return [_entry("scenes rendered", _int(result, "done"), path, _up_to_date(result))]


def _validate(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    detail = ""
    if "collision_pct" in result and "stability_pct" in result:
        detail = (
            f"collision {float(result['collision_pct']):.1f} %, "
            f"stability {float(result['stability_pct']):.1f} %"
        )
    checks = result.get("checks")
    if isinstance(checks, Mapping):
        for name, c in checks.items():
            if isinstance(c, Mapping):
                ok, failed = int(c.get("passed", 0)), sum(dict(c.get("failed", {})).values())
                detail += f", {name} check {ok}/{ok + failed} passed"
    n = _int(result, "done") + _int(result, "skipped")
    return [_entry("scenes validated", n, "validate/summary.json", detail)]


def _export(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    out = Path(result["out"]).absolute() if result.get("out") else "export/"
    n = _int(result, "done") + _int(result, "skipped")
    return [_entry("scenes exported", n, out)]


def _demos(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    details = [f"{_int(result, 'new_successes')} new"]
    if "success_rate" in result:
        details.append(f"success {100 * float(result['success_rate']):.0f} %")
    failures = result.get("failures") or {}
    if isinstance(failures, Mapping) and failures:
        details.append("failed: " + ", ".join(f"{k} {v}" for k, v in sorted(failures.items())))
    return [
        _entry(
            "episodes stored",
            _int(result, "episodes_stored"),
            store.episodes_shard(shard).absolute(),
            ", ".join(details),
        ),
        _entry("demos summary", None, f"episodes/summary-{shard.name}.json"),
    ]


def _dataset(result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    path = Path(result["path"]).absolute() if result.get("path") else "dataset/"
    frames = _int(result, "export_frames")
    if "episodes" in result:  # every shard exported and merged
        detail = f"{frames} frames exported now" if frames else ""
        return [_entry("episodes", _int(result, "episodes"), path, detail)]
    detail = f"{frames} frames" if frames else "up to date"
    return [_entry("shards exported", _int(result, "exported"), path, detail)]


DERIVED: dict[str, Callable[[Mapping[str, Any], RunStore, Shard], list[Entry]]] = {
    "generate": _scenes("generated"),
    "ingest": _scenes("ingested"),
    "augment": _augment,
    "compile": _compile,
    "validate": _validate,
    "render": _render,
    "export": _export,
    "demos": _demos,
    "dataset": _dataset,
}
"""Stage -> its ``"produced"`` entries derived from the keys its result already has."""


def produced(stage: str, result: Mapping[str, Any], store: RunStore, shard: Shard) -> list[Entry]:
    """The ``"produced"`` entries of a stage's result (given, derived, or one generic entry)."""
    given = result.get("produced")
    if isinstance(given, Sequence) and not isinstance(given, str):
        return [dict(e) for e in given if isinstance(e, Mapping)]
    if stage in DERIVED:
        return DERIVED[stage](result, store, shard)
    scalars = [
        f"{k} {v}" for k, v in result.items() if isinstance(v, str | int | float) and k != "path"
    ]
    return [_entry(", ".join(scalars[:6]) or "done", None, result.get("path") or "")]


def _phrase(entry: Mapping[str, Any]) -> str:
    what = str(entry.get("what", "")).strip()
    count = entry.get("count")
    if count is None:
        text = what
    else:
        if count == 1:
            first, _, rest = what.partition(" ")
            if first.endswith("s") and not first.endswith("ss"):
                what = " ".join(w for w in (first[:-1], rest) if w)
        text = f"{count} {what}".strip()
    detail = str(entry.get("detail") or "").strip()
    return f"{text}, {detail}" if detail else text


def show_path(path: str | Path, root: Path) -> str:
    """``path`` (relative to ``root`` unless absolute) as the user would type it: relative to the
    working directory where it lies below it, else absolute; folders (existing ones, or given
    with a final ``/``) end with ``/``."""
    if str(path) == "":
        return ""
    folder = str(path).endswith("/")
    full = Path(path) if Path(path).is_absolute() else root / path
    absolute = Path(os.path.abspath(full))
    try:
        text = str(absolute.relative_to(Path.cwd()))
    except ValueError:
        text = str(absolute)
    return text + "/" if folder or ("*" not in text and absolute.is_dir()) else text


def stage_rows(
    stage: str,
    result: Mapping[str, Any],
    store: RunStore,
    shard: Shard,
    seconds: float | None = None,
    log: bool = True,
) -> list[Row]:
    """The table rows of one finished stage: its ``produced`` entries (the first one with
    ``seconds``), then, with ``log``, its log file."""
    rows = [
        Row(stage if i == 0 else "", _phrase(e), show_path(e.get("path") or "", store.root))
        for i, e in enumerate(produced(stage, result, store, shard))
    ]
    if rows and seconds is not None:
        rows[0] = Row(rows[0].stage, rows[0].text, rows[0].path, seconds)
    if log:
        path = (store.logs_dir / f"{stage}-{shard.name}.log").absolute()
        rows.append(Row("log", "all output, third-party too", show_path(path, store.root)))
    return rows


def run_rows(
    results: Mapping[str, Mapping[str, Any]],
    seconds: Mapping[str, float],
    store: RunStore,
    shard: Shard,
) -> list[Row]:
    """The rows of ``stage=all``: every stage's entries with its time, then the logs folder."""
    rows: list[Row] = []
    for stage, result in results.items():
        rows += stage_rows(stage, result, store, shard, seconds.get(stage), log=False)
    rows.append(
        Row(
            "logs",
            "one per stage, third-party output too",
            show_path(f"{store.logs_dir.absolute()}/", store.root),
        )
    )
    return rows


def format_table(title: str, rows: Sequence[Row]) -> str:
    """``title`` and the rows, two spaces in, columns aligned (one string, no final newline).

    Rows with ``seconds`` get a time column after the stage name.
    """
    timed = any(r.seconds is not None for r in rows)
    cells = [
        [r.stage]
        + ([f"{r.seconds:.1f} s" if r.seconds is not None else ""] if timed else [])
        + [r.text, r.path]
        for r in rows
    ]
    widths = [max(len(c[i]) for c in cells) for i in range(len(cells[0]))] if cells else []
    right = {1} if timed else set()
    lines = [title]
    for c in cells:
        parts = [
            v.rjust(w) if i in right else v.ljust(w)
            for i, (v, w) in enumerate(zip(c, widths, strict=True))
        ]
        lines.append("  " + "  ".join(parts).rstrip())
    return "\n".join(lines)
