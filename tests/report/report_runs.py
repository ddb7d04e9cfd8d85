"""Synthetic run directories for the report's tests: one with data for every section of the page
(and text that must be escaped, a broken log line, a failed stage), one with scenes only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

HOSTILE = '<script>alert("x")</script>&<b>'
"""Text from files that must appear escaped, never as markup."""

SECTIONS_ALL = [
    "scenes",
    "augmentation",
    "demos",
    "dataset",
    "policies",
    "evaluation",
    "scaling",
    "notes",
]


def _png(path: Path, rgb: tuple[int, int, int], size: tuple[int, int] = (64, 48)) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    im = np.zeros((size[1], size[0], 3), np.uint8)
    im[:] = rgb
    im[::8] = 255
    Image.fromarray(im).save(path)


def _scene(root: Path, sid: str, source: str, description: str, renders: bool = True) -> None:
    folder = root / "scenes" / sid
    folder.mkdir(parents=True)
    scene = {
        "schema_version": 1,
        "id": sid,
        "description": description,
        "source": source,
        "rooms": [{"id": "kitchen", "room_type": "kitchen"}],
        "objects": [{"id": f"o{i}"} for i in range(5)],
        "task": {"kind": "pick_place", "instruction": "put the mug in the bowl"},
    }
    (folder / "scene.json").write_text(json.dumps(scene))
    if renders:
        for k, view in enumerate(("top", "corner_0", "corner_1")):
            _png(folder / "renders" / f"{view}.png", (40 * k, 120, 200))


def _episode_store(root: Path, scene_id: str, n: int = 2) -> None:
    from factory.demos.record.episodes import EpisodeStore
    from factory.schema.episode import EpisodeInfo, RobotBase

    store = EpisodeStore(root / "episodes" / "shard-0.zarr")
    frames = 30
    for k in range(n):
        rgb = np.zeros((frames, 32, 32, 3), np.uint8)
        for t in range(frames):
            rgb[t, :, : t + 1] = (200, 80 + 4 * k, 40)
        info = EpisodeInfo(
            episode_id=f"{scene_id}-ep{k:03d}",
            scene_id=scene_id,
            task="pick_place",
            instruction="put the mug in the bowl",
            seed=k,
            success=True,
            failure_reason="",
            pick_id="mug_0",
            target_id="bowl_0",
            support_id="table_0",
            robot=RobotBase(0.0, 0.0, 0.0, 0.0),
            fps=20.0,
            timestep=0.002,
            n_frames=frames,
            cameras=["left"],
            image_size=[32, 32],
            depth_format="uint16_mm",
            state_spec=0,
        )
        store.write(info, {"time": np.arange(frames) / 20.0, "rgb/left": rgb})


def _mp4(path: Path, frames: int = 20) -> None:
    import av

    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as out:
        stream = out.add_stream("h264", rate=20)
        stream.width, stream.height, stream.pix_fmt = 96, 32, "yuv420p"
        for t in range(frames):
            im = np.full((32, 96, 3), 30, np.uint8)
            im[:, : 4 * t + 4] = (50, 200, 90)
            for packet in stream.encode(av.VideoFrame.from_ndarray(im, format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)


def _gif(path: Path) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    ims = [Image.new("RGB", (40, 30), (20 * k, 90, 160)) for k in range(5)]
    ims[0].save(path, save_all=True, append_images=ims[1:], duration=100, loop=0)


CARD = f"""---
task_categories:
- robotics
---

This dataset was created using [LeRobot](https://github.com/huggingface/lerobot).

<a class="flex" href="https://example.org/viz">
<img src="https://example.org/badge.svg"/>
</a>

## Dataset Description

- **Task:** `pick_place`; note {HOSTILE}
- **Episodes:** 2 (60 frames at 20 fps)

| key | value |
| --- | --- |
| fps | 20 |

[meta/info.json](meta/info.json):
```json
{{"fps": 20}}
```
"""


def write_full_run(root: Path) -> Path:
    """A run directory with data for every section of the report (and one bad log line)."""
    root.mkdir(parents=True, exist_ok=False)
    shard = {"status": "done", "time": 1.7e9, "seconds": 12.5, "result": {"done": 1}}
    manifest = {
        "schema_version": 1,
        "factory_version": "0.1.0",
        "git_sha": "0123456789abcdef",
        "created": 1.7e9,
        "config": {"profile": "small", "seed": 0},
        "stages": {
            "generate": {"status": "done", "shards": {"0-of-1": shard}},
            "augment": {
                "status": "done",
                "shards": {
                    "0-of-1": {
                        **shard,
                        "result": {"kept": 2, "total": 3, "dropped": {"P: physics": 1}},
                    }
                },
            },
            "validate": {"status": "done", "shards": {"0-of-1": shard}},
            "demos": {"status": "done", "shards": {"0-of-1": shard}},
            "eval": {
                "status": "failed",
                "shards": {"0-of-1": {**shard, "status": "failed", "error": HOSTILE}},
            },
        },
    }
    (root / "manifest.json").write_text(json.dumps(manifest))
    _scene(root, "kitchen_a", "text", f"a kitchen {HOSTILE}")
    _scene(root, "kitchen_b", "text", "another kitchen", renders=False)
    for k in range(2):
        vid = f"kitchen_a__P{k}"
        _scene(root, vid, "augment:kitchen_a", "a kitchen")
        (root / "scenes" / vid / "report.json").write_text(
            json.dumps(
                {
                    "schema_version": 1,
                    "augment": {
                        "parent": "kitchen_a",
                        "index": k,
                        "seed": 7 + k,
                        "levels": ["configuration"],
                        "applied": [
                            {
                                "level": "configuration",
                                "moved": {"mug_0": {"from": [0, 0], "to": [1, 1]}},
                            }
                        ],
                    },
                }
            )
        )
    (root / "validate").mkdir()
    (root / "validate" / "summary.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "scenes": [
                    {
                        "scene": "kitchen_a",
                        "objects": 5,
                        "collision_pct": 0.0,
                        "stability_pct": 100.0,
                    },
                    {
                        "scene": "kitchen_b",
                        "objects": 5,
                        "collision_pct": 20.0,
                        "stability_pct": 80.0,
                    },
                ],
            }
        )
    )
    _episode_store(root, "kitchen_a")
    (root / "episodes" / "summary-0-of-1.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "episodes_stored": 2,
                "new_successes": 2,
                "failures": {"no_ik": 1, "scene_unusable": 4},
                "success_rate": 2 / 3,
                "scenes": {
                    "kitchen_a": {"episodes": 2, "new": 2, "failures": {"no_ik": 1}},
                    "kitchen_b": {
                        "episodes": 0,
                        "new": 0,
                        "failures": {"scene_unusable": 4},
                        "error": f"no grasp {HOSTILE}",
                    },
                },
                "seconds": {"wall": 42.0},
                "frames": 60,
            }
        )
    )
    merged = root / "dataset" / "merged"
    (merged / "meta").mkdir(parents=True)
    (merged / "README.md").write_text(CARD)
    (merged / "meta" / "info.json").write_text(
        json.dumps(
            {
                "codebase_version": "v3.0",
                "robot_type": "franka_panda",
                "total_episodes": 2,
                "total_frames": 60,
                "fps": 20,
                "features": {
                    "observation.state": {"dtype": "float32", "shape": [8]},
                    "observation.images.left": {"dtype": "video", "shape": [32, 32, 3]},
                },
            }
        )
    )
    pol = root / "policy" / "act"
    pol.mkdir(parents=True)
    (pol / "train.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "policy": "act",
                "inputs": ["observation.state", "observation.images.left"],
                "steps": 200,
                "final_loss": 0.05,
                "seconds": 30.0,
                "dataset": str(merged),
                "config": {"batch_size": 8, "lr": 1e-4},
            }
        )
    )
    log = [
        {"step": s, "loss": 2.0 * 0.98**s, "lr": 1e-4, "seconds": s * 0.1}
        for s in range(0, 200, 10)
    ]
    (pol / "train_log.jsonl").write_text("\n".join(json.dumps(r) for r in log) + "\nnot json\n")
    ev = root / "eval" / "act"
    ev.mkdir(parents=True)
    (ev / "results.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "policy": "act",
                "kind": "trained",
                "success_rate": 0.5,
                "ci95": [0.2, 0.8],
                "episodes": 10,
                "successes": 5,
                "per_scene": {"kitchen_b": {"episodes": 10, "successes": 5}},
                "failures": {"timeout": 4, "dropped": 1},
                "seconds": 12.0,
            }
        )
    )
    _mp4(ev / "videos" / "kitchen_b-1.mp4")
    _gif(ev / "videos" / "kitchen_b-2.gif")
    (root / "eval" / "scaling.json").write_text(
        json.dumps(
            {
                "schema_version": 1,
                "rows": [
                    {
                        "scenes": s,
                        "demos": d,
                        "success_rate": 0.1 * s + 0.001 * d,
                        "ci95": [0.05 * s, 0.2 * s],
                    }
                    for s in (1, 2)
                    for d in (10, 50, 100)
                ],
            }
        )
    )
    return root


def write_scenes_only_run(root: Path) -> Path:
    """A run with one scene (no validation, no demos, no dataset, no policy)."""
    root.mkdir(parents=True, exist_ok=False)
    (root / "manifest.json").write_text(
        json.dumps({"schema_version": 1, "stages": {}, "config": {"profile": "small"}})
    )
    _scene(root, "kitchen_a", "text", "a kitchen")
    return root
