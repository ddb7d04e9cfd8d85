"""Renders every articulated category closed and open (every joint at its upper limit) into
one labelled sheet: pairs side by side, closed on the left.

MUJOCO_GL=egl python scripts/render_articulated_gallery.py \\
    [--out docs/images/articulated_gallery.png] [--size 200] [--columns 3]
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
    p.add_argument("--out", default="docs/images/articulated_gallery.png")
    p.add_argument("--size", type=int, default=200)
    p.add_argument("--columns", type=int, default=3, help="categories (pairs) per row")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    logging.basicConfig(level=logging.WARNING)
    size, cols = args.size, args.columns
    names = sorted(n for n, c in CATEGORIES.items() if c.articulated)
    rows = -(-len(names) // cols)
    label, pad = 16, 8
    cell = 2 * size + pad
    sheet = Image.new("RGB", (cols * cell - pad, rows * (size + label)), "white")
    draw = ImageDraw.Draw(sheet)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp), articulated=True)
        for i, name in enumerate(names):
            meta = lib.get(AssetSpec(name, seed=args.seed))
            r, c = divmod(i, cols)
            x, y = c * cell, r * (size + label)
            for k, opened in enumerate((0.0, 1.0)):
                # from the front-left, nearly square on: doors hinged on either edge show
                image = render_asset(
                    Path(tmp),
                    meta,
                    size,
                    size,
                    azimuth=65.0,
                    elevation=-20.0,
                    opened=opened,
                    margin=1.6,
                )
                sheet.paste(Image.fromarray(np.asarray(image)), (x + k * size, y))
            draw.text((x + 4, y + size + 2), f"{name}: closed | open", fill=(0, 0, 0))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, optimize=True)
    print(f"wrote {args.out}: {len(names)} categories in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
