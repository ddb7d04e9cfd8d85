"""The dataset card (``README.md``) of an exported dataset, from lerobot's own template.

It names what a reader of the Hub page needs to use the data without factory: the task, the
scenes and seeds, the factory version, what each feature holds (units, frames), how depth is
packed, and what ``extras/`` holds. ``meta/factory.json`` keeps the full per-episode listing.
Mobile datasets (``layout: mobile`` in it) describe their own fields: the base pose in the
state, the 11 action columns, the sub-task labels and done flags.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from factory.dataset.mobile_features import MOBILE, meta_layout, mobile_card_lines

CARD_FILE = "README.md"
TAGS = ["factory", "mujoco", "simulation", "franka-panda", "pick-and-place"]
MOBILE_TAGS = ["mobile-manipulation"]
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
    if meta_layout(meta) == MOBILE:
        return _mobile_card_text(meta, info, instructions, cams, rgb, seed_text)
    return "\n".join(
        [
            f"Franka Panda demonstrations planned and recorded in physically validated MuJoCo "
            f"scenes by factory {meta['factory_version'] or '(unknown version)'}.",
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
            "- **`observation.state`:** 7 arm joint positions (rad) and the gripper opening (m)",
            "- **`observation.ee_pose`:** tool position (m) and quaternion (w, x, y, z), world "
            "frame",
            "- **`observation.environment_state`:** the pick object's position (m) and "
            "quaternion (w, x, y, z), then the target's, world frame (privileged state for "
            "low-dimensional policies)",
            "- **`action`:** the arm joint targets at the end of the frame (rad) and the gripper "
            "command (m; 0.08 open, negative squeezes)",
            f"- **`observation.images.<camera>`** for {', '.join(f'`{c}`' for c in cams)}: RGB "
            f"video ({rgb.get('codec', 'h264')}, {rgb.get('pix_fmt', 'yuv420p')})",
            "- **`observation.depth.<camera>`:** depth in millimetres, packed into a lossless RGB "
            f"video: {meta['depth_encoding']}. `factory.dataset.unpack_depth_mm` reads it back "
            "exactly.",
            "- **`extras/<episode_id>/`:** `scene.json` (the scene), `model.xml` (the MuJoCo "
            "model; meshes in `extras/assets`), `robot.json` (the robot's base) and `states.npz` "
            "(full MuJoCo states per frame, for exact replay)",
        ]
    )


def _mobile_card_text(
    meta: dict[str, Any],
    info: dict[str, Any],
    instructions: list[str],
    cams: list[str],
    rgb: dict[str, Any],
    seed_text: str,
) -> str:
    """:func:`card_text` of a mobile dataset (``meta['layout'] == 'mobile'``)."""
    episodes = meta["episodes"]
    return "\n".join(
        [
            "Mobile manipulation demonstrations (a Franka Panda on an Omron mobile base) "
            "planned and recorded in physically validated MuJoCo scenes by factory "
            f"{meta['factory_version'] or '(unknown version)'}. Each episode runs the "
            "sub-tasks " + ", ".join(f"`{t}`" for t in meta.get("subtasks", [])) + " in order.",
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
            *mobile_card_lines(meta, cams, rgb),
            "- **`extras/<episode_id>/`:** `scene.json` (the scene), `model.xml` (the MuJoCo "
            "model of the scene; meshes in `extras/assets`), `robot.json` (the base's spawn "
            "pose) and `states.npz` (full MuJoCo states per frame, for exact replay)",
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
        tags=TAGS + MOBILE_TAGS if meta_layout(meta) == MOBILE else TAGS,
        dataset_info=lerobot_meta.info,
        repo_id=lerobot_meta.repo_id,
        dataset_description=card_text(meta, lerobot_meta.info, instructions),
    )
    card.save(str(root / CARD_FILE))
