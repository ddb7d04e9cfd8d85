"""Recording speed of the new look against the flat look before issue 17 (same scene, seed and
robot states), on one CPU core and with MuJoCo Warp's batch renderer.

    python scripts/bench_recording.py [--run NEW_RUN --flat-run FLAT_RUN] [--workdir DIR]
        [--request TEXT] [--seed 3] [--frames 60] [--rounds 12] [--executor cpu|warp]
        [--worlds 1024] [--out benchmarks/results/recording-look-cpu1.json]

The two looks of one pick-and-place scene:

* ``flat`` ("today's" recording before issue 17): generated with ``assets.real_meshes=false``
  (procedural parts only), compiled with ``CompileOptions(textures=False, lights=False)``
  (flat colours; a headlight and a sun, no ceiling or lamp lights), recorded without
  appearance randomisation;
* ``new`` (the default look): generated with the defaults (textured real meshes where one
  matches), compiled with the defaults (procedural textures, ceiling and lamp lights) and
  recorded with the default ``demos.appearance`` (a different episode look every frame, as the
  CPU executor interleaves the episodes of a batch, and the other rooms' lights off).

Without ``--run``/``--flat-run`` both runs are generated under ``--workdir`` from ``--request``
and ``--seed`` (``stage=generate``, about 20 s each). Each run's scene is set up for the demos
(:func:`factory.tasks.pick_place.plan.setup_scene`: base spot, cameras, far objects static); the
flat one is then recomposed with the flat compile options.

``--executor cpu`` (default): the process pins itself to one core (``os.sched_setaffinity``)
and Mesa to one render thread before any GL context exists; each look's frame is what the CPU
executor does per recorded frame (write the episode's appearance into the model, set the
state, ``mj_forward``, :class:`factory.demos.execute.cpu.FrameRenderer`: 3 cameras, 128 px, RGB +
depth). The looks alternate in rounds (flat, new, new, flat, ...) over the same arm states;
per round frames per CPU-second of this process (other load on the machine does not count)
and per wall second, of the whole frame and of the draw alone. The median of the rounds is
kept and the ratio new / flat reported.

``--executor warp`` (CUDA only; skipped with a message otherwise): each look's model on the
GPU with ``--worlds`` worlds in the arm states, MuJoCo Warp's render context built as
:mod:`factory.demos.execute.warp` builds it (textures, no shadows, geom groups 0-2, the three
recording cameras); a round times ``--frames`` draws (BVH refit + render) of every world;
frames/s (a frame: three images of one world) and images/s, median of the rounds, and the
ratio.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
log = logging.getLogger("bench_recording")

LOOKS = ("flat", "new")
"""The two looks, in the order of a round's first half."""

DEFAULT_REQUEST = "a kitchen where the robot picks up a coke can and puts it in the bowl"


def _machine(executor: str) -> dict[str, Any]:
    """What this ran on: :func:`bench_stability.machine`'s description, the platform, the
    cores used and the GL backend."""
    from bench_stability import machine

    info = machine()
    info.update(
        platform=platform.platform(),
        cpus_total=os.cpu_count(),
        cores_used=1 if executor == "cpu" else len(os.sched_getaffinity(0)),
        gl=os.environ.get("MUJOCO_GL", "auto"),
    )
    return info


def _generate(run: Path, request: str, seed: int, flat: bool) -> None:
    """Generates ``run`` with the factory's CLI unless it already holds a scene."""
    if (run / "scenes").is_dir() and any((run / "scenes").iterdir()):
        return
    cmd = [
        sys.executable,
        "-m",
        "factory",
        "stage=generate",
        f"run_dir={run}",
        f"generate.prompts=[{request}]",
        "generate.render=false",
        f"seed={seed}",
    ]
    if flat:
        cmd += ["assets.real_meshes=false", "compile.textures=false", "compile.lights=false"]
    log.info("generating %s", run)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def _setup(run: Path, flat: bool) -> Any:
    """The demos' set-up of the run's pick-and-place scene, its model compiled in the look."""
    import mujoco

    from factory.robots.panda import RobotIndex, add_robot
    from factory.sim.compile import CompileOptions, compile_scene
    from factory.store import RunStore
    from factory.tasks.pick_place.plan import setup_scene

    store = RunStore(run)
    for sid in store.scene_ids():
        scene = store.load_scene(sid)
        if scene.task is not None and scene.task.kind == "pick_place":
            break
    else:
        raise SystemExit(f"{run}: no pick_place scene (generate one with a task request)")
    setup = setup_scene(scene, store.assets_dir)
    if not flat:
        return setup
    # compose() compiles with the default options: the same composition, flat options
    compiled = compile_scene(
        setup.scene, store.assets_dir, CompileOptions(textures=False, lights=False)
    )
    for oid in setup.frozen:
        compiled.spec.delete(compiled.spec.joint(f"{oid}/free"))
    add_robot(compiled.spec, setup.placement, setup.rig)
    compiled.spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    model = compiled.spec.compile()
    return dataclasses.replace(setup, model=model, robot=RobotIndex.of(model))


def _arm_states(frames: int, seed: int = 0) -> np.ndarray:
    """The arm's joint positions (frames, 7) rad: home plus a smooth sweep."""
    from factory.robots.panda import HOME_QPOS

    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 7)
    k = np.arange(frames)[:, None]
    return HOME_QPOS[None, :] + 0.3 * np.sin(0.05 * k + phase[None, :])


def _describe(setup: Any) -> dict[str, Any]:
    m = setup.model
    return {
        "scene": setup.scene.id,
        "objects": len(setup.scene.objects),
        "geoms_drawn": int(np.sum(m.geom_group < 3)),
        "meshes": int(m.nmesh),
        "mesh_faces": int(m.nmeshface),
        "textures": int(m.ntex),
        "texture_mpx": round(float(np.sum(m.tex_width * m.tex_height)) / 1e6, 2),
        "materials": int(m.nmat),
        "lights": int(m.nlight),
        "shadow_lights": int(np.sum(m.light_castshadow)),
    }


class _CpuLook:
    """One look's model, renderer (``cull``: :class:`~factory.demos.execute.cpu.FrameRenderer`'s
    culling; off: the renderer before it) and per-frame episode looks on the CPU."""

    def __init__(self, setup: Any, appearance: bool, cfg: Any, episodes: int, cull: bool) -> None:
        import mujoco

        from factory.config import AppearanceConfig
        from factory.demos.execute.cpu import FrameRenderer
        from factory.demos.record.appearance import episode_looks, setup_index

        self.setup = setup
        self.model = setup.model
        self.data = mujoco.MjData(self.model)
        self.patches = []
        if appearance:
            index = setup_index(setup, cfg.cameras)
            looks = episode_looks(
                self.model, index, AppearanceConfig(), list(range(1, episodes + 1))
            )
            self.patches = [p for _, p in looks]
        self.renderer = FrameRenderer(self.model, cfg, cull=cull)
        self.arm = np.asarray(setup.robot.qpos)

    def round(self, arm: np.ndarray) -> dict[str, float]:
        """Records one frame per row of ``arm``; frames per CPU- and wall-second."""
        import mujoco

        from factory.demos.record.appearance import apply_patch

        m, d = self.model, self.data
        q0 = m.qpos0.copy()
        draw_cpu = draw_wall = 0.0
        c0, w0 = time.process_time(), time.perf_counter()
        for k, q in enumerate(arm):
            if self.patches:
                apply_patch(m, self.patches[k % len(self.patches)])
            d.qpos[:] = q0
            d.qpos[self.arm] = q
            mujoco.mj_forward(m, d)
            c1, w1 = time.process_time(), time.perf_counter()
            self.renderer.render(d)
            draw_cpu += time.process_time() - c1
            draw_wall += time.perf_counter() - w1
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        n = len(arm)
        return {
            "frame_cpu": n / cpu,
            "frame_wall": n / wall,
            "draw_cpu": n / draw_cpu,
            "draw_wall": n / draw_wall,
        }

    def close(self) -> None:
        self.renderer.close()


def _summary(
    rounds: dict[str, list[dict[str, float]]], ratios: dict[str, tuple[str, str]]
) -> dict[str, Any]:
    """Median per variant and measure (``<measure>_fps``, and every round's), and each ratio
    ``name -> (numerator, denominator)`` variant: of the medians, and the median of the
    rounds' paired ratios."""
    out: dict[str, Any] = {"variants": {}, "ratios": {}}
    for name, rows in rounds.items():
        out["variants"][name] = {
            f"{key}_fps": round(statistics.median(r[key] for r in rows), 2) for key in rows[0]
        } | {"rounds": {key: [round(r[key], 2) for r in rows] for key in rows[0]}}
    for name, (num, den) in ratios.items():
        row: dict[str, Any] = {"of": f"{num} / {den}"}
        for key in rounds[num][0]:
            paired = [a[key] / b[key] for a, b in zip(rounds[num], rounds[den], strict=True)]
            row[key] = {
                "of_medians": round(
                    out["variants"][num][f"{key}_fps"] / out["variants"][den][f"{key}_fps"], 3
                ),
                "paired_median": round(statistics.median(paired), 3),
            }
        out["ratios"][name] = row
    return out


def _cpu(setups: dict[str, Any], frames: int, rounds: int, episodes: int) -> dict[str, Any]:
    from factory.demos.execute.cpu import RecordConfig

    cfg = RecordConfig()
    looks = {
        f"{k}/{r}": _CpuLook(s, k == "new", cfg, episodes, cull=r == "cull")
        for k, s in setups.items()
        for r in ("nocull", "cull")
    }
    names = list(looks)
    arm = _arm_states(frames)
    for look in looks.values():  # warm up: GL context, texture upload, shader compile
        look.round(arm[:5])
    res: dict[str, list[dict[str, float]]] = {k: [] for k in names}
    for r in range(rounds):
        for k in names if r % 2 == 0 else names[::-1]:
            res[k].append(looks[k].round(arm))
        log.info(
            "round %d: frames per CPU-s %s",
            r,
            ", ".join(f"{k} {res[k][-1]['frame_cpu']:.1f}" for k in names),
        )
    for look in looks.values():
        look.close()
    ratios = {
        # today's recording: the flat look through the renderer without culling
        "new_over_today": ("new/cull", "flat/nocull"),
        "new_over_flat_culled": ("new/cull", "flat/cull"),
        "new_over_flat_unculled": ("new/nocull", "flat/nocull"),
        "culling_flat": ("flat/cull", "flat/nocull"),
        "culling_new": ("new/cull", "new/nocull"),
    }
    return {
        "renderer": "FrameRenderer (OpenGL)",
        "cameras": list(cfg.cameras),
        "size_px": cfg.width,
        "depth": cfg.depth,
        "shadows": cfg.shadows,
        "frames_per_round": frames,
        "rounds": rounds,
        "appearance_looks": episodes,
    } | _summary(res, ratios)


def _warp(
    setups: dict[str, Any], frames: int, rounds: int, worlds: int, device: str
) -> dict[str, Any]:
    import mujoco_warp as mjw
    import warp as wp

    from factory.demos.execute.cpu import RecordConfig
    from factory.demos.execute.warp import render_context
    from factory.robots.panda import CAMERAS

    wp.config.quiet = True  # type: ignore[attr-defined]
    wp.init()
    cfg = RecordConfig()
    names = [CAMERAS[c] for c in cfg.cameras]
    arm = _arm_states(worlds, seed=1)
    state: dict[str, Any] = {}
    with wp.ScopedDevice(device):
        for k, setup in setups.items():
            model = setup.model
            m = mjw.put_model(model)
            d = mjw.make_data(model, nworld=worlds)
            qpos = np.tile(model.qpos0, (worlds, 1))
            qpos[:, np.asarray(setup.robot.qpos)] = arm
            d.qpos.assign(qpos.astype(np.float32))
            mjw.forward(m, d)
            rc = render_context(model, worlds, (cfg.width, cfg.height), names)
            mjw.refit_bvh(m, d, rc)
            mjw.render(m, d, rc)  # warm up: kernel compilation
            wp.synchronize()
            state[k] = (m, d, rc)
        res: dict[str, list[dict[str, float]]] = {k: [] for k in LOOKS}
        for r in range(rounds):
            order = LOOKS if r % 2 == 0 else LOOKS[::-1]
            for k in order:
                m, d, rc = state[k]
                wp.synchronize()
                t0 = time.perf_counter()
                for _ in range(frames):
                    mjw.refit_bvh(m, d, rc)
                    mjw.render(m, d, rc)
                wp.synchronize()
                fps = frames * worlds / (time.perf_counter() - t0)
                res[k].append({"frame_wall": fps, "image_wall": fps * len(names)})
            log.info(
                "round %d: flat %.0f, new %.0f frames/s",
                r,
                res["flat"][-1]["frame_wall"],
                res["new"][-1]["frame_wall"],
            )
    return {
        "renderer": "mujoco_warp batch renderer (ray traced)",
        "device": device,
        "cameras": list(cfg.cameras),
        "size_px": cfg.width,
        "worlds": worlds,
        "draws_per_round": frames,
        "rounds": rounds,
    } | _summary(res, {"new_over_flat": ("new", "flat")})


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, default=None, help="a run in the new look")
    p.add_argument("--flat-run", type=Path, default=None, help="the same, real_meshes=false")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/bench-recording"))
    p.add_argument("--request", default=DEFAULT_REQUEST)
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--frames", type=int, default=60, help="frames (draws) per look per round")
    p.add_argument("--rounds", type=int, default=12)
    p.add_argument("--episodes", type=int, default=4, help="appearance looks cycled (new)")
    p.add_argument("--executor", choices=["cpu", "warp"], default="cpu")
    p.add_argument("--worlds", type=int, default=1024)
    p.add_argument("--device", default="cuda:0", help="warp: device (cpu: a smoke test)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")

    if args.executor == "warp":
        from factory.sim.backend import cuda_available

        if args.device.startswith("cuda") and not cuda_available():
            print("bench_recording: --executor warp needs a CUDA device; skipped")
            return
    else:
        # one core, one Mesa render thread: before any GL context exists
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        os.environ["LP_NUM_THREADS"] = "1"
        from factory.sim.gl import configure_gl

        configure_gl("auto")

    runs = {"new": args.run, "flat": args.flat_run}
    for look in LOOKS:
        if runs[look] is None:
            runs[look] = args.workdir / f"run-{look}"
            _generate(runs[look], args.request, args.seed, look == "flat")
    setups = {k: _setup(runs[k], k == "flat") for k in LOOKS}
    if args.executor == "cpu":
        result = _cpu(setups, args.frames, args.rounds, args.episodes)
    else:
        result = _warp(setups, args.frames, args.rounds, args.worlds, args.device)
    doc = {
        "schema_version": 1,
        "benchmark": "recording-look",
        "executor": args.executor,
        "machine": _machine(args.executor),
        "request": args.request,
        "seed": args.seed,
        "runs": {k: str(v) for k, v in runs.items()},
        "models": {k: _describe(s) for k, s in setups.items()},
        **result,
    }
    print(json.dumps({k: v for k, v in doc.items() if k != "variants"}, indent=2))
    for name, row in doc["variants"].items():
        print(name, {k: v for k, v in row.items() if k != "rounds"})
    gpu = "cpu1" if args.executor == "cpu" else f"warp-{args.device.split(':')[0]}"
    out = args.out or RESULTS / f"recording-look-{gpu}.json"
    from factory.store import atomic_write_json

    atomic_write_json(out, doc)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
