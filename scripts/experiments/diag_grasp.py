"""Why do a pick-and-place policy's grasps fail? Closed-loop rollouts of a trained policy (or the
planner) on the evaluation configurations of ``stage=eval``, with every frame's observations and
actions kept, and a per-episode anatomy of the grasp: where the tool was relative to the object
when the gripper command first closed, how fast the tool moved then, how long the hand waited
before lifting, how far the fingers closed, how high the object rose, how many times the hand
closed, and the gripper commands the policy put out. The demos' grasps are measured the same way
from the dataset (``--demos``).

Inference-time variants act on the same trained policy: ``--snap T`` (gripper commands below
``T`` become the demos' squeeze, the others open), ``--n-action-steps``, ``--ddim`` (denoising
steps), ``--ensemble K`` (``eval.ensemble``: a chunk every frame, the overlapping predictions of
the current frame averaged with weights ``exp(-K * age)``; default off here, as the policy's own
chunks), ``--zero-noise`` (the sampler starts from zeros), ``--fixed-noise`` (one draw of the
sampler's noise per episode, reused for every chunk).

Usage:
  python scripts/experiments/diag_grasp.py --run runs/g --policy state_cpu --episodes 20 \
      --out runs/g/diag/base.jsonl [--snap 0.03] [--planner]
  python scripts/experiments/diag_grasp.py --run runs/g --demos --out runs/g/diag/demos.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's factory

CLOSE_BELOW = 0.04
"""A gripper command below this (m, half of open) counts as closing."""
LIFT_M = 0.03
"""The success check's lift (m)."""


def grasp_anatomy(
    state: np.ndarray,
    ee: np.ndarray,
    env: np.ndarray,
    grip_cmd: np.ndarray,
    fps: float,
    raw_grip: np.ndarray | None = None,
) -> dict[str, Any]:
    """One episode's grasp measures from its frames.

    Args:
        state: (T, 8) joints + measured gripper opening; ee: (T, 7) world tool pose;
        env: (T, 14) world poses of the pick object and the target; grip_cmd: (T,) the executed
        gripper command of the action that led to each frame (frame 0: open); fps: frames/s;
        raw_grip: (T,) the policy's gripper output before any change (None: grip_cmd).
    """
    from factory.policy.inputs import env_features

    feats = env_features(state, ee, env)
    off = feats[:, 18:21]  # tool -> pick object, base frame
    obj_z = env[:, 2]
    lift = float(obj_z.max() - obj_z[0])
    closed = grip_cmd < CLOSE_BELOW
    onsets = np.flatnonzero(closed[1:] & ~closed[:-1]) + 1
    out: dict[str, Any] = {
        "frames": len(state),
        "lift_m": lift,
        "lifted": lift >= LIFT_M,
        "closes": len(onsets),
        "closed": bool(len(onsets)),
    }
    out.update(release_anatomy(ee, env, grip_cmd, fps))
    raw = grip_cmd if raw_grip is None else raw_grip
    out["grip_raw_min"] = float(raw.min())
    # commands strictly between open and the squeeze: the policy's hesitation
    mid = (raw > -0.015) & (raw < 0.075)
    out["grip_mid_frac"] = float(mid.mean())
    if not len(onsets):
        out["dist_nearest_m"] = float(np.linalg.norm(off, axis=1).min())
        return out
    c = int(onsets[0])
    o = off[c]
    out.update(
        close_frame=c,
        close_off=[float(x) for x in o],
        close_dist_m=float(np.linalg.norm(o)),
        close_xy_m=float(np.linalg.norm(o[:2])),
        close_z_m=float(o[2]),
        close_speed_ms=float(np.linalg.norm(ee[c, :3] - ee[c - 1, :3]) * fps) if c > 0 else 0.0,
    )
    # speed over the frames after the close (the hand should hold still while the fingers shut)
    k = min(len(ee) - 1, c + 10)
    out["speed_after_close_ms"] = float(np.linalg.norm(ee[k, :3] - ee[c, :3]) * fps / max(1, k - c))
    # the lift: the tool 1 cm above where it closed
    up = np.flatnonzero(ee[c:, 2] > ee[c, 2] + 0.01)
    if len(up):
        u = c + int(up[0])
        out["wait_frames"] = u - c
        out["width_at_lift_m"] = float(state[u, 7])
        out["grip_at_lift"] = float(grip_cmd[u])
    # the first closed block's commands
    end = np.flatnonzero(~closed[c:])
    stop = c + int(end[0]) if len(end) else len(closed)
    block = raw[c:stop]
    out["closed_frames"] = int(stop - c)
    out["grip_block_mean"] = float(block.mean())
    out["grip_block_max"] = float(block.max())
    return out


def tilt_deg(quat: np.ndarray) -> float:
    """The angle (deg) between a body's up axis (quaternion w, x, y, z) and the world's."""
    from factory.policy.inputs import quat_to_mat

    r = quat_to_mat(np.asarray(quat, np.float64))
    return float(np.degrees(np.arccos(np.clip(r[2, 2], -1.0, 1.0))))


def release_anatomy(
    ee: np.ndarray, env: np.ndarray, grip_cmd: np.ndarray, fps: float
) -> dict[str, Any]:
    """Where the object was when the hand let go of it.

    The carrying stretch is the first closed stretch of the gripper command during which the
    pick object rose at least :data:`LIFT_M` above its start; the release is the frame its
    first open command was issued from (the last closed frame ``m``; ``grip_cmd[m + 1]`` is
    open). At ``m``: the object's horizontal offset from the target's centre (world, body
    origins: the object's bottom centre, the target's origin), its height above the target's
    origin, its tilt (deg from upright) and the tool's speed over the frame before ``m``
    (m/s). The same measures at the last frame (``final_*``).
    """
    out: dict[str, Any] = {
        "final_xy_to_target_m": float(np.linalg.norm(env[-1, 0:2] - env[-1, 7:9])),
        "final_z_above_target_m": float(env[-1, 2] - env[-1, 9]),
        "final_tilt_deg": tilt_deg(env[-1, 3:7]),
    }
    closed = grip_cmd < CLOSE_BELOW
    z0 = env[0, 2]
    t = 0
    n = len(closed)
    while t < n:
        if not closed[t]:
            t += 1
            continue
        s = t
        while t < n and closed[t]:
            t += 1
        if env[s:t, 2].max() - z0 < LIFT_M:
            continue
        out["released"] = t < n
        if t >= n:
            return out
        m = t - 1
        out.update(
            release_frame=int(m),
            release_xy_to_target_m=float(np.linalg.norm(env[m, 0:2] - env[m, 7:9])),
            release_z_above_target_m=float(env[m, 2] - env[m, 9]),
            release_tilt_deg=tilt_deg(env[m, 3:7]),
            release_speed_ms=float(np.linalg.norm(ee[m, :3] - ee[m - 1, :3]) * fps),
        )
        return out
    return out


class _LoggingEnv:
    """A batched env that keeps every env's frames (state, tool pose, object poses, executed
    gripper command) for :func:`grasp_anatomy`; everything else goes to the env."""

    def __init__(self, env: Any) -> None:
        self._env = env
        self.logs: dict[int, dict[str, list[Any]]] = {}

    def __getattr__(self, k: str) -> Any:
        return getattr(self._env, k)

    def _keep(self, i: int, obs: dict[str, np.ndarray], grip: float) -> None:
        from factory.policy.inputs import EE_POSE, ENV_STATE, STATE

        lg = self.logs[i]
        lg["state"].append(np.asarray(obs[STATE][i], np.float64)[:8].copy())
        lg["ee"].append(np.asarray(obs[EE_POSE][i], np.float64).copy())
        lg["env"].append(np.asarray(obs[ENV_STATE][i], np.float64).copy())
        lg["grip"].append(float(grip))

    def reset(self, *args: Any, ids: Any = None, **kw: Any) -> Any:
        from factory.robots.panda import GRIP_OPEN

        out = self._env.reset(*args, ids=ids, **kw)
        obs = self._env.observations()
        for i in range(self._env.num_envs) if ids is None else ids:
            self.logs[int(i)] = {"state": [], "ee": [], "env": [], "grip": []}
            self._keep(int(i), obs, GRIP_OPEN)
        return out

    def step(self, actions: np.ndarray) -> Any:
        running = np.array(~np.asarray(self._env.done))
        out = self._env.step(actions)
        obs = self._env.observations()
        for i in np.flatnonzero(running):
            if int(i) in self.logs:
                self._keep(int(i), obs, float(actions[i, 7]))
        return out


def rollout_record(
    scene: str,
    index: int,
    seed: int,
    result: dict[str, Any],
    lg: dict[str, list[Any]],
    fps: float,
    raw: np.ndarray | None = None,
    **extra: Any,
) -> dict[str, Any]:
    """One rollout's line: the env's verdict, ``extra`` fields, then :func:`grasp_anatomy` of
    its kept frames (``lg``: state, ee, env, grip lists; ``raw``: the policy's raw gripper
    commands, where kept)."""
    ok = bool(result["success"])
    rec: dict[str, Any] = {
        "scene": scene,
        "index": index,
        "seed": int(seed),
        "success": ok,
        "reason": "" if ok else (result["reason"] or "timeout"),
        "steps": int(result["steps"]),
        **extra,
    }
    frames = [np.stack(lg[k]) for k in ("state", "ee", "env")]
    rec.update(grasp_anatomy(*frames, np.asarray(lg["grip"]), fps, raw))
    return rec


def _stage_eval(a: argparse.Namespace, argv: list[str]) -> int:
    """``python -m factory stage=eval <argv>`` in this process (``eval.workers=1``), every
    rollout's frames kept: one line of grasp and release anatomy per episode in ``--out``
    (the same rollouts as the stage's ``episodes.jsonl``)."""
    import factory.policy.eval as fe
    from factory.__main__ import main as factory_main

    meta = json.loads((Path(a.run) / "dataset" / "merged" / "meta" / "info.json").read_text())
    fps = float(meta["fps"])
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fh = out.open("a")
    orig = fe.run_batch

    def run_batch(env: Any, jobs: list[Any], actor: Any, *rest: Any, **kw: Any) -> Any:
        proxy = _LoggingEnv(env)
        records, frames = orig(proxy, jobs, actor, *rest, **kw)
        for i, job in enumerate(jobs):
            lg = proxy.logs.get(i)
            if lg is None or len(lg["state"]) < 2:
                continue
            r = env.result(i)
            rec = rollout_record(
                job.scene, job.index, job.seed, r, lg, fps, details=r.get("details", {})
            )
            fh.write(json.dumps(rec) + "\n")
        fh.flush()
        return records, frames

    fe.run_batch = run_batch
    try:
        return int(factory_main(argv))
    finally:
        fh.close()


RELEASE_KEYS = (
    "release_xy_to_target_m",
    "release_speed_ms",
    "release_z_above_target_m",
    "release_tilt_deg",
    "final_xy_to_target_m",
    "final_z_above_target_m",
    "final_tilt_deg",
)
TILTED_DEG = 10.0
"""An object more than this from upright counts as tilted."""


def release_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians (and quartiles) of the release measures of ``rows``, with how many were
    released and tilted at the release."""
    rel = [r for r in rows if "release_frame" in r]
    out: dict[str, Any] = {
        "n": len(rows),
        "with_release": len(rel),
        "carried_never_released": sum(1 for r in rows if r.get("released") is False),
        "tilted_at_release": sum(1 for r in rel if r["release_tilt_deg"] > TILTED_DEG),
        "tilted_at_end": sum(1 for r in rows if r.get("final_tilt_deg", 0.0) > TILTED_DEG),
    }
    for k in RELEASE_KEYS:
        v = np.asarray([r[k] for r in rows if k in r], np.float64)
        if len(v):
            q = np.percentile(v, [25, 50, 75])
            out[k] = {
                "median": round(float(q[1]), 4),
                "q25_q75": [round(float(x), 4) for x in (q[0], q[2])],
            }
    radius = [
        r["details"]["target_radius_m"] for r in rows if "target_radius_m" in r.get("details", {})
    ]
    if radius:
        out["target_radius_m_median"] = round(float(np.median(radius)), 4)
    return out


def _summary(paths: list[str]) -> None:
    """Prints the release anatomy of jsonl files by outcome (JSON)."""
    res: dict[str, Any] = {}
    for p in paths:
        rows = [json.loads(x) for x in Path(p).read_text().splitlines() if x.strip()]
        groups: dict[str, list[dict[str, Any]]] = {"all": rows}
        for r in rows:
            groups.setdefault("success" if r["success"] else r["reason"], []).append(r)
        res[p] = {k: release_summary(v) for k, v in groups.items()}
    print(json.dumps(res, indent=1))


def _demos(run: Path, out: Path) -> None:
    """The demos' grasps from the dataset's table."""
    import pyarrow.parquet as pq

    from factory.policy.inputs import ACTION, EE_POSE, ENV_STATE, STATE

    root = run / "dataset" / "merged"
    meta = json.loads((root / "meta" / "info.json").read_text())
    fps = float(meta["fps"])
    files = sorted((root / "data").rglob("*.parquet"))
    cols = ["episode_index", STATE, EE_POSE, ENV_STATE, ACTION]
    table = pq.read_table(files[0], columns=cols)
    for f in files[1:]:
        import pyarrow as pa

        table = pa.concat_tables([table, pq.read_table(f, columns=cols)])
    ep = table["episode_index"].to_numpy()

    def arr(k: str) -> np.ndarray:
        return np.stack(table[k].to_numpy(zero_copy_only=False)).astype(np.float64)

    state, ee, env, act = arr(STATE), arr(EE_POSE), arr(ENV_STATE), arr(ACTION)
    with out.open("w") as fh:
        for e in np.unique(ep):
            m = ep == e
            # the action of frame f leads to frame f + 1
            grip = np.concatenate([[0.08], act[m][:-1, 7]])
            rec = {"episode": int(e), "success": True, "reason": ""}
            rec.update(grasp_anatomy(state[m], ee[m], env[m], grip, fps))
            fh.write(json.dumps(rec) + "\n")


def _rollouts(a: argparse.Namespace) -> None:
    import torch

    from factory.policy.checkpoint import load_policy
    from factory.policy.env import RESEED_STRIDE, eval_seed, make_vec_env
    from factory.policy.eval import plan_actions
    from factory.policy.eval_stage import _dataset_meta, _spec_for_policy
    from factory.policy.eval_task import evaluated_task
    from factory.policy.eval_units import usable_seed
    from factory.policy.inputs import EE_POSE, ENV_STATE, STATE
    from factory.policy.obs_spec import obs_spec_of_dataset
    from factory.robots.panda import GRIP_CLOSED, GRIP_OPEN
    from factory.store import RunStore

    torch.set_num_threads(a.threads)
    run = Path(a.run)
    dataset = run / "dataset" / "merged"
    meta = _dataset_meta(dataset)
    assert meta is not None
    policy = None
    if not a.planner:
        policy = load_policy(a.policy, run, "cpu", a.ensemble)
        lp = policy.policy
        if a.n_action_steps:
            lp.config.n_action_steps = a.n_action_steps
        if a.ddim:
            lp.diffusion.num_inference_steps = a.ddim
        if a.zero_noise or a.fixed_noise:
            orig = lp.predict_action_chunk
            fixed: dict[str, Any] = {}

            def fixed_chunk(batch: dict[str, Any], noise: Any = None) -> Any:
                b = batch["observation.state"].shape[0]
                cfg = lp.config
                shape = (b, cfg.horizon, cfg.action_feature.shape[0])
                if a.zero_noise:
                    return orig(batch, noise=torch.zeros(shape))
                if fixed.get("z") is None or fixed["z"].shape != shape:
                    fixed["z"] = torch.randn(shape)
                return orig(batch, noise=fixed["z"])

            lp.predict_action_chunk = fixed_chunk
            orig_reset = lp.reset

            def reset_noise() -> None:
                orig_reset()
                fixed.clear()

            lp.reset = reset_noise
        train_scenes = set(policy.info.scenes)
        features = policy.info.features
    else:
        train_scenes = set(meta["scenes"])
        features = None
    task = evaluated_task("pick_place", meta, features, "")
    run_spec = obs_spec_of_dataset(dataset, env_state=True, task=task.name)
    if policy is not None:
        spec = _spec_for_policy(policy.info, run_spec, True)
    else:
        from dataclasses import replace

        spec = replace(run_spec, cameras=(), depth=False, env_state=True, pose_cameras=())
    store = RunStore(run)
    scenes = [s for s in store.scene_ids() if s not in train_scenes]
    if a.scenes:
        scenes = a.scenes.split(",")
    longest = max(e["n_frames"] for e in meta["episodes"])
    max_steps = a.max_steps or int(1.5 * longest)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    with out.open("w") as fh:
        for scene in scenes:
            n = a.episodes
            env, planner = make_vec_env(
                run, scene, n, spec, max_steps, a.threads, True, None, task.name
            )
            seeds = [usable_seed(env, eval_seed(0, scene, k), RESEED_STRIDE) for k in range(n)]
            limits = [max_steps] * n
            plans: list[np.ndarray | None] = [None] * n
            if a.planner:
                for i, s in enumerate(seeds):
                    res = planner.plan_episode(s)
                    if hasattr(res, "targets"):
                        plans[i] = plan_actions(res.targets, env.per_frame)
                        limits[i] = len(plans[i])
            env.reset(seeds=seeds, max_steps=limits)
            torch.manual_seed(a.torch_seed)
            if policy is not None:
                policy.reset()
            fps = float(spec.fps)
            logs: list[dict[str, list[np.ndarray]]] = [
                {"state": [], "ee": [], "env": [], "grip": [], "raw": []} for _ in range(n)
            ]
            obs = env.observations()
            for i in range(n):
                logs[i]["state"].append(obs[STATE][i].copy())
                logs[i]["ee"].append(obs[EE_POSE][i].copy())
                logs[i]["env"].append(obs[ENV_STATE][i].copy())
                logs[i]["grip"].append(np.float64(GRIP_OPEN))
                logs[i]["raw"].append(np.float64(GRIP_OPEN))
            while not env.done.all():
                if a.planner:
                    acts = np.zeros((n, 8), np.float32)
                    for i in range(n):
                        p = plans[i]
                        if p is not None:
                            acts[i] = p[min(int(env.steps[i]), len(p) - 1)]
                else:
                    assert policy is not None
                    acts = np.asarray(policy.act(obs), np.float32)
                raw = acts[:, 7].copy()
                if a.snap is not None:
                    acts[:, 7] = np.where(acts[:, 7] < a.snap, GRIP_CLOSED, GRIP_OPEN)
                running = ~env.done
                obs, *_ = env.step(acts)
                for i in np.flatnonzero(running):
                    lg = logs[i]
                    lg["state"].append(obs[STATE][i].copy())
                    lg["ee"].append(obs[EE_POSE][i].copy())
                    lg["env"].append(obs[ENV_STATE][i].copy())
                    lg["grip"].append(np.float64(acts[i, 7]))
                    lg["raw"].append(np.float64(raw[i]))
            for i in range(n):
                r = env.result(i)
                lg = logs[i]
                rec = rollout_record(
                    scene,
                    i,
                    seeds[i],
                    r,
                    lg,
                    fps,
                    raw=np.asarray(lg["raw"]),
                    planned=plans[i] is not None if a.planner else None,
                )
                fh.write(json.dumps(rec) + "\n")
                if a.dump:
                    np.savez_compressed(
                        out.parent / f"{out.stem}-{scene}-{i}.npz",
                        **{k: np.stack(v) for k, v in lg.items()},
                    )
            fh.flush()
            env.close()
            print(f"{scene}: done in {time.perf_counter() - t_start:.0f} s", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", default="")
    ap.add_argument("--policy", default="state_cpu")
    ap.add_argument("--out", default="")
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--scenes", default="", help="comma-separated ids (default: held out)")
    ap.add_argument("--max-steps", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--torch-seed", type=int, default=0)
    ap.add_argument("--planner", action="store_true")
    ap.add_argument("--demos", action="store_true")
    ap.add_argument("--snap", type=float, default=None)
    ap.add_argument("--n-action-steps", type=int, default=0)
    ap.add_argument("--ddim", type=int, default=0)
    ap.add_argument(
        "--ensemble", type=float, default=-1.0, help="eval.ensemble's k (negative: off)"
    )
    ap.add_argument("--zero-noise", action="store_true")
    ap.add_argument("--fixed-noise", action="store_true", help="one noise draw per episode")
    ap.add_argument("--dump", action="store_true", help="each episode's frames as .npz")
    ap.add_argument(
        "--stage-eval",
        action="store_true",
        help="run python -m factory stage=eval with the remaining arguments, anatomy to --out",
    )
    ap.add_argument("--summary", nargs="+", help="release anatomy of these jsonl files")
    a, rest = ap.parse_known_args()
    if a.summary:
        _summary(a.summary)
        return
    if a.stage_eval:
        sys.exit(_stage_eval(a, rest))
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    if a.demos:
        _demos(Path(a.run), Path(a.out))
    else:
        _rollouts(a)


if __name__ == "__main__":
    main()
