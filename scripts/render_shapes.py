"""Renders the categories whose shapes were reworked, before (a committed revision of the
package, exported with ``git archive`` into a temporary folder) and after (this working tree),
side by side: same category, seed and size.

    python scripts/render_shapes.py [--before-rev HEAD] [--out docs/images/shapes_before_after.png]
    python scripts/render_shapes.py --tiles DIR     # only render this tree's tiles into DIR
"""

from __future__ import annotations

import argparse
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CATEGORIES = (
    "toilet",
    "clock",
    "table_lamp",
    "floor_lamp",
    "potted_plant",
    "small_plant",
    "curtain",
    "sofa",
    "armchair",
    "bed",
    "cushion",
    "dining_table",
    "dresser",
    "refrigerator",
    "oven",
    "microwave",
    "dishwasher",
    "washing_machine",
)


def render_tiles(out: Path, size: int, seed: int) -> None:
    """Renders each category this interpreter's ``factory`` knows into ``out/<name>.png``."""
    from factory.sim.gl import configure_gl

    configure_gl("auto")
    import numpy as np
    from PIL import Image

    from factory.assets import CATEGORIES as KNOWN
    from factory.assets import AssetLibrary, AssetSpec
    from factory.assets.preview import render_asset

    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        for name in CATEGORIES:
            if name not in KNOWN:
                continue
            meta = lib.get(AssetSpec(name, seed=seed))
            image = render_asset(Path(tmp), meta, size, size, azimuth=125.0, elevation=-20.0)
            Image.fromarray(np.asarray(image)).save(out / f"{name}.png")


def compose(before: Path, after: Path, out: Path, size: int, columns: int) -> None:
    """A sheet of column pairs: per category the 'before' tile above the 'after' tile."""
    from PIL import Image, ImageDraw

    label = 16
    blocks = -(-len(CATEGORIES) // columns)
    sheet = Image.new("RGB", (columns * size, blocks * (2 * size + 2 * label + 8)), "white")
    draw = ImageDraw.Draw(sheet)
    for i, name in enumerate(CATEGORIES):
        b, c = divmod(i, columns)
        x, y = c * size, b * (2 * size + 2 * label + 8)
        for k, (folder, tag) in enumerate(((before, "before"), (after, "after"))):
            tile = folder / f"{name}.png"
            top = y + k * (size + label)
            if tile.is_file():
                sheet.paste(Image.open(tile).convert("RGB"), (x, top))
            else:
                draw.rectangle((x + 4, top + 4, x + size - 4, top + size - 4), outline=(180,) * 3)
                draw.text((x + 12, top + size // 2), "(no such category)", fill=(120, 120, 120))
            draw.text((x + 4, top + size + 2), f"{name} - {tag}", fill=(0, 0, 0))
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out, optimize=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before-rev", default="HEAD", help="git revision drawn as 'before'")
    p.add_argument("--out", default=str(ROOT / "docs/images/shapes_before_after.png"))
    p.add_argument("--size", type=int, default=200)
    p.add_argument("--columns", type=int, default=9)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tiles", default=None, help="only render this tree's tiles into this folder")
    args = p.parse_args()
    logging.basicConfig(level=logging.WARNING)
    if args.tiles:
        render_tiles(Path(args.tiles), args.size, args.seed)
        return
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="shapes-") as tmp:
        old = Path(tmp) / "before"
        old.mkdir()
        archive = subprocess.run(
            ["git", "archive", args.before_rev, "factory"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        tiles = [Path(tmp) / "tiles_before", Path(tmp) / "tiles_after"]
        for pythonpath, folder in ((old, tiles[0]), (ROOT, tiles[1])):
            env = dict(os.environ, PYTHONPATH=str(pythonpath))
            cmd = [sys.executable, __file__, "--tiles", str(folder)]
            cmd += ["--size", str(args.size), "--seed", str(args.seed)]
            subprocess.run(cmd, env=env, check=True, cwd=tmp)
        compose(tiles[0], tiles[1], Path(args.out), args.size, args.columns)
    print(f"wrote {args.out} in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
