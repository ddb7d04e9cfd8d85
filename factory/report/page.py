"""Writes the report page from :class:`~factory.report.collect.RunData`.

One HTML document with inline CSS and no script: a header with the run's stages and times, then
a section per kind of data that the run has (``<section id="scenes">``, ``augmentation``,
``demos``, ``dataset``, ``policies``, ``evaluation``, ``scaling``) and a ``notes`` section naming
what could not be shown. Every string that comes from a file is escaped.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from html import escape
from typing import Any

from factory.config import ReportConfig
from factory.report.charts import Series, line_chart
from factory.report.collect import DemoSummary, EvalRun, RunData, SceneRow, TrainRun
from factory.report.markdown_html import markdown_to_html
from factory.report.media import MediaSink, thumbnail

log = logging.getLogger(__name__)

SECTIONS: dict[str, str] = {
    "scenes": "Scenes",
    "augmentation": "Augmentation",
    "demos": "Demonstrations",
    "dataset": "Dataset",
    "policies": "Policies",
    "evaluation": "Evaluation",
    "scaling": "Scaling",
    "notes": "Notes",
}
"""Section id -> heading, in page order."""

MAX_ROWS = 200
"""Rows of a long table shown (the rest are counted)."""

CSS = """
:root { --fg:#1d2330; --muted:#5b6475; --line:#dde1e8; --bg:#f6f7f9; --ok:#1a7f37; --bad:#c62828; }
* { box-sizing: border-box; }
body { margin:0; font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;
  color:var(--fg); background:var(--bg); }
header { background:#1d2330; color:#fff; padding:18px 28px 14px; }
header h1 { margin:0 0 4px; font-size:22px; }
header .meta { color:#c9d1e0; font-size:13px; }
header .meta code { color:#fff; }
nav { position:sticky; top:0; z-index:1; background:#fff; border-bottom:1px solid var(--line);
  padding:8px 28px; }
nav a { margin-right:16px; color:#2356a8; text-decoration:none; font-weight:600; }
main { padding:8px 28px 40px; max-width:1400px; }
section { background:#fff; border:1px solid var(--line); border-radius:8px; margin:18px 0;
  padding:6px 20px 18px; }
h2 { font-size:19px; margin:14px 0 8px; }
h3 { font-size:15px; margin:16px 0 6px; }
table { border-collapse:collapse; margin:6px 0 10px; font-size:13px; }
th, td { border-bottom:1px solid var(--line); padding:4px 10px; text-align:left;
  vertical-align:top; }
th { background:#f0f2f5; font-weight:600; }
td.num, th.num { text-align:right; font-variant-numeric:tabular-nums; }
.kpis { display:flex; flex-wrap:wrap; gap:12px; margin:8px 0 12px; }
.kpi { border:1px solid var(--line); border-radius:6px; padding:8px 14px; min-width:130px; }
.kpi b { display:block; font-size:20px; }
.kpi span { color:var(--muted); font-size:12px; }
.gallery { display:flex; flex-wrap:wrap; gap:14px; }
figure { margin:0; border:1px solid var(--line); border-radius:6px; padding:6px;
  background:#fafbfc; }
figure img { display:block; max-width:100%; height:auto; image-rendering:auto; }
figure .views { display:flex; gap:4px; }
figcaption { font-size:12px; color:var(--muted); margin-top:4px; max-width:660px; }
.ok { color:var(--ok); } .bad { color:var(--bad); }
.bar { display:inline-block; height:10px; background:#2356a8; border-radius:2px;
  vertical-align:middle; margin-right:6px; }
.muted { color:var(--muted); }
details summary { cursor:pointer; font-weight:600; margin:8px 0; }
.card { border-left:3px solid var(--line); padding-left:14px; }
pre { background:#f0f2f5; padding:8px; overflow:auto; max-height:360px; font-size:12px; }
svg.chart { max-width:100%; height:auto; }
svg.chart text { font:11px system-ui,sans-serif; fill:#444; }
svg.chart text.axis { font-size:12px; fill:#222; }
"""


@dataclass
class Built:
    """The page and what it shows: the section ids present, extra notes made while building."""

    html: str
    sections: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    images: int = 0


def _pct(v: float | None, digits: int = 1) -> str:
    return "–" if v is None else f"{v:.{digits}f} %"


def _secs(s: float | None) -> str:
    if s is None:
        return "–"
    if s < 120:
        return f"{s:.1f} s"
    if s < 7200:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.2f} h"


def _kpi(value: str, label: str) -> str:
    return f'<div class="kpi"><b>{escape(value)}</b><span>{escape(label)}</span></div>'


def _table(head: list[str], rows: list[list[str]], num: set[int] | None = None) -> str:
    """A table; cells are HTML already (callers escape), ``num`` columns right-aligned."""
    num = num or set()
    shown = rows[:MAX_ROWS]
    th = "".join(
        f"<th{' class=num' if i in num else ''}>{escape(h)}</th>" for i, h in enumerate(head)
    )
    body = "".join(
        "<tr>"
        + "".join(f"<td{' class=num' if i in num else ''}>{c}</td>" for i, c in enumerate(r))
        + "</tr>"
        for r in shown
    )
    more = (
        f'<p class="muted">… and {len(rows) - len(shown)} more rows.</p>'
        if len(rows) > len(shown)
        else ""
    )
    return f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>{more}"


def _counts_table(counts: dict[str, int], what: str) -> str:
    total = sum(counts.values()) or 1
    return _table(
        [what, "count", "share"],
        [[f"<code>{escape(k)}</code>", str(n), _pct(100 * n / total)] for k, n in counts.items()],
        {1, 2},
    )


def _rate_bar(rate: float) -> str:
    return f'<span class="bar" style="width:{max(1.0, 100 * rate):.0f}px"></span>'


class _Builder:
    def __init__(self, data: RunData, cfg: ReportConfig, sink: MediaSink) -> None:
        self.data = data
        self.cfg = cfg
        self.sink = sink
        self.notes: list[str] = []
        self.images = 0

    # -- images --------------------------------------------------------------------------

    def _img(self, src: str, alt: str, width: int | None = None) -> str:
        self.images += 1
        w = f' width="{width}"' if width else ""
        return f'<img src="{escape(src)}" alt="{escape(alt)}"{w}>'

    def _gif(self, data: bytes, name: str, alt: str) -> str:
        """An ``<img>`` of a GIF, shown at twice its size if it is small (128 px frames)."""
        import io

        from PIL import Image

        with Image.open(io.BytesIO(data)) as im:
            width = im.width
        src = self.sink.add(data, name, "image/gif")
        return self._img(src, alt, 2 * width if width <= 160 else None)

    def _thumb(self, scene: SceneRow, view: str) -> str:
        path = scene.renders.get(view)
        if path is None:
            return ""
        try:
            data = thumbnail(path, self.cfg.thumb_width)
        except OSError as e:
            self.notes.append(f"scenes/{scene.scene_id}/renders/{view}.png: unreadable ({e})")
            return ""
        src = self.sink.add(data, f"thumbs/{scene.scene_id}_{view}.jpg", "image/jpeg")
        img = self._img(src, f"{scene.scene_id} {view}")
        return f'<a href="{escape(self.sink.link(path))}">{img}</a>'

    # -- sections ------------------------------------------------------------------------

    def header(self) -> tuple[str, str]:
        """The page header and the stages section (manifest.json)."""
        info = self.data.info
        created = (
            time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(info.created)) if info.created else "–"
        )
        meta = [
            f"run <code>{escape(str(info.run_dir))}</code>",
            f"created {escape(created)}",
        ]
        if info.profile:
            meta.append(f"profile <code>{escape(info.profile)}</code>")
        if info.seed is not None:
            meta.append(f"seed {info.seed}")
        if info.factory_version:
            meta.append(f"factory {escape(info.factory_version)}")
        if info.git_sha:
            meta.append(f"git <code>{escape(info.git_sha[:12])}</code>")
        stages = [s for s in info.stages if s.name != "report"]
        rows = []
        for s in stages:
            cls = "ok" if s.status == "done" else "bad" if s.status == "failed" else "muted"
            rows.append(
                [
                    f"<code>{escape(s.name)}</code>",
                    f'<span class="{cls}">{escape(s.status)}</span>',
                    f"{s.shards_done}/{s.shards}",
                    _secs(s.seconds),
                    escape(s.error[:200]),
                ]
            )
        total = sum(s.seconds or 0.0 for s in stages)
        table = (
            _table(["stage", "status", "shards done", "time", "error"], rows, {2, 3})
            + f'<p class="muted">Stage time summed over shards: {_secs(total)}.</p>'
            if rows
            else '<p class="muted">No stage recorded in manifest.json.</p>'
        )
        return (
            "<header><h1>factory run report</h1>"
            f'<div class="meta">{" · ".join(meta)}</div></header>',
            f'<section id="stages"><h2>Stages</h2>{table}</section>',
        )

    def scenes(self) -> str:
        scenes = self.data.scenes
        if not scenes:
            return ""
        rows = [
            [
                f"<code>{escape(s.scene_id)}</code>",
                escape(s.source),
                escape(", ".join(s.room_types)),
                str(s.objects) if s.objects is not None else "–",
                _pct(s.collision_pct),
                _pct(s.stability_pct),
                escape(s.instruction or s.description),
            ]
            for s in scenes
        ]
        validated = [s for s in scenes if s.stability_pct is not None]
        objects = sum(s.objects or 0 for s in scenes)
        kpis = _kpi(str(len(scenes)), "scenes") + _kpi(str(objects), "objects")
        if validated:
            n = sum(s.objects or 0 for s in validated) or 1
            coll = sum((s.collision_pct or 0) * (s.objects or 0) for s in validated) / n
            stab = sum((s.stability_pct or 0) * (s.objects or 0) for s in validated) / n
            kpis += _kpi(_pct(coll), "collision (objects)") + _kpi(_pct(stab), "stable (objects)")
        gallery = []
        for s in scenes[: self.cfg.max_scenes]:
            views = "".join(self._thumb(s, v) for v in self.cfg.views)
            if views:
                caption = escape(s.scene_id + (f": {s.description}" if s.description else ""))
                gallery.append(
                    f'<figure><div class="views">{views}</div><figcaption>{caption}</figcaption>'
                    "</figure>"
                )
        more = (
            f'<p class="muted">Renders of the first {self.cfg.max_scenes} of {len(scenes)} '
            "scenes (report.max_scenes).</p>"
            if len(scenes) > self.cfg.max_scenes
            else ""
        )
        return (
            f'<div class="kpis">{kpis}</div>'
            + _table(
                ["scene", "source", "rooms", "objects", "collision", "stable", "request / task"],
                rows,
                {3, 4, 5},
            )
            + (f'<h3>Renders</h3><div class="gallery">{"".join(gallery)}</div>' if gallery else "")
            + more
        )

    def augmentation(self) -> str:
        variants = self.data.variants
        res = self.data.augment_result
        if not variants and not res.get("total"):
            return ""
        kpis = _kpi(str(len(variants)), "variants kept")
        if res.get("total"):
            kpis += _kpi(_pct(100 * res.get("kept", 0) / res["total"]), "acceptance (last run)")
        parts = [f'<div class="kpis">{kpis}</div>']
        if res.get("dropped"):
            parts.append(
                "<h3>Dropped variants</h3>" + _counts_table(res["dropped"], "level: reason")
            )
        by_parent: dict[str, list[SceneRow]] = {}
        for v in variants:
            by_parent.setdefault(v.parent or "?", []).append(v)
        shown = 0
        for parent, group in by_parent.items():
            rows = []
            figures = []
            for v in group:
                levels = v.augment.get("levels")
                rows.append(
                    [
                        f"<code>{escape(v.scene_id)}</code>",
                        escape(", ".join(map(str, levels)) if isinstance(levels, list) else "–"),
                        escape(str(v.augment.get("seed", "–"))),
                        escape(_changes(v.augment.get("applied"))),
                        str(v.objects) if v.objects is not None else "–",
                        _pct(v.collision_pct),
                        _pct(v.stability_pct),
                    ]
                )
                if shown < self.cfg.max_scenes:
                    views = "".join(self._thumb(v, view) for view in self.cfg.views)
                    if views:
                        shown += 1
                        figures.append(
                            f'<figure><div class="views">{views}</div>'
                            f"<figcaption>{escape(v.scene_id)}</figcaption></figure>"
                        )
            parts.append(
                f"<h3>Variants of <code>{escape(parent)}</code> ({len(group)})</h3>"
                + _table(
                    ["variant", "levels", "seed", "changes", "objects", "collision", "stable"],
                    rows,
                    {4, 5, 6},
                )
                + (f'<div class="gallery">{"".join(figures)}</div>' if figures else "")
            )
        return "".join(parts)

    def demos(self) -> str:
        d: DemoSummary | None = self.data.demos
        if d is None or (not d.stored and not d.attempts):
            return ""
        rate = d.success_rate
        kpis = (
            _kpi(str(d.stored), "episodes stored")
            + _kpi(_pct(None if rate is None else 100 * rate), "success (last runs' attempts)")
            + _kpi(str(d.frames), "frames recorded (last runs)")
            + _kpi(_secs(d.seconds), "wall time, summed over shards")
        )
        parts = [f'<div class="kpis">{kpis}</div>']
        if d.failures:
            parts.append("<h3>Failure reasons</h3>" + _counts_table(d.failures, "reason"))
        elif d.attempts:
            parts.append('<p class="ok">No failed attempt.</p>')
        if d.per_scene:
            rows = [
                [
                    f"<code>{escape(sid)}</code>",
                    str(s.get("episodes", 0)),
                    escape(", ".join(f"{k}: {n}" for k, n in s.get("failures", {}).items()) or "–"),
                    escape(str(s.get("error", ""))),
                ]
                for sid, s in sorted(d.per_scene.items())
            ]
            parts.append(
                "<h3>Per scene</h3>"
                + _table(["scene", "episodes stored", "failed attempts", "error"], rows, {1})
            )
        parts.append(self._demo_gifs(d))
        return "".join(parts)

    def _demo_gifs(self, d: DemoSummary) -> str:
        if self.cfg.gifs <= 0 or not d.episodes:
            return ""
        from factory.report.gifs import episode_gif

        # Spread over scenes: the first episode of each scene, then the second, ...
        by_scene: dict[str, list[Any]] = {}
        for ref in d.episodes:
            by_scene.setdefault(ref.scene_id, []).append(ref)
        order = [
            refs[k]
            for k in range(max(len(v) for v in by_scene.values()))
            for refs in by_scene.values()
            if k < len(refs)
        ]
        figures = []
        for ref in order[: self.cfg.gifs]:
            try:
                data, cam = episode_gif(
                    ref.store,
                    ref.episode_id,
                    self.cfg.gif_camera,
                    self.cfg.gif_fps,
                    self.cfg.gif_size,
                )
            except Exception as e:  # a report never fails on one GIF
                self.notes.append(f"GIF of episode {ref.episode_id}: {type(e).__name__}: {e}")
                continue
            img = self._gif(data, f"gifs/{ref.episode_id}.gif", f"episode {ref.episode_id}")
            figures.append(
                f"<figure>{img}"
                f"<figcaption>{escape(ref.episode_id)} ({escape(cam)} camera)</figcaption></figure>"
            )
        if not figures:
            return ""
        return f'<h3>Recorded episodes</h3><div class="gallery">{"".join(figures)}</div>'

    def dataset(self) -> str:
        ds = self.data.dataset
        if ds is None:
            return ""
        info = ds.info
        parts = []
        facts = [
            (k, info[k])
            for k in (
                "total_episodes",
                "total_frames",
                "fps",
                "total_tasks",
                "robot_type",
                "codebase_version",
            )
            if k in info and not isinstance(info[k], dict | list)
        ]
        if facts:
            parts.append(
                '<div class="kpis">'
                + "".join(_kpi(str(v), k.replace("_", " ")) for k, v in facts)
                + "</div>"
            )
        features = info.get("features")
        if isinstance(features, dict) and features:
            rows = []
            for key, feat in features.items():
                feat = feat if isinstance(feat, dict) else {}
                shape = feat.get("shape")
                rows.append(
                    [
                        f"<code>{escape(str(key))}</code>",
                        escape(str(feat.get("dtype", ""))),
                        escape(" x ".join(map(str, shape)) if isinstance(shape, list) else ""),
                    ]
                )
            parts.append("<h3>Features</h3>" + _table(["feature", "dtype", "shape"], rows))
        parts.append(
            f'<p class="muted">Folder: <a href="{escape(self.sink.link(ds.path))}/">'
            f"{escape(str(ds.path.relative_to(self.sink.run_dir)))}</a></p>"
        )
        if ds.card:
            base = self.sink.link(ds.path) + "/"
            parts.append(
                "<details><summary>Dataset card (README.md)</summary>"
                f'<div class="card">{markdown_to_html(ds.card, base)}</div></details>'
            )
        return "".join(parts)

    def policies(self) -> str:
        runs = self.data.policies
        if not runs:
            return ""
        return "".join(self._train_run(r) for r in runs)

    def _train_run(self, run: TrainRun) -> str:
        meta_rows = [
            [f"<code>{escape(str(k))}</code>", escape(_short(v))]
            for k, v in run.meta.items()
            if k != "schema_version"
        ]
        parts = [f"<h3>Policy <code>{escape(run.name)}</code></h3>"]
        if meta_rows:
            parts.append(_table(["train.json", "value"], meta_rows))
        if run.log:
            losses = [r.loss for r in run.log]
            positive = all(v > 0 for v in losses)
            log_y = positive and max(losses) / min(losses) > 30
            chart = line_chart(
                [Series("loss", [r.step for r in run.log], losses)],
                title=f"training loss of {run.name}",
                x_label="step",
                y_label="loss" + (" (log scale)" if log_y else ""),
                log_y=log_y,
                markers=len(run.log) <= 30,
            )
            if chart:
                parts.append(
                    f'<figure class="curve" data-policy="{escape(run.name)}">{chart}'
                    f"<figcaption>Training loss ({len(run.log)} logged steps, last "
                    f"{losses[-1]:.4g}).</figcaption></figure>"
                )
        elif not meta_rows:
            parts.append('<p class="muted">No train.json content and no logged step.</p>')
        if run.curve:
            pts = sorted(run.curve, key=lambda p: p.step)
            series = [
                Series("held-out success", [p.step for p in pts], [100 * p.success for p in pts])
            ]
            if all(p.ci95 for p in pts):
                series += [
                    Series("95 % CI low", [p.step for p in pts], [100 * p.ci95[0] for p in pts]),  # type: ignore[index]
                    Series("95 % CI high", [p.step for p in pts], [100 * p.ci95[1] for p in pts]),  # type: ignore[index]
                ]
            chart = line_chart(
                series,
                title=f"learning curve of {run.name}",
                x_label="step",
                y_label="success (%)",
                y_range=(0.0, 100.0),
                markers=True,
            )
            rows = [
                [
                    f"{int(p.step)}",
                    "–" if p.seconds is None else f"{p.seconds / 60:.1f}",
                    f"{100 * p.success:.1f} %",
                    "–" if p.ci95 is None else f"{100 * p.ci95[0]:.1f}–{100 * p.ci95[1]:.1f} %",
                    f"{p.episodes}",
                ]
                for p in pts
            ]
            if chart:
                parts.append(
                    f'<figure class="curve" data-policy="{escape(run.name)}">{chart}'
                    f"<figcaption>Held-out success during training ({len(pts)} evaluations "
                    "of train.eval_every_minutes).</figcaption></figure>"
                )
            parts.append(
                _table(["step", "training minutes", "success", "95 % CI", "episodes"], rows)
            )
        return "".join(parts)

    def evaluation(self) -> str:
        evals = self.data.evals
        if not evals:
            return ""
        rows = []
        for e in evals:
            ci = f"{100 * e.ci95[0]:.1f}–{100 * e.ci95[1]:.1f} %" if e.ci95 else "–"
            fails = ", ".join(f"{k}: {n}" for k, n in e.failures.items()) or "–"
            rows.append(
                [
                    f"<code>{escape(e.policy)}</code>",
                    escape(e.kind),
                    f"{_rate_bar(e.success_rate)}{_pct(100 * e.success_rate)}",
                    ci,
                    str(e.episodes),
                    escape(fails),
                    _secs(e.seconds),
                ]
            )
        parts = [
            _table(
                ["policy", "kind", "success", "95 % CI", "episodes", "failures", "time"],
                rows,
                {3, 4},
            )
        ]
        for e in evals:
            parts.append(self._eval_detail(e))
        return "".join(parts)

    def _eval_detail(self, e: EvalRun) -> str:
        parts = [f"<h3>{escape(e.policy)}</h3>"]
        if e.per_scene:
            rows = []
            for sid, s in e.per_scene.items():
                n, k = s.get("episodes"), s.get("successes")
                rate = k / n if isinstance(n, int) and isinstance(k, int) and n > 0 else None
                rows.append(
                    [
                        f"<code>{escape(sid)}</code>",
                        escape(str(n)),
                        escape(str(k)),
                        _pct(None if rate is None else 100 * rate),
                    ]
                )
            parts.append(_table(["scene", "episodes", "successes", "success"], rows, {1, 2, 3}))
        if e.failures:
            parts.append(_counts_table(e.failures, "failure reason"))
        figures = []
        if self.cfg.eval_videos > 0 and e.videos:
            from factory.report.gifs import video_gif

            for path in e.videos[: self.cfg.eval_videos]:
                try:
                    data = video_gif(path, self.cfg.gif_fps, max(self.cfg.gif_size, 384))
                except Exception as ex:  # a report never fails on one video
                    self.notes.append(
                        f"eval/{e.name}/videos/{path.name}: {type(ex).__name__}: {ex}"
                    )
                    continue
                img = self._gif(data, f"eval/{e.name}/{path.stem}.gif", f"rollout {path.stem}")
                figures.append(
                    f"<figure>{img}"
                    f'<figcaption><a href="{escape(self.sink.link(path))}">{escape(path.name)}</a>'
                    "</figcaption></figure>"
                )
        if figures:
            parts.append(f'<div class="gallery">{"".join(figures)}</div>')
        return "".join(parts)

    def scaling(self) -> str:
        rows = self.data.scaling
        if not rows:
            return ""
        by_scenes: dict[int, list[Any]] = {}
        for r in rows:
            by_scenes.setdefault(r.scenes, []).append(r)
        series = [
            Series(
                f"{n} scene{'s' if n != 1 else ''}",
                [float(r.demos) for r in group],
                [100 * r.success_rate for r in group],
                [100 * r.ci95[0] if r.ci95 else math.nan for r in group],
                [100 * r.ci95[1] if r.ci95 else math.nan for r in group],
            )
            for n, group in sorted(by_scenes.items())
        ]
        chart = line_chart(
            series,
            title="success rate against demonstrations",
            x_label="demonstrations",
            y_label="success rate (%)",
            y_range=(0.0, 100.0),
            markers=True,
        )
        table = _table(
            ["scenes", "demos", "success", "95 % CI"],
            [
                [
                    str(r.scenes),
                    str(r.demos),
                    _pct(100 * r.success_rate),
                    f"{100 * r.ci95[0]:.1f}–{100 * r.ci95[1]:.1f} %" if r.ci95 else "–",
                ]
                for r in rows
            ],
            {0, 1, 2, 3},
        )
        return (f'<figure class="curve">{chart}</figure>' if chart else "") + table


def _changes(applied: Any) -> str:
    """What a variant changed, from its ``report.json`` ``augment.applied`` records:
    ``configuration: moved bowl_0, mug_0`` (the keys of each record's dict values)."""
    if not isinstance(applied, list):
        return "–"
    parts = []
    for rec in applied:
        if not isinstance(rec, dict):
            continue
        what = [
            f"{k} {', '.join(map(str, v)) if isinstance(v, dict | list) else v}"
            for k, v in rec.items()
            if k != "level" and not isinstance(v, bool)
        ]
        parts.append(f"{rec.get('level', '?')}: {'; '.join(what)}")
    return _short(" | ".join(parts)) if parts else "–"


def _short(value: Any, limit: int = 160) -> str:
    """A value of train.json as one short line (a dict: its keys)."""
    import json

    if isinstance(value, str):
        text = value
    elif isinstance(value, float):
        text = f"{value:.6g}"
    elif isinstance(value, dict):
        text = ", ".join(map(str, value)) or "{}"
    else:
        text = json.dumps(value, default=str)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def build_page(data: RunData, cfg: ReportConfig, sink: MediaSink) -> Built:
    """The report page of a run.

    Args:
        data: what :func:`factory.report.collect.collect_run` read.
        cfg: ``report.*`` options (GIFs, thumbnails, embedding).
        sink: where images go (data URIs or ``report_files/``).

    Returns:
        the HTML and the ids of the sections it shows.
    """
    b = _Builder(data, cfg, sink)
    bodies: dict[str, str] = {}
    for sid in SECTIONS:
        if sid == "notes":
            continue
        body = getattr(b, sid)()
        if body:
            bodies[sid] = body
    notes = data.notes + b.notes
    if notes:
        bodies["notes"] = (
            '<p class="muted">Files that exist but could not be shown in full:</p><ul>'
            + "".join(f"<li>{escape(n)}</li>" for n in notes)
            + "</ul>"
        )
    if not bodies:
        bodies_html = (
            '<section id="empty"><h2>Nothing yet</h2><p>This run has no scenes, '
            "demonstrations, dataset or policy results yet.</p></section>"
        )
    else:
        bodies_html = "".join(
            f'<section id="{sid}"><h2>{SECTIONS[sid]}</h2>{body}</section>'
            for sid, body in bodies.items()
        )
    header, stages = b.header()
    nav = '<a href="#stages">Stages</a>' + "".join(
        f'<a href="#{sid}">{SECTIONS[sid]}</a>' for sid in bodies
    )
    title = f"factory report: {data.info.run_dir.name}"
    html = (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{escape(title)}</title><style>{CSS}</style></head>"
        f'<body data-sections="{" ".join(bodies)}">'
        f"{header}<nav>{nav}</nav><main>{stages}{bodies_html}</main>"
        '<footer class="muted" style="padding:0 28px 24px">Written by '
        "<code>python -m factory stage=report</code> from the run directory's files.</footer>"
        "</body></html>\n"
    )
    return Built(html=html, sections=list(bodies), notes=notes, images=b.images)
