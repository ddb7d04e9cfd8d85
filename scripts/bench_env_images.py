"""Benchmark of what a camera policy sees on the two evaluation executors: the first
observation of the same evaluation configurations drawn by the CPU env (OpenGL,
:class:`~factory.demos.execute.cpu.FrameRenderer`) and by the env on MuJoCo Warp
(``eval.executor=warp``, its batch ray tracer; on Warp's CPU device where there is no CUDA).

For each scene and camera: the mean absolute RGB difference (0-255), the median absolute depth
difference (mm) and the fraction of pixels whose depth differs by more than 10 mm; the robot's
and objects' states must be equal (the same configurations). A policy trained on one renderer's
images meets the other's at evaluation: these are the differences it has to bear.

    python scripts/bench_env_images.py --run-dir runs/camera --configs 4 --tag cpu2 \
        --save-images benchmarks/results/env-images

With ``--grasp-view N``, also the share of the wrist camera's pixels the pick object covers
while the hand reaches, approaches and closes on it, in the recordings of the first N planned
episodes per scene (the CPU executor, states only), drawn with OpenGL's near clip plane at 1 cm
(:data:`~factory.demos.record.frame_render.NEAR_CLIP_M`) and at MuJoCo's default (1 % of the
scene's extent): what a near plane hides from the wrist camera during a grasp.

With ``--policy PATH`` (a ``train.vision=perception`` policy), also what its perception
network reads from each renderer's images: the planner's episode of each configuration is played
on both executors (the same actions: the states agree, as replays do) and, every ``--every``
frames, the network's pick object and target positions from the OpenGL and from the Warp images
are compared with the true ones (root-mean-square error, cm, by third of the episode; and how far
the two readings are apart): whether a policy trained on OpenGL images is misled by Warp's.
``--shading S`` adds how far its readings move when the OpenGL images are shaded at random
(:func:`factory.policy.shading.shade`, ``train.augment_shading=S``): whether that augmentation
spans the renderers' difference.

``--seeds-from`` takes the configurations of an evaluation's ``results.json`` (its ``seeds``);
default: the first ``--configs`` evaluation seeds of each scene (``eval.seed=0``,
:func:`factory.policy.env.eval_seed`).
Prints and saves JSON to ``benchmarks/results/env-images-<tag>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from factory.policy.env import make_vec_env  # noqa: E402
from factory.policy.eval import Job, run_batch  # noqa: E402
from factory.policy.obs_spec import ObsSpec  # noqa: E402
from factory.store import atomic_write_json, git_sha  # noqa: E402

CAMERAS = ("left", "right", "wrist")


def first_observation(
    run: Path, scene: str, seeds: list[int], spec: ObsSpec, executor: str
) -> dict[str, np.ndarray]:
    """The env's observation after reset of the configurations ``seeds`` of ``scene``
    (key -> (n, ...))."""
    jobs = [Job(scene=scene, seed=s, index=i, max_steps=1) for i, s in enumerate(seeds)]
    vec, _ = make_vec_env(run, scene, len(jobs), spec, nthread=4, executor=executor)
    seen: list[dict[str, np.ndarray]] = []

    def hold(obs: dict[str, np.ndarray], steps: np.ndarray) -> np.ndarray:
        seen.append({k: np.array(v) for k, v in obs.items()})
        return np.zeros((len(steps), vec.action_dim), np.float32)

    try:
        run_batch(vec, jobs, hold)
    finally:
        vec.close()
    return seen[0]


def observations_along_plan(
    run: Path, scene: str, seeds: list[int], spec: ObsSpec, executor: str, every: int
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The observations every ``every`` frames while the planner's episode of each
    configuration ``seeds`` of ``scene`` plays on ``executor``: key -> (m, ...) over the
    captured (configuration, frame) pairs, and each pair's share of its episode (m,) (0 start,
    1 end). A configuration the planner cannot plan is left out (the same on both executors)."""
    from factory.policy.eval import plan_actions, scripted_actor

    vec, planner = make_vec_env(run, scene, len(seeds), spec, nthread=4, executor=executor)
    try:
        jobs = []
        for i, s in enumerate(seeds):
            res = planner.plan_episode(s)
            if hasattr(res, "targets"):
                actions = plan_actions(res.targets, vec.per_frame)
                jobs.append(
                    Job(scene=scene, seed=s, index=i, actions=actions, max_steps=len(actions))
                )
        play = scripted_actor(jobs)
        parts: dict[str, list[np.ndarray]] = {}
        shares: list[np.ndarray] = []

        def capture(obs: dict[str, np.ndarray], steps: np.ndarray) -> np.ndarray:
            lengths = np.array([j.max_steps for j in jobs])
            take = (steps % every == 0) & (steps < lengths)
            if take.any():
                for k, v in obs.items():
                    parts.setdefault(k, []).append(np.array(v)[take])
                shares.append(steps[take] / lengths[take])
            return play(obs, steps)

        run_batch(vec, jobs, capture)
    finally:
        vec.close()
    return {k: np.concatenate(v) for k, v in parts.items()}, np.concatenate(shares)


def perception_reading(policy: Any, obs: dict[str, np.ndarray]) -> np.ndarray:
    """The perception network's 24 environment values (m, ...) from observations ``obs``
    (key -> (m, ...)), as the policy reads them when it acts
    (:meth:`factory.policy.checkpoint.LoadedPolicy.read_objects`), in batches of 64."""
    from factory.policy.inputs import convert_observation

    on = policy.device if policy.device != "cpu" else None
    out = []
    for a in range(0, len(obs["observation.state"]), 64):
        part = {k: v[a : a + 64] for k, v in obs.items()}
        batch = convert_observation(policy.spec, part, on)
        out.append(policy.read_objects(batch, part).numpy())
    return np.concatenate(out)


def perception_rows(
    run: Path, scene: str, seeds: list[int], policy: object, every: int, shading: float = 0.0
) -> dict[str, object]:
    """The perception's position errors (cm) on the same planned episodes drawn by OpenGL and by
    MuJoCo Warp (see the module)."""
    from factory.config import DemosConfig
    from factory.policy.inputs import env_features
    from factory.policy.obs_spec import obs_spec_of_demos
    from factory.policy.perception import POSITIONS

    spec = obs_spec_of_demos(DemosConfig(), env_state=True)  # what the demos record, and truth
    seen = {}
    for ex in ("cpu", "warp"):
        seen[ex] = observations_along_plan(run, scene, seeds, spec, ex, every)
    (cpu, share), (gpu, share_gpu) = seen["cpu"], seen["warp"]
    if len(share) != len(share_gpu):
        raise RuntimeError(f"{scene}: {len(share)} frames on the CPU, {len(share_gpu)} on Warp")
    truth = env_features(
        cpu["observation.state"], cpu["observation.ee_pose"], cpu["observation.environment_state"]
    )
    read = {"opengl": perception_reading(policy, cpu), "warp": perception_reading(policy, gpu)}
    if shading > 0:  # the OpenGL images under train.augment_shading's draws
        import torch

        from factory.policy.shading import shade

        gen = torch.Generator().manual_seed(0)
        shaded = dict(cpu)
        for k in [k for k in cpu if k.startswith("observation.images.")]:
            x = torch.from_numpy(cpu[k]).movedim(-1, -3).float() / 255.0
            y = shade(x, shading, gen).movedim(-3, -1) * 255.0
            shaded[k] = y.round().clamp(0, 255).to(torch.uint8).numpy()
        read["opengl_shaded"] = perception_reading(policy, shaded)
    third = np.minimum((3 * share).astype(int), 2)
    row: dict[str, object] = {"frames": len(share)}
    every_frame = np.ones(len(share), bool)

    def rms(err: np.ndarray, mask: np.ndarray, cols: tuple[int, int]) -> float:
        sq = err[mask, cols[0] : cols[1]] ** 2
        return round(100 * float(np.sqrt(sq.sum(-1).mean())), 2)

    for name, cols in zip(("pick", "target"), POSITIONS, strict=True):
        cell: dict[str, object] = {}
        for r, pred in read.items():
            err = pred - truth
            cell[f"{r}_rms_cm"] = {
                "all": rms(err, every_frame, cols),
                **{
                    f"third_{p}": rms(err, third == p, cols) for p in range(3) if (third == p).any()
                },
            }
        cell["apart_rms_cm"] = rms(read["warp"] - read["opengl"], every_frame, cols)
        if "opengl_shaded" in read:
            cell["shaded_apart_rms_cm"] = rms(
                read["opengl_shaded"] - read["opengl"], every_frame, cols
            )
        row[name] = cell
    return row


def compare(cpu: dict[str, np.ndarray], gpu: dict[str, np.ndarray]) -> dict[str, object]:
    """Per camera: RGB mean absolute difference, depth median absolute difference (mm) and the
    fraction of depth pixels more than 10 mm apart; and the largest state difference."""
    row: dict[str, object] = {
        "state_max_abs": float(
            max(
                np.abs(cpu[k].astype(float) - gpu[k]).max()
                for k in cpu
                if not k.startswith(("observation.images", "observation.depth"))
            )
        )
    }
    for c in CAMERAS:
        a, b = cpu[f"observation.images.{c}"], gpu[f"observation.images.{c}"]
        da = cpu[f"observation.depth.{c}"].astype(float)
        db = gpu[f"observation.depth.{c}"].astype(float)
        row[c] = {
            "rgb_mean_abs": round(float(np.abs(a.astype(float) - b).mean()), 2),
            "depth_median_abs_mm": float(np.median(np.abs(da - db))),
            "depth_frac_over_10mm": round(float((np.abs(da - db) > 10).mean()), 4),
        }
    return row


def save_strip(path: Path, cpu: dict[str, np.ndarray], gpu: dict[str, np.ndarray]) -> None:
    """The first configuration's cameras, OpenGL above and MuJoCo Warp below, as a PNG."""
    from PIL import Image

    top = np.concatenate([cpu[f"observation.images.{c}"][0] for c in CAMERAS], 1)
    bottom = np.concatenate([gpu[f"observation.images.{c}"][0] for c in CAMERAS], 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate([top, bottom], 0)).save(path)


def grasp_view(run: Path, scene: str, episodes: int, size: int) -> dict[str, object]:
    """The pick object's share of the wrist camera's pixels (segmentation) from 10 frames
    before the approach to the lift, over ``episodes`` planned and executed episodes, with
    the near plane at 1 cm and at 1 % of the scene's extent."""
    import mujoco

    from factory.config import DemosConfig
    from factory.demos.execute.cpu import RecordConfig, execute
    from factory.demos.record.frame_render import NEAR_CLIP_M
    from factory.robots.panda import CAMERAS
    from factory.tasks.pick_place.demos import scene_planner
    from factory.tasks.pick_place.plan import EpisodePlan

    setup, planner = scene_planner(run, scene, DemosConfig())
    plans = []
    for seed in range(4 * episodes):
        res = planner.plan_episode(seed)
        if isinstance(res, EpisodePlan):
            plans.append(res)
        if len(plans) == episodes:
            break
    recs = execute(setup, plans, RecordConfig(render=False))
    m = setup.model
    pick = np.nonzero(m.geom_bodyid == m.body(setup.objects.pick.id).id)[0]
    per_frame = max(1, round(1.0 / (20.0 * m.opt.timestep)))
    data = mujoco.MjData(m)
    renderer = mujoco.Renderer(m, size, size)
    renderer.enable_segmentation_rendering()
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
    out: dict[str, object] = {"episodes": len(plans)}
    extent = float(m.stat.extent)
    try:
        for name, near_m in (("near_1cm", NEAR_CLIP_M), ("near_1pct_extent", 0.01 * extent)):
            m.vis.map.znear = near_m / extent
            share = []
            for plan, rec in zip(plans, recs, strict=True):
                first = max(0, plan.phases["approach"] // per_frame - 10)
                for f in range(first, min(plan.phases["lift"] // per_frame, len(rec.state))):
                    mujoco.mj_setState(m, data, rec.state[f], mujoco.mjtState.mjSTATE_INTEGRATION)
                    mujoco.mj_forward(m, data)
                    renderer.update_scene(data, camera=CAMERAS["wrist"], scene_option=option)
                    seg = renderer.render()
                    geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
                    share.append(float((geom & np.isin(seg[..., 0], pick)).mean()))
            out[name] = {
                "near_m": round(near_m, 3),
                "frames": len(share),
                "pick_share_mean": round(float(np.mean(share)), 4),
                "pick_share_last_20_frames": round(float(np.mean(share[-20:])), 4),
            }
    finally:
        renderer.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--run-dir", type=Path, required=True)
    ap.add_argument("--scenes", nargs="*", default=None, help="default: every scene of the run")
    ap.add_argument("--configs", type=int, default=4)
    ap.add_argument("--seeds-from", type=Path, default=None)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--tag", default="cpu")
    ap.add_argument("--save-images", type=Path, default=None)
    ap.add_argument("--grasp-view", type=int, default=0, metavar="N")
    ap.add_argument("--policy", default="", help="a perception policy: its readings on both")
    ap.add_argument("--every", type=int, default=10, help="with --policy: frames apart")
    ap.add_argument(
        "--shading",
        type=float,
        default=0.0,
        help="with --policy: also its readings of the OpenGL images under "
        "train.augment_shading of this strength (how far they move, beside the renderers')",
    )
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    policy = None
    if args.policy:
        from factory.policy.checkpoint import load_policy

        policy = load_policy(args.policy, None, "auto")
        if policy.perception is None:
            sys.exit(f"--policy {args.policy}: not a train.vision=perception policy")
    from factory.policy.env import eval_seed

    scenes = args.scenes or sorted(p.name for p in (args.run_dir / "scenes").iterdir())
    given = json.loads(args.seeds_from.read_text())["seeds"] if args.seeds_from else {}
    spec = ObsSpec(cameras=CAMERAS, width=args.size, height=args.size, env_state=True)
    rows = {}
    for scene in scenes:
        default = [eval_seed(0, scene, k) for k in range(args.configs)]
        seeds = [int(s) for s in given.get(scene, default)][: args.configs]
        cpu = first_observation(args.run_dir, scene, seeds, spec, "cpu")
        gpu = first_observation(args.run_dir, scene, seeds, spec, "warp")
        rows[scene] = compare(cpu, gpu)
        if policy is not None:
            rows[scene]["perception"] = perception_rows(
                args.run_dir, scene, seeds, policy, args.every, args.shading
            )
        if args.grasp_view > 0:
            rows[scene]["grasp_view"] = grasp_view(args.run_dir, scene, args.grasp_view, args.size)
        print(scene, json.dumps(rows[scene]), flush=True)
        if args.save_images is not None:
            save_strip(args.save_images / f"{scene}.png", cpu, gpu)
    sha = (git_sha() or "")[:7]
    import warp as wp

    out = {
        "schema_version": 1,
        "benchmark": "env-images",
        "date": datetime.date.today().isoformat(),
        "machine": platform.platform(),
        "warp_device": str(wp.get_preferred_device()),
        "git_sha": sha,
        "command": " ".join(sys.argv),
        "configs_per_scene": args.configs,
        "policy": args.policy or None,
        "shading": args.shading or None,
        "size_px": args.size,
        "scenes": rows,
    }
    path = args.out or ROOT / "benchmarks" / "results" / f"env-images-{args.tag}.json"
    atomic_write_json(path, out)
    print(f"saved {path}")


if __name__ == "__main__":
    main()
