"""Renders the same requests and seeds with an older committed revision of ``factory`` and with
this working tree, side by side (issue 17's before/after figure).

Both sides go through the CLI (``python -m factory stage=generate``, heuristic agent, renders
on): the older revision is exported with ``git archive`` into a temporary folder and run with
its own ``PYTHONPATH``; the tree's run uses this checkout. Each request gets the seed
``seed + 1000 * i`` (``stage=generate``'s rule), the same on both sides.

    python scripts/render_before_after.py [--before-rev 7b5a5f6^] [--view corner_0]
        [--out docs/images/visual_before_after.png]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REQUESTS = (
    "a kitchen where the robot picks up a mug and puts it in the bowl",
    "a cozy bedroom with a wooden desk",
    "a dusty old living room with a rusty metal shelf",
    "a child's room",
)
"""The requests of the figure, in order (the first three are the textures figure's)."""

log = logging.getLogger("render_before_after")


def run_cli(pythonpath: Path, run_dir: Path, args: argparse.Namespace) -> dict[str, Path]:
    """Runs ``stage=generate`` of the ``factory`` package under ``pythonpath`` into ``run_dir``.

    Returns:
        The render of ``args.view`` per request (a PNG path).
    """
    prompts = "[" + ",".join(json.dumps(r) for r in REQUESTS) + "]"
    cmd = [
        sys.executable,
        "-m",
        "factory",
        "stage=generate",
        f"run_dir={run_dir}",
        f"seed={args.seed}",
        f"generate.prompts={prompts}",
        f"render.width={args.width}",
        f"render.height={args.height}",
        f"render.views=[{args.view}]",
    ]
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    # cwd outside the checkout, so that ``-m factory`` resolves through PYTHONPATH only
    if not (args.reuse and (run_dir / "scenes").is_dir()):
        subprocess.run(cmd, env=env, check=True, cwd=run_dir.parent)
    found: dict[str, Path] = {}
    for report in sorted((run_dir / "scenes").glob("*/report.json")):
        request = json.loads(report.read_text())["generate"]["request"]
        found[request] = report.parent / "renders" / f"{args.view}.png"
    return found


def compose(
    before: dict[str, Path], after: dict[str, Path], labels: tuple[str, str], out: Path, seed: int
) -> None:
    """A sheet of rows: per request the 'before' render left of the 'after' render."""
    from PIL import Image, ImageDraw

    first = Image.open(next(iter(after.values())))
    w, h = first.size
    label = 16
    sheet = Image.new("RGB", (2 * w + 6, len(REQUESTS) * (h + label)), "white")
    draw = ImageDraw.Draw(sheet)
    for i, request in enumerate(REQUESTS):
        y = i * (h + label)
        draw.text((4, y + 2), f'"{request}", seed {seed + 1000 * i}', fill=(0, 0, 0))
        for k, (renders, tag) in enumerate(((before, labels[0]), (after, labels[1]))):
            x = k * (w + 6)
            path = renders.get(request)
            if path is not None and path.is_file():
                sheet.paste(Image.open(path).convert("RGB").resize((w, h)), (x, y + label))
            else:
                draw.text((x + 12, y + label + h // 2), "(no render)", fill=(120, 120, 120))
            box = draw.textbbox((x + 6, y + label + 4), tag)
            draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill="white")
            draw.text((x + 6, y + label + 4), tag, fill=(0, 0, 0))
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out, optimize=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before-rev", default="7b5a5f6^", help="git revision drawn as 'before'")
    p.add_argument("--out", default=str(ROOT / "docs/images/visual_before_after.png"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--view", default="corner_0")
    p.add_argument("--width", type=int, default=400)
    p.add_argument("--height", type=int, default=300)
    p.add_argument("--keep", default=None, help="folder for the two runs (default: temporary)")
    p.add_argument(
        "--reuse", action="store_true", help="with --keep: re-use its runs (only compose again)"
    )
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    t0 = time.perf_counter()
    rev = subprocess.run(
        ["git", "rev-parse", "--short", args.before_rev],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="before-after-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        old = work / "before_src"
        old.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(
            ["git", "archive", args.before_rev, "factory", "conf"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        before = run_cli(old, work / "run_before", args)
        log.info("before (%s): %d renders", rev, len(before))
        after = run_cli(ROOT, work / "run_after", args)
        log.info("after (working tree): %d renders", len(after))
        compose(
            before,
            after,
            (f"before ({rev}, committed)", "after (this tree)"),
            Path(args.out),
            args.seed,
        )
    log.info("wrote %s in %.1f s", args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
