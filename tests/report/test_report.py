"""``stage=report``: the page builder on synthetic runs, and the page in a real headless Chromium
(Debian's ``chromium``, driven by playwright) from file://, on synthetic runs and a real one."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from report_runs import HOSTILE, SECTIONS_ALL

from factory.config import FactoryConfig, ReportConfig
from factory.context import StageContext
from factory.errors import ConfigError
from factory.report.collect import collect_run
from factory.report.gifs import subsample, to_gif
from factory.report.markdown_html import markdown_to_html
from factory.report.media import MediaSink
from factory.report.page import build_page
from factory.report.stage import run as run_report
from factory.store import RunStore, Shard


def _run(run_dir: Path, **report: object) -> dict:
    cfg = FactoryConfig(stage="report", run_dir=str(run_dir))
    for k, v in report.items():
        setattr(cfg.report, k, v)
    return run_report(StageContext(cfg=cfg, store=RunStore(run_dir), shard=Shard()))


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m factory`` in a subprocess (one torch thread)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    repo = Path(__file__).resolve().parents[2]
    return subprocess.run(
        [sys.executable, "-m", "factory", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=repo,
        timeout=900,
    )


def _data_sections(html: str) -> list[str]:
    return re.search(r'<body data-sections="([^"]*)"', html)[1].split()


# --------------------------------------------------------------------------------------------
# The builder (no browser)


def test_full_run_has_every_section_and_escapes_file_text(full_run: Path) -> None:
    result = _run(full_run)
    path = full_run / "report.html"
    assert result["produced"] == [{"what": "report", "count": 1, "path": str(path)}]
    html = path.read_text()
    assert _data_sections(html) == SECTIONS_ALL
    assert result["sections"] == SECTIONS_ALL
    # Text from files is escaped wherever it appears (description, error, card, demo error).
    assert HOSTILE not in html and "<script" not in html.lower()
    assert html.count("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&amp;&lt;b&gt;") >= 3
    # The card's raw HTML (a badge loading images from the internet) is dropped; links kept.
    assert "example.org/badge.svg" not in html and "example.org/viz" not in html
    assert 'href="https://github.com/huggingface/lerobot"' in html
    assert 'href="dataset/merged/meta/info.json"' in html
    # Everything is embedded: no src that is not a data URI.
    srcs = re.findall(r'<img src="([^"]*)"', html)
    assert srcs and all(s.startswith("data:image/") for s in srcs)
    # thumbnails: 2 views of kitchen_a (kitchen_b has none) and of each of the 2 variants;
    # 2 demo GIFs; 2 eval media (an mp4 and a GIF)
    assert result["images"] == len(srcs) == 2 + 2 * 2 + 2 + 2
    assert "configuration: moved mug_0" in html
    assert "<td>batch_size, lr</td>" in html  # train.json's dicts: their keys
    # The training log's bad line is a note, the rest a curve; the failed stage shows its error.
    assert "train_log.jsonl: 1 line(s) without a numeric step and loss skipped" in html
    assert html.count("<polyline") >= 1 + 2  # loss curve, one line per scaling series
    assert '<span class="bad">failed</span>' in html
    # Demo success counts attempts, not unusable scenes: 2 of 3.
    assert "66.7 %" in html
    assert not (full_run / "report_files").exists()


def test_absent_data_means_absent_sections(scenes_only_run: Path) -> None:
    result = _run(scenes_only_run)
    html = (scenes_only_run / "report.html").read_text()
    assert result["sections"] == _data_sections(html) == ["scenes"]
    for sid in set(SECTIONS_ALL) - {"scenes"}:
        assert f'<section id="{sid}"' not in html
    assert "–" in html  # unvalidated: no collision or stability numbers


def test_relative_files_mode(full_run: Path) -> None:
    result = _run(full_run, embed=False, gifs=1, eval_videos=1, views=["top"])
    html = (full_run / "report.html").read_text()
    srcs = re.findall(r'<img src="([^"]*)"', html)
    assert len(srcs) == result["images"] == 1 + 2 + 1 + 1
    for src in srcs:
        assert src.startswith("report_files/") and (full_run / src).is_file(), src
    assert (full_run / "report_files" / "gifs" / "kitchen_a-ep000.gif").stat().st_size > 0


def test_broken_files_become_notes(full_run: Path) -> None:
    (full_run / "eval" / "act" / "results.json").write_text('{"policy": "act"}')
    (full_run / "validate" / "summary.json").write_text("{not json")
    (full_run / "scenes" / "kitchen_a" / "renders" / "top.png").write_bytes(b"not a png")
    data = collect_run(full_run)
    assert not data.evals
    assert any("results.json: no numeric success_rate" in n for n in data.notes)
    assert any("validate/summary.json: unreadable" in n for n in data.notes)
    built = build_page(data, ReportConfig(), MediaSink(full_run, embed=True))
    assert "evaluation" not in built.sections and "notes" in built.sections
    assert any("renders/top.png: unreadable" in n for n in built.notes)


def test_empty_run_directory(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    result = _run(run)
    html = (run / "report.html").read_text()
    assert result["sections"] == ["notes"] and "manifest.json: missing" in html


def test_bad_options_are_config_errors(scenes_only_run: Path) -> None:
    for bad in ({"gifs": -1}, {"gif_fps": 0.0}, {"views": ["side"]}, {"thumb_width": 4}):
        with pytest.raises(ConfigError, match="report\\."):
            _run(scenes_only_run, **bad)


def test_gif_helpers() -> None:
    import numpy as np

    assert subsample(40, 20.0, 10.0) == list(range(0, 40, 2))
    assert subsample(5, 10.0, 20.0) == [0, 1, 2, 3, 4]
    assert subsample(0, 20.0, 10.0) == []
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 255, (40, 64, 64, 3), dtype=np.uint8)  # incompressible
    data = to_gif(noise, 10.0, 64, max_bytes=60_000)
    assert data[:6] == b"GIF89a" and len(data) <= 60_000
    import io

    from PIL import Image

    with Image.open(io.BytesIO(data)) as im:
        assert im.size == (64, 64) and 1 < im.n_frames < 40  # thinned to fit


def test_gif_frames_decode_exactly() -> None:
    """A square moving over a still background (a few colours, so the palette is exact):
    every decoded frame is the frame given, although each stores only what changed (the
    rest transparent over the frame before)."""
    import io

    import numpy as np
    from PIL import Image, ImageSequence

    background = np.zeros((48, 64, 3), np.uint8)
    background[:, :32] = (200, 60, 30)
    background[24:] += np.uint8(40)
    frames = []
    for k in range(12):
        f = background.copy()
        f[10:20, 4 * k : 4 * k + 10] = (20, 220, 90)
        frames.append(f)
    data = to_gif(frames, 10.0, 64)
    with Image.open(io.BytesIO(data)) as im:
        decoded = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]
    assert len(decoded) == len(frames)
    for got, want in zip(decoded, frames, strict=True):
        assert np.array_equal(got, want)


def test_markdown_is_safe() -> None:
    html = markdown_to_html(
        "# T\n[x](javascript:alert) [y](../secret) [z](meta/info.json) [w](https://a.org/b)"
        " `<i>` **b** *e*\n\n<div onclick=x>\nraw\n</div>\n\n- a\n- b\n",
        "dataset/",
    )
    assert "javascript" not in html and "../secret" not in html  # unsafe targets: label only
    assert ">x</a>" not in html and ">y</a>" not in html
    assert '<a href="dataset/meta/info.json">z</a>' in html
    assert '<a href="https://a.org/b">w</a>' in html
    assert "<code>&lt;i&gt;</code>" in html
    assert "<strong>b</strong>" in html and "<em>e</em>" in html
    assert "onclick" not in html and "raw" not in html
    assert "<ul><li>a</li><li>b</li></ul>" in html and "<h3>T</h3>" in html


# --------------------------------------------------------------------------------------------
# In the browser


def _assert_page_ok(check, sections: list[str]) -> None:
    assert not check.console_errors, check.console_errors
    assert not check.page_errors, check.page_errors
    assert not check.failed, check.failed
    assert not check.external, check.external
    assert check.sections == ["stages", *sections], check.sections
    assert check.images, "no image on the page"
    bad = [i for i in check.images if not (i["complete"] and i["naturalWidth"] > 0)]
    assert not bad, bad


def test_browser_full_synthetic_run(full_run: Path, open_page) -> None:
    _run(full_run)
    check = open_page(full_run / "report.html")
    _assert_page_ok(check, SECTIONS_ALL)
    assert HOSTILE in check.text  # shown as text, not run
    assert check.title == "factory report: run"


def test_browser_relative_files_and_absent_sections(
    full_run: Path, scenes_only_run: Path, open_page
) -> None:
    _run(full_run, embed=False)
    _assert_page_ok(open_page(full_run / "report.html"), SECTIONS_ALL)
    _run(scenes_only_run, embed=False)
    check = open_page(scenes_only_run / "report.html")
    _assert_page_ok(check, ["scenes"])


@pytest.mark.slow
def test_browser_small_profile_run(small_run, open_page, tmp_path: Path) -> None:
    """The report that ``stage=all profile=small`` writes at its end, in the browser; then a
    copy of that run with an augmented variant, reported again."""
    run = small_run.run_dir
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["config"]["all"]["stages"][-1] == "report"
    result = manifest["stages"]["report"]["shards"]["0-of-1"]["result"]
    path = run / "report.html"
    assert result["produced"] == [{"what": "report", "count": 1, "path": str(path)}]
    # the small profile trains a policy for a few steps and evaluates it
    expected = ["scenes", "demos", "dataset", "policies", "evaluation"]
    assert result["sections"] == expected
    check = open_page(path)
    _assert_page_ok(check, expected)
    (scene,) = (p.name for p in (run / "scenes").iterdir())
    assert scene in check.text and "Recorded episodes" in check.text
    gifs = [i for i in check.images if i["src"].startswith("data:image/gif")]
    # one per stored episode (report.gifs=4) and the rollout video of eval.videos=1
    assert len(gifs) == 2 + 1
    assert len(check.images) == 2 + len(gifs)  # the scene's two views (report.views), GIFs

    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    common = ("profile=small", f"run_dir={copy}")
    out = _cli("stage=augment", *common, "augment.variants_per_scene=1")
    assert out.returncode == 0, out.stderr[-3000:]
    assert _cli("stage=report", *common, "report.embed=false").returncode == 0
    variants = [p.name for p in (copy / "scenes").iterdir() if "__" in p.name]
    expected = [expected[0], "augmentation", *expected[1:]] if variants else expected
    check = open_page(copy / "report.html", screenshot=tmp_path / "report.png")
    _assert_page_ok(check, expected)
    assert all(i["src"].startswith("report_files/") for i in check.images)
    assert all(v in check.text for v in variants)
    assert (tmp_path / "report.png").stat().st_size > 10_000


def test_browser_check_catches_broken_pages(tmp_path: Path, open_page) -> None:
    """The checks above can fail: a missing image, a script error, a remote request."""
    page = tmp_path / "bad.html"
    page.write_text(
        '<!DOCTYPE html><html><head><title>bad</title></head><body><section id="x"></section>'
        '<img src="missing.png"><img src="https://example.org/a.png">'
        "<script>undefined_function()</script></body></html>"
    )
    check = open_page(page)
    assert check.sections == ["x"]
    assert [i["naturalWidth"] for i in check.images] == [0, 0]
    assert check.page_errors and "undefined_function" in check.page_errors[0]
    assert check.external == ["https://example.org/a.png"]
    assert any("missing.png" in f for f in check.failed)


def test_cli_bad_option_is_one_line(scenes_only_run: Path) -> None:
    out = _cli("stage=report", f"run_dir={scenes_only_run}", "report.views=[side]")
    assert out.returncode == 2, out.stderr[-2000:]
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("factory: error:")]
    assert len(lines) == 1 and "report.views" in lines[0] and "Traceback" not in out.stderr
    assert not (scenes_only_run / "report.html").exists()
