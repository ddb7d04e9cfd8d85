"""The dataset card (``README.md``) of an exported dataset, from lerobot's own template.

It names what a reader of the Hub page needs to use the data without factory: the task, the
scenes and seeds, the factory version, what each feature holds (units, frames), how depth is
packed, and what ``extras/`` holds. ``meta/factory.json`` keeps the full per-episode listing.
The dataset's task writes its opening paragraph and the feature lines
(:meth:`~factory.tasks.base.Task.dataset_card`) and adds its tags; the task, episode and seed
lines are the same for every task, as is the line of ``observation.camera_poses`` where the
dataset has it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from factory.dataset.layout import meta_task
from factory.demos.record.calibration import CAMERA_POSES_KEY, cameras_of_names

CARD_FILE = "README.md"
TAGS = ["factory", "mujoco", "simulation", "franka-panda", "pick-and-place"]
MAX_LISTED = 20  # scenes or instructions named on the card; all are in meta/ files


def _listing(items: list[str], sep: str = ", ", more_note: str = "") -> str:
    """The first ``MAX_LISTED`` items joined, and how many more there are."""
    more = len(items) - MAX_LISTED
    return sep.join(items[:MAX_LISTED]) + (f" and {more} more{more_note}" if more > 0 else "")


def card_text(meta: dict[str, Any], info: dict[str, Any], instructions: list[str]) -> str:
    """The card's description (markdown) for a dataset.

    Args:
        meta: the dataset's ``meta/factory.json`` (as :func:`export_store` or
            :func:`merge_datasets` write it).
        info: lerobot's ``meta/info.json`` of the same dataset.
        instructions: its language instructions (lerobot's tasks).
    """
    episodes = meta["episodes"]
    seeds = sorted({int(e["seed"]) for e in episodes})
    cams = sorted(
        k.rsplit(".", 1)[1] for k in info["features"] if k.startswith("observation.images.")
    )
    videos = meta.get("video", {})
    rgb: dict[str, Any] = next(
        (v for k, v in videos.items() if k.startswith("observation.images.")), {}
    )
    seed_text = f"{seeds[0]}" if len(seeds) == 1 else f"{seeds[0]} to {seeds[-1]}"
    intro, lines = meta_task(meta).dataset_card(meta, cams, rgb)
    calib = info["features"].get(CAMERA_POSES_KEY)
    if calib:
        named = ", ".join(f"`{c}`" for c in cameras_of_names(calib["names"]))
        lines = [
            *lines,
            f"- **`{CAMERA_POSES_KEY}`:** the calibration of the cameras placed in the scene "
            f"({named}), 13 values each: position (m) and rotation matrix rows in the robot's "
            "base frame (the camera looks along its -z axis, y up), then the vertical field "
            "of view (deg); the same at every frame of an episode",
        ]
    return "\n".join(
        [
            intro,
            "",
            f"- **Task:** `{meta['task']}`; instruction(s): "
            + _listing([f'"{t}"' for t in instructions], "; "),
            f"- **Episodes:** {len(episodes)} ({info['total_frames']} frames at {info['fps']} fps) "
            f"from {len(meta['scenes'])} scene(s): "
            + _listing(
                [f"`{n}`" for n in meta["scenes"]], more_note=" (all in `meta/factory.json`)"
            ),
            f"- **Seeds:** {seed_text} (each episode's scene, seed and length are in "
            "`meta/factory.json`)",
            *lines,
        ]
    )


def write_card(root: Path, meta: dict[str, Any], lerobot_meta: Any) -> None:
    """Writes ``<root>/README.md`` with lerobot's dataset-card template.

    Args:
        root: a finished dataset folder.
        meta: its ``meta/factory.json`` content.
        lerobot_meta: its ``LeRobotDatasetMetadata`` (info, tasks and repository id).
    """
    from lerobot.datasets.utils import create_lerobot_dataset_card

    instructions = [str(t) for t in lerobot_meta.tasks.index]
    card = create_lerobot_dataset_card(
        tags=TAGS + list(meta_task(meta).card_tags()),
        dataset_info=lerobot_meta.info,
        repo_id=lerobot_meta.repo_id,
        dataset_description=card_text(meta, lerobot_meta.info, instructions),
    )
    card.save(str(root / CARD_FILE))
