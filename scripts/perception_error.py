"""How well a ``train.vision=perception`` policy's network reads the object poses from the
cameras, on the frames of a LeRobot dataset: root-mean-square position error of the pick
object and the target (cm), overall and by the episode's phase (first, middle and last third
of each episode), against the dataset's recorded poses.

Run it on a dataset of scenes the policy never saw (held-out kitchens recorded into their own
run directory) to see what the policy acts on there, and on its training dataset to compare:

    python scripts/perception_error.py --policy runs/camera/policy/rgbd \\
        --dataset runs/heldout/dataset/merged --out benchmarks/results/perception-error.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", required=True, help="policy/<name> folder or pretrained_model")
    ap.add_argument("--dataset", required=True, help="a merged LeRobot dataset with RGB(-D)")
    ap.add_argument("--device", default="auto")
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--out", default="", help="JSON file for the numbers")
    a = ap.parse_args()

    import pyarrow.parquet as pq
    import torch
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from factory.policy.checkpoint import INFO_IN_MODEL, read_info, resolve_device, resolve_ref
    from factory.policy.inputs import CAMERA_POSES, depth_image, env_features
    from factory.policy.perception import POSITIONS, camera_poses, camera_stack, load
    from factory.policy.video_frames import decode_videos

    device = resolve_device(a.device)
    model = resolve_ref(a.policy, None)
    net = load(model, device)
    depth_max_m = read_info(model / INFO_IN_MODEL).depth_max_m
    root = Path(a.dataset)
    keys = [f"observation.images.{c}" for c in net.cameras]
    if net.depth:
        keys += [f"observation.depth.{c}" for c in net.cameras]
    base = LeRobotDataset("factory/demos", root=root, video_backend="pyav")
    t0 = time.perf_counter()
    videos = decode_videos(base, keys)
    cols = ["observation.state", "observation.ee_pose", "observation.environment_state"]
    extra = [CAMERA_POSES] if CAMERA_POSES in base.meta.info["features"] else []
    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in [*cols, *extra, "episode_index", "frame_index"]
    }
    for f in sorted((root / "data").glob("*/*.parquet")):
        table = pq.read_table(f)
        for k in parts:
            parts[k].append(np.stack(table.column(k).to_numpy(zero_copy_only=False)))
    rows = {k: np.concatenate(v) for k, v in parts.items()}
    truth = env_features(*(rows[k] for k in cols))
    n = len(truth)
    poses = None
    if net.xyz:  # the point cameras' poses: kinematics, the dataset's calibration
        from factory.demos.record.calibration import cameras_of_names

        feat = base.meta.info["features"].get(CAMERA_POSES)
        have = cameras_of_names(feat["names"]) if feat else ()  # this dataset's order
        got = camera_poses(
            net.point_cameras, rows["observation.state"], rows.get(CAMERA_POSES), have
        )
        poses = torch.from_numpy(got)
    pred = np.zeros_like(truth)
    with torch.inference_mode():
        for i in range(0, n, a.batch):
            sl = slice(i, min(i + a.batch, n))
            batch = {}
            for k in keys:
                pix = torch.from_numpy(np.ascontiguousarray(videos[k][sl])).to(device)
                if k.startswith("observation.depth."):
                    batch[k] = depth_image(pix.to(torch.int32), depth_max_m)
                else:
                    batch[k] = pix.movedim(-1, -3).float() / 255.0
            images = camera_stack(batch, net.cameras, net.depth)
            pose = None if poses is None else poses[sl].to(device)
            pred[sl] = net.predict(images, pose).float().cpu().numpy()
    err = pred - truth
    ep = rows["episode_index"].reshape(-1)
    frame = rows["frame_index"].reshape(-1)
    length = np.zeros(n)
    for e in np.unique(ep):
        length[ep == e] = (ep == e).sum()
    phase = np.minimum((3 * frame / np.maximum(length, 1)).astype(int), 2)

    def rms_cm(mask: np.ndarray, cols: tuple[int, int]) -> float:
        a_, b_ = cols
        return round(100 * float(np.sqrt((err[mask, a_:b_] ** 2).sum(-1).mean())), 2)

    out = {
        "schema_version": 1,
        "policy": str(model),
        "dataset": str(root),
        "frames": int(n),
        "episodes": len(np.unique(ep)),
        "device": torch.cuda.get_device_name() if device.startswith("cuda") else "cpu",
        "seconds": round(time.perf_counter() - t0, 1),
        "rms_cm": {
            name: {
                "all": rms_cm(np.ones(n, bool), cols),
                **{f"phase_{p}": rms_cm(phase == p, cols) for p in range(3) if (phase == p).any()},
            }
            for name, cols in zip(("pick", "target"), POSITIONS, strict=True)
        },
    }
    print(json.dumps(out, indent=1))
    if a.out:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
