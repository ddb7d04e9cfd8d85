"""Asset command line.

    python -m factory.assets --list                      # categories
    python -m factory.assets --rooms                     # room types and their categories
    python -m factory.assets "small blue ceramic bowl" --out bowl.png
    python -m factory.assets "king-size bed" --seed 3 --assets runs/a/assets --out bed.png

Generating resolves the text, builds (or reuses) the asset in ``--assets`` (a temporary folder
by default), prints what was understood and the asset's metadata, and renders it if ``--out``
is given.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import sys
import tempfile
from pathlib import Path

from factory.sim.gl import configure_gl


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m factory.assets", description=__doc__)
    p.add_argument("text", nargs="?", help="what to make, e.g. 'a tall oak bookshelf'")
    p.add_argument("--list", action="store_true", help="list the categories")
    p.add_argument("--markdown", action="store_true", help="with --list: a Markdown table")
    p.add_argument(
        "--rooms", action="store_true", help="list the room types and the categories they hold"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--dims", type=float, nargs=3, metavar=("W", "L", "H"), default=None)
    p.add_argument("--assets", default=None, help="asset cache folder (default: a temp folder)")
    p.add_argument(
        "--backend", default="procedural", choices=["procedural", "mesh_library", "trellis"]
    )
    p.add_argument("--library-dir", default=None)
    p.add_argument("--trellis-url", default=None)
    p.add_argument("--out", default=None, help="render the asset to this PNG")
    p.add_argument("--size", type=int, default=512)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    configure_gl("auto")
    from factory.assets import CATEGORIES, AssetError, AssetLibrary, TrellisConfig

    if args.list and args.markdown:
        print(
            "| category | group | placement | typical size (m) | materials | mass (kg) | synonyms "
            "| description |"
        )
        print("|---|---|---|---|---|---|---|---|")
        for name, cat in CATEGORIES.items():
            dims = " x ".join(f"{v:g}" for v in cat.dims)
            print(
                f"| {name} | {cat.group} | {cat.placement} | {dims} | "
                f"{', '.join(dict.fromkeys(cat.materials))} | {cat.mass[0]:g}-{cat.mass[1]:g} | "
                f"{', '.join(cat.synonyms)} | {cat.description} |"
            )
        return 0
    if args.rooms:
        from factory.assets.catalog import ROOMS_FILE, read_yaml

        rooms = read_yaml(ROOMS_FILE)
        width = max(map(len, rooms))
        for room, program in rooms.items():
            held = [n for n, c in CATEGORIES.items() if room in c.rooms]
            (w0, w1), (l0, l1) = program["size"]
            print(
                f"{room:<{width}}  {w0:g}-{w1:g} x {l0:g}-{l1:g} m  "
                f"{len(program.get('items', [])):>2} items  {len(held):>3} categories: "
                f"{', '.join(held[:6])}{', ...' if len(held) > 6 else ''}"
            )
        print(f"{len(rooms)} room types ({ROOMS_FILE.name})")
        return 0
    if args.list:
        width = max(map(len, CATEGORIES))
        for name, cat in CATEGORIES.items():
            lo, hi = cat.mass
            print(
                f"{name:<{width}}  {cat.group:<12} {cat.placement:<7} {lo:g}-{hi:g} kg  "
                f"{', '.join(cat.synonyms[:3])}"
            )
        print(f"{len(CATEGORIES)} categories")
        return 0
    if not args.text:
        p.error("give a text request, --list or --rooms")
    assets = Path(args.assets) if args.assets else Path(tempfile.mkdtemp(prefix="assets-"))
    trellis = TrellisConfig(url=args.trellis_url) if args.trellis_url else None
    try:
        lib = AssetLibrary(assets, args.backend, args.library_dir, trellis)
        meta, res = lib.from_text(args.text, seed=args.seed, dims=args.dims)
    except AssetError as e:
        if not args.assets:
            shutil.rmtree(assets, ignore_errors=True)
        print(f"assets: error: {e}", file=sys.stderr)
        return 2
    print(
        json.dumps(
            {
                "text": args.text,
                "category": res.spec.category,
                "confidence": res.confidence,
                "approximated": res.approximated,
                "notes": res.notes,
                "asset_id": meta.asset_id,
                "folder": str(assets / meta.asset_id),
                "extents_m": [round(v, 4) for v in meta.extents],
                "mass_kg": None if meta.mass is None else round(meta.mass, 4),
                "collision_parts": len(meta.collision),
                "supports": len(meta.supports),
                "containers": len(meta.containers),
                "license": meta.license,
            },
            indent=2,
        )
    )
    if args.out:
        from factory.assets.preview import render_asset
        from factory.sim.images import png_bytes
        from factory.store import atomic_write_bytes

        image = render_asset(assets, meta, args.size, args.size)
        atomic_write_bytes(args.out, png_bytes(image))
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
