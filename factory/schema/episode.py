"""The episode record: what one recorded demonstration is (metadata beside its arrays).

An episode store (``episodes/shard-<k>.zarr``, see :mod:`factory.demos.episodes`) holds one
group per episode; the group's attributes are an :class:`EpisodeInfo` as JSON and its arrays
are named in :data:`EPISODE_ARRAYS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from factory.schema.errors import SchemaError
from factory.schema.scene import _check_version, _from_dict, check_id, to_dict

EPISODE_SCHEMA_VERSION = 1

EPISODE_ARRAYS: dict[str, str] = {
    "time": "(F,) float64, s since the episode start",
    "state": "(F, nstate) float64, MuJoCo integration state (mj_setState, state_spec)",
    "joint_pos": "(F, 7) float32, arm joint positions (rad)",
    "gripper": "(F, 1) float32, opening between the fingers (m)",
    "ee_pose": "(F, 7) float32, tool site position (m) + quaternion wxyz, world frame",
    "action": "(F, 8) float32, next arm joint targets (rad) + gripper command (m)",
    "env_state": "(F, 14) float32, pick object then target: position (m) + quaternion wxyz, "
    "world frame (stores written before it lack it; the export computes it from state)",
    "rgb/<camera>": "(F, H, W, 3) uint8",
    "depth/<camera>": "(F, H, W) uint16 mm or float32 m (depth_format)",
}
"""Arrays of an episode group (F frames)."""


@dataclass
class RobotBase:
    """Where the robot stood: base position (m, world) and heading (rad)."""

    x: float
    y: float
    z: float
    yaw: float


@dataclass
class EpisodeInfo:
    """Metadata of one recorded episode.

    Attributes:
        episode_id: unique within a run (``<scene_id>-ep<k>``).
        scene_id: the scene it was recorded in (``scenes/<scene_id>/scene.json``).
        task: task kind (``pick_place``); instruction: the language instruction.
        seed: seed of the episode's randomization and planning.
        success: the success check passed; failure_reason: why not (empty on success).
        pick_id, target_id, support_id: the task objects.
        robot: the robot base placement.
        fps: recording rate (Hz); timestep: physics step (s); n_frames: frames recorded.
        cameras: camera names; image_size: ``[height, width]``; depth_format: ``uint16_mm``
            or ``float32``.
        state_spec: ``mjtState`` bits of the ``state`` array.
        phases: phase name -> first frame index.
        grasp_width: span of the grasp (m).
        plan_seconds: planning time per planned motion (s).
        outcome: numbers of the success check.
        factory_version: version of factory that recorded it.
        cleared: objects of the scene taken out to free the robot's base spot.
        frozen: objects out of the robot's reach that were simulated static (no free joint):
            ``state`` holds no coordinates for them.
    """

    episode_id: str
    scene_id: str
    task: str
    instruction: str
    seed: int
    success: bool
    failure_reason: str
    pick_id: str
    target_id: str
    support_id: str
    robot: RobotBase
    fps: float
    timestep: float
    n_frames: int
    cameras: list[str]
    image_size: list[int]
    depth_format: str
    state_spec: int
    phases: dict[str, int] = field(default_factory=dict)
    grasp_width: float = 0.0
    plan_seconds: dict[str, float] = field(default_factory=dict)
    outcome: dict[str, float] = field(default_factory=dict)
    factory_version: str = ""
    cleared: list[str] = field(default_factory=list)
    frozen: list[str] = field(default_factory=list)
    schema_version: int = EPISODE_SCHEMA_VERSION


def episode_info_to_dict(info: EpisodeInfo) -> dict[str, Any]:
    """JSON-ready dict of an episode's metadata."""
    return to_dict(info)


def episode_info_from_dict(data: Any) -> EpisodeInfo:
    """Reads episode metadata, checking its version and fields.

    Raises:
        SchemaVersionError: missing or unsupported ``schema_version``.
        SchemaError: malformed content.
    """
    _check_version(
        data,
        "episode metadata",
        "episode",
        EPISODE_SCHEMA_VERSION,
        "re-record the episodes or use a matching factory",
    )
    info: EpisodeInfo = _from_dict(EpisodeInfo, data, "episode")
    check_id(info.episode_id, "episode id")
    if info.n_frames < 1:
        raise SchemaError(f"episode {info.episode_id!r}: n_frames must be >= 1")
    return info
