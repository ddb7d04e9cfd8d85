"""Renders a room view of a generated two-room apartment before and after the shared-wall
fix (docs/images/shared_wall_before_after.png): left, both rooms' wall pieces in the same slab
(the compiler without :func:`factory.sim.walls.wall_keepout`, as before), flickering between
the two rooms' materials; right, each room's wall on its own side.

    python scripts/render_shared_wall.py [--request "a two-room apartment"] [--seed 0]
        [--view room_bathroom] [--out docs/images/shared_wall_before_after.png]
"""

from __future__ import annotations

import argparse
import logging

from factory.sim.gl import configure_gl

configure_gl("auto")

import numpy as np  # noqa: E402

import factory.sim.compile as compile_module  # noqa: E402
from factory.scenes.floorplan import init_scene  # noqa: E402
from factory.scenes.render import png_bytes, render_views  # noqa: E402
from factory.store import atomic_write_bytes  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--request", default="a two-room apartment")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--view", default="room_bathroom")
    p.add_argument("--width", type=int, default=480)
    p.add_argument("--height", type=int, default=360)
    p.add_argument("--out", default="docs/images/shared_wall_before_after.png")
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO)
    scene, _ = init_scene(args.request, seed=args.seed)
    views = [args.view]
    after = render_views(
        compile_module.compile_scene(scene).model, scene, views, args.width, args.height
    )
    keepout = compile_module.wall_keepout
    compile_module.wall_keepout = lambda rooms: [[] for _ in rooms]  # the compiler before
    try:
        before = render_views(
            compile_module.compile_scene(scene).model, scene, views, args.width, args.height
        )
    finally:
        compile_module.wall_keepout = keepout
    image = np.concatenate([before[args.view], after[args.view]], axis=1)
    atomic_write_bytes(args.out, png_bytes(image))
    logging.info("wrote %s", args.out)


if __name__ == "__main__":
    main()
