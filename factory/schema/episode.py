"""The episode record: what one recorded demonstration is (metadata beside its arrays).

An episode store (``episodes/shard-<k>.zarr``, see :mod:`factory.demos.record.episodes`) holds one
group per episode; the group's attributes are an :class:`EpisodeInfo` as JSON and its arrays
are named in :data:`EPISODE_ARRAYS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from factory.schema.errors import SchemaError
from factory.schema.scene import _check_version, _from_dict, check_id, to_dict

EPISODE_SCHEMA_VERSION = 4
"""Version of the episode metadata written now (2 added ``appearance``, 3 ``recorder``, 4
``camera_poses`` and ``camera_fovy``)."""

READABLE_EPISODE_VERSIONS = (1, 2, 3, 4)
"""Metadata versions this factory reads (a version-1 episode reads with ``appearance=None``,
versions 1-2 with ``recorder=""``, versions 1-3 with empty ``camera_poses`` and
``camera_fovy``)."""

CAMERA_POSE_SIZE = 12
"""Values of one camera's pose in :attr:`EpisodeInfo.camera_poses`: position (3, m), then the
rows of its rotation matrix (9; MuJoCo's ``cam_xmat``: its columns are the camera's x right,
y up and z axes, the camera looking along -z)."""

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
class ObjectLook:
    """How an episode changed a background object's look (or a room's floor or walls).

    Attributes:
        id: scene object id, or ``<room_id>/floor`` / ``<room_id>/walls``.
        tint: factor on its colours (red, green, blue; 1 = unchanged), on top of its
            materials' colours and textures.
        material_from: id of the scene object whose materials (textures and colours) its
            visual parts wear, part k taking that object's part k modulo its part count;
            empty: its own.
    """

    id: str
    tint: list[float]
    material_from: str = ""


@dataclass
class LightLook:
    """How an episode changed one light of the model.

    Attributes:
        name: the light's name in the model (``<room>/ceiling_<k>``, ``<object>/lamp``,
            ``sun``).
        offset: added to its position (m, its body's frame: the world for ceiling lights).
        intensity: factor on its diffuse and specular intensity.
        color: factor on its colour per channel (red, green, blue).
    """

    name: str
    offset: list[float]
    intensity: float
    color: list[float]


@dataclass
class CameraLook:
    """How an episode moved one recording camera from its rig pose.

    Attributes:
        name: recording camera (``left``, ``right``, ``wrist``).
        offset: added to its position (m, the frame of the body it is mounted on: the world
            for ``left``/``right``, the hand for ``wrist``).
        rotation: rotation vector (deg, the camera's own frame) applied after its rig
            orientation; its norm is the angle.
    """

    name: str
    offset: list[float]
    rotation: list[float]


@dataclass
class EpisodeAppearance:
    """The appearance randomisation of one episode (``demos.appearance``): applying it to
    the recording model (:func:`factory.demos.record.appearance.model_patch`) reproduces the images.

    Attributes:
        seed: seed it was drawn from (derived from the episode seed).
        objects: changed background objects and room surfaces (the task objects and the
            robot never change).
        lights: changed lights.
        cameras: moved recording cameras.
        lights_off: lights switched off for the recording (those of the rooms the robot is
            not in: OpenGL draws eight lights at most).
    """

    seed: int
    objects: list[ObjectLook] = field(default_factory=list)
    lights: list[LightLook] = field(default_factory=list)
    cameras: list[CameraLook] = field(default_factory=list)
    lights_off: list[str] = field(default_factory=list)


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
        cleared: objects of the scene taken out to free the robot's base spot, or (the
            fixed-base task) as look-alikes of the task's objects within reach.
        frozen: objects out of the robot's reach that were simulated static (no free joint):
            ``state`` holds no coordinates for them.
        appearance: the episode's appearance randomisation (``None``: recorded with the
            scene's own look, by an executor without it, or before schema version 2).
        route: the mobile task only: the route check's base poses the episode drove to
            (``pick_pose``, ``place_pose``: x, y m, yaw rad, world frame), their indices in the
            route's pose lists and the route's pose counts, grid cell (m) and footprint
            (``factory.tasks.mobile_pick_place.plan.MobilePlanner.route_record``); empty otherwise.
        recorder: the executor that simulated and rendered it: ``cpu`` (MuJoCo and its
            OpenGL renderer) or ``warp`` (MuJoCo Warp and its ray-traced batch renderer);
            empty before schema version 3.
        camera_poses: the calibration of the recorded cameras placed in the scene (not those
            riding on the robot, whose pose is forward kinematics): camera name ->
            :data:`CAMERA_POSE_SIZE` values, its pose in the robot's base frame as its images
            were drawn (after the scene's camera placement and the episode's appearance
            jitter), constant over the episode; empty where the recorder knows none (the
            mobile task, rendering off) and before schema version 4.
        camera_fovy: camera name -> vertical field of view (deg) of the cameras of
            ``camera_poses``.
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
    route: dict[str, Any] = field(default_factory=dict)
    appearance: EpisodeAppearance | None = None
    recorder: str = ""
    camera_poses: dict[str, list[float]] = field(default_factory=dict)
    camera_fovy: dict[str, float] = field(default_factory=dict)
    schema_version: int = EPISODE_SCHEMA_VERSION


def episode_info_to_dict(info: EpisodeInfo) -> dict[str, Any]:
    """JSON-ready dict of an episode's metadata."""
    return to_dict(info)


def episode_info_from_dict(data: Any) -> EpisodeInfo:
    """Reads episode metadata, checking its version and fields.

    Version-1 metadata (before ``appearance``), version-2 metadata (before ``recorder``) and
    version-3 metadata (before ``camera_poses`` and ``camera_fovy``) read as version 4 without
    them.

    Raises:
        SchemaVersionError: missing or unsupported ``schema_version``.
        SchemaError: malformed content.
    """
    old = (1, 2, 3)
    if isinstance(data, dict) and data.get("schema_version") in old and "camera_poses" not in data:
        data = {**data, "schema_version": EPISODE_SCHEMA_VERSION}
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
    for cam, pose in info.camera_poses.items():
        size = len(pose) if isinstance(pose, list) else -1
        if size != CAMERA_POSE_SIZE or cam not in info.camera_fovy:
            raise SchemaError(
                f"episode {info.episode_id!r}: camera_poses[{cam!r}] must hold "
                f"{CAMERA_POSE_SIZE} values and have a camera_fovy entry, got {pose!r}: "
                "re-record the episode"
            )
    return info
