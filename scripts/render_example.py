"""Renders a scene's five views into one contact sheet (the README figure).

Usage:
    python scripts/render_example.py [SCENE_JSON] [--out docs/images/example_scene.png]
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from factory.sim.gl import configure_gl

configure_gl("auto")

from factory.scenes.render import VIEWS, contact_sheet, png_bytes, render_views  # noqa: E402
from factory.schema import load_scene  # noqa: E402
from factory.sim.compile import compile_scene  # noqa: E402
from factory.store import atomic_write_bytes  # noqa: E402

EXAMPLE = Path(__file__).resolve().parent.parent / "factory/data/examples/kitchen_pick_place"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(EXAMPLE / "scene.json"))
    parser.add_argument("--out", default="docs/images/example_scene.png")
    parser.add_argument("--width", type=int, default=480)
    parser.add_argument("--height", type=int, default=360)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO)
    scene = load_scene(args.scene)
    images = render_views(compile_scene(scene).model, scene, VIEWS, args.width, args.height)
    atomic_write_bytes(args.out, png_bytes(contact_sheet(images, columns=5)))
    logging.info("wrote %s", args.out)


if __name__ == "__main__":
    main()
