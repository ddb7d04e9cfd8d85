"""Writes a GIF (and a PNG strip) of one recorded episode: its camera views side by side.

Usage: python scripts/render_demo.py RUN_DIR [--episode ID] [--out docs/images/demo.gif]
    [--depth] [--every 2] [--fps 10] [--labels] [--max-mb 5]

``--fps`` subsamples the frames to that rate and encodes them with the report's GIF writer
(:func:`factory.report.gifs.to_gif`: one palette, frames thinned further until the GIF fits
``--max-mb``) instead of keeping every ``--every``-th frame. ``--labels`` writes each
camera's name above its view. The mobile task's five views:

    python scripts/render_demo.py RUN_DIR --fps 10 --labels --out docs/images/mobile_five_views.gif
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from factory.demos.record.episodes import EpisodeStore
from factory.report.gifs import subsample, to_gif

log = logging.getLogger("render_demo")


def depth_rgb(depth: np.ndarray, scale_mm: float = 3000.0) -> np.ndarray:
    """Depth (H, W) uint16 mm or float m -> grey RGB (near is bright)."""
    d = depth.astype(np.float32)
    if depth.dtype != np.uint16:
        d = d * 1000.0
    g = np.clip(255 * (1 - d / scale_mm), 0, 255).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=-1)


def _labels(cameras: list[str], widths: list[int], height: int = 14) -> np.ndarray:
    """A black band (height, sum(widths), 3) uint8 with each camera's name over its view."""
    band = Image.new("RGB", (sum(widths), height))
    draw = ImageDraw.Draw(band)
    x = 0
    for name, w in zip(cameras, widths, strict=True):
        draw.text((x + 3, 1), name, fill=(255, 255, 255))
        x += w
    return np.asarray(band)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--episode", default=None)
    ap.add_argument("--out", type=Path, default=Path("docs/images/demo.gif"))
    ap.add_argument("--depth", action="store_true", help="add a row of depth images")
    ap.add_argument("--every", type=int, default=2, help="keep every n-th frame")
    ap.add_argument("--fps", type=float, default=0.0, help="subsample to this rate (Hz)")
    ap.add_argument("--labels", action="store_true", help="name each view above it")
    ap.add_argument("--max-mb", type=float, default=5.0, help="largest GIF with --fps (MB)")
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
    if args.fps > 0:
        picks = subsample(info.n_frames, info.fps, args.fps)
    else:
        picks = list(range(0, info.n_frames, args.every))
    header = _labels(info.cameras, [rgb[c].shape[2] for c in info.cameras]) if args.labels else None
    frames = []
    for f in picks:
        row = np.concatenate([rgb[c][f] for c in info.cameras], axis=1)
        if depth:
            row = np.concatenate(
                [row, np.concatenate([depth_rgb(depth[c][f]) for c in info.cameras], axis=1)], 0
            )
        if header is not None:
            row = np.concatenate([header, row], axis=0)
        im = Image.fromarray(row)
        top = header.shape[0] if header is not None else 0
        ImageDraw.Draw(im).text((3, top + 2), f"{f / info.fps:4.1f} s", fill=(255, 255, 255))
        frames.append(im)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if args.fps > 0:
        width = frames[0].size[0]
        data = to_gif(
            [np.asarray(im) for im in frames],
            min(args.fps, info.fps),
            width,
            max_bytes=int(args.max_mb * 1e6),
        )
        tmp = args.out.with_name(args.out.name + ".tmp")
        tmp.write_bytes(data)
        tmp.replace(args.out)
    else:
        frames[0].save(
            args.out,
            save_all=True,
            append_images=frames[1:],
            duration=int(1000 * args.every / info.fps),
            loop=0,
        )
    shown = np.linspace(0, len(frames) - 1, 5).round().astype(int)
    strip = np.concatenate([np.asarray(frames[i]) for i in shown], axis=0)
    Image.fromarray(strip).save(args.out.with_suffix(".png"))
    log.info(
        "%s: %d frames of %s (%s) -> %s (%.2f MB)",
        eid,
        len(frames),
        info.scene_id,
        ", ".join(info.cameras),
        args.out,
        args.out.stat().st_size / 1e6,
    )


if __name__ == "__main__":
    main()
