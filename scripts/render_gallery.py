"""Renders one asset of every procedural category into a labelled contact sheet.

python scripts/render_gallery.py [--out docs/images/asset_gallery.png] [--size 160]
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

from factory.sim.gl import configure_gl

configure_gl("auto")

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec  # noqa: E402
from factory.assets.preview import render_asset  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/images/asset_gallery.png")
    p.add_argument("--size", type=int, default=160)
    p.add_argument("--columns", type=int, default=12)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    logging.basicConfig(level=logging.WARNING)
    size, cols = args.size, args.columns
    names = list(CATEGORIES)
    rows = -(-len(names) // cols)
    label = 16
    sheet = Image.new("RGB", (cols * size, rows * (size + label)), "white")
    draw = ImageDraw.Draw(sheet)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        for i, name in enumerate(names):
            meta = lib.get(AssetSpec(name, seed=args.seed))
            image = render_asset(Path(tmp), meta, size, size)
            r, c = divmod(i, cols)
            sheet.paste(Image.fromarray(np.asarray(image)), (c * size, r * (size + label)))
            draw.text((c * size + 4, r * (size + label) + size + 2), name, fill=(0, 0, 0))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, optimize=True)
    print(f"wrote {args.out}: {len(names)} categories in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
