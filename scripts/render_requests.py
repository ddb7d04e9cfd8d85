"""Generates one scene per open-vocabulary request and renders a labelled sheet for the docs.

python scripts/render_requests.py [--out docs/images/open_vocab.png]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from factory.sim.gl import configure_gl

configure_gl("auto")

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from factory.assets import AssetLibrary  # noqa: E402
from factory.scenes.brain import generate_scene  # noqa: E402
from factory.scenes.render import render_views  # noqa: E402
from factory.sim.compile import compile_scene  # noqa: E402

REQUESTS = [
    "a cyberpunk game den",
    "a fairy-tale princess bedroom",
    "a mid-century living room",
    "a rustic farmhouse kitchen",
    "a victorian library",
    "an industrial garage workshop",
    "a retro cafe",
    "a scandinavian home gym",
    "a boho children's room",
    "a futuristic meeting room",
]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/images/open_vocab.png")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    w, h, label, cols = 384, 288, 18, 5
    rows = -(-len(REQUESTS) // cols)
    sheet = Image.new("RGB", (cols * w, rows * (h + label)), "white")
    draw = ImageDraw.Draw(sheet)
    stats = []
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        for i, request in enumerate(REQUESTS):
            t0 = time.perf_counter()
            scene, _ = generate_scene(request, lib, seed=args.seed)
            model = compile_scene(scene, Path(tmp)).model
            image = render_views(model, scene, ["corner_0"], w, h)["corner_0"]
            r, c = divmod(i, cols)
            sheet.paste(Image.fromarray(np.asarray(image)), (c * w, r * (h + label)))
            draw.text((c * w + 4, r * (h + label) + h + 3), request, fill=(0, 0, 0))
            stats.append(
                {
                    "request": request,
                    "room_type": scene.rooms[0].room_type,
                    "objects": len(scene.objects),
                    "seconds": round(time.perf_counter() - t0, 1),
                }
            )
            print(stats[-1])
    sheet.save(args.out, optimize=True)
    print(json.dumps(stats))


if __name__ == "__main__":
    main()
