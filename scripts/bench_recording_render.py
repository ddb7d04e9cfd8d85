"""Rendering rate of the demos' CPU recording in one scene: frames/s (three cameras, RGB +
depth, 128 px) of what :func:`factory.demos.execute.cpu.execute` does per frame and episode
(write the episode's appearance into the model, set the state, ``mj_forward``, draw).

    python scripts/bench_recording_render.py RUN_DIR [--frames 150] [--shadows]
        [--no-appearance] [--rounds 3]

Meant for A/B comparisons on a loaded machine: run it pinned to one core (``taskset -c 0``)
alternately with another checkout's code on ``PYTHONPATH``; a checkout without
``factory.demos.record.appearance`` (before issue 17's lighting) is timed without appearance. Prints
one JSON line: the median frames/s over the rounds and each round's.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

os.environ.setdefault("MUJOCO_GL", "egl")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dir")
    p.add_argument("--frames", type=int, default=150)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--shadows", action="store_true")
    p.add_argument("--no-appearance", action="store_true")
    args = p.parse_args()

    import mujoco
    import numpy as np

    import factory
    from factory.demos.execute.cpu import FrameRenderer, RecordConfig
    from factory.store import RunStore
    from factory.tasks.pick_place.plan import setup_scene

    store = RunStore(args.run_dir)
    scene = store.load_scene(store.scene_ids()[0])
    setup = setup_scene(scene, store.assets_dir)
    model = setup.model
    kw = {"shadows": True} if args.shadows else {}
    cfg = RecordConfig(**kw)  # type: ignore[arg-type]
    patches = []
    try:
        from factory.config import AppearanceConfig
        from factory.demos.record.appearance import apply_patch, episode_looks, setup_index

        if not args.no_appearance:
            index = setup_index(setup, cfg.cameras)
            patches = [p for _, p in episode_looks(model, index, AppearanceConfig(), [1, 2])]
    except ImportError:
        apply_patch = None  # type: ignore[assignment]
    renderer = FrameRenderer(model, cfg)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    qpos0 = model.qpos0.copy()
    arm = setup.robot.qpos
    rates = []
    for _ in range(args.rounds):
        t0 = time.perf_counter()
        for f in range(args.frames):
            if patches and apply_patch is not None:
                apply_patch(model, patches[f % len(patches)])
            data.qpos[:] = qpos0
            data.qpos[arm] = qpos0[arm] + rng.normal(0, 0.05, len(arm))
            mujoco.mj_forward(model, data)
            renderer.render(data)
        rates.append(args.frames / (time.perf_counter() - t0))
    renderer.close()
    print(
        json.dumps(
            {
                "factory": os.path.dirname(factory.__file__),
                "nlight": int(model.nlight),
                "shadows": args.shadows,
                "appearance": bool(patches),
                "frames_per_s": statistics.median(rates),
                "rounds": [round(r, 2) for r in rates],
            }
        )
    )


if __name__ == "__main__":
    main()
