"""Writes a GIF (and a PNG strip) of one recorded episode: its camera views side by side.

Usage: python scripts/render_demo.py RUN_DIR [--episode ID] [--out docs/images/demo.gif]
    [--depth] [--every 2]
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from factory.demos.episodes import EpisodeStore

log = logging.getLogger("render_demo")


def depth_rgb(depth: np.ndarray, scale_mm: float = 3000.0) -> np.ndarray:
    """Depth (H, W) uint16 mm or float m -> grey RGB (near is bright)."""
    d = depth.astype(np.float32)
    if depth.dtype != np.uint16:
        d = d * 1000.0
    g = np.clip(255 * (1 - d / scale_mm), 0, 255).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=-1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--episode", default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/images/demo.gif"))
    ap.add_argument("--depth", action="store_true", help="add a row of depth images")
    ap.add_argument("--every", type=int, default=2, help="keep every n-th frame")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    stores = sorted((args.run_dir / "episodes").glob("shard-*.zarr"))
    if not stores:
        raise SystemExit(f"no episode stores under {args.run_dir / 'episodes'}: run stage=demos")
    store = EpisodeStore(stores[0])
    eid = args.episode or store.episode_ids()[0]
    info = store.info(eid)
    g = store.arrays(eid)
    rgb = {c: g[f"rgb/{c}"][:] for c in info.cameras}
    depth = {c: g[f"depth/{c}"][:] for c in info.cameras} if args.depth else {}
    frames = []
    for f in range(0, info.n_frames, args.every):
        row = np.concatenate([rgb[c][f] for c in info.cameras], axis=1)
        if depth:
            row = np.concatenate(
                [row, np.concatenate([depth_rgb(depth[c][f]) for c in info.cameras], axis=1)], 0
            )
        im = Image.fromarray(row)
        ImageDraw.Draw(im).text((3, 2), f"{f / info.fps:4.1f} s", fill=(255, 255, 255))
        frames.append(im)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(
        args.out,
        save_all=True,
        append_images=frames[1:],
        duration=int(1000 * args.every / info.fps),
        loop=0,
    )
    picks = np.linspace(0, len(frames) - 1, 5).round().astype(int)
    strip = np.concatenate([np.asarray(frames[i]) for i in picks], axis=0)
    Image.fromarray(strip).save(args.out.with_suffix(".png"))
    log.info(
        "%s: %d frames of %s (%s) -> %s",
        eid,
        len(frames),
        info.scene_id,
        ", ".join(info.cameras),
        args.out,
    )


if __name__ == "__main__":
    main()
