"""What a policy reads (``train.inputs``) and the conversions that turn a dataset sample and an
env observation into the same model input.

Settings (dataset / env keys read):

* ``state``: ``observation.state`` (arm joints + gripper), ``observation.ee_pose`` and
  ``observation.environment_state`` (pick object and target poses); no images;
* ``rgb``: ``observation.images.<cam>`` of every recorded camera of left, right, wrist, plus
  ``observation.state`` and ``observation.ee_pose``;
* ``rgbd``: the same plus ``observation.depth.<cam>`` (the paper's setting: RGB-D from three
  cameras and the end-effector pose).

A ``train.vision=perception`` policy with depth and ``train.perception_points`` also reads
``observation.camera_poses`` where the dataset has it (the calibration of the cameras fixed in
the scene: :mod:`factory.demos.record.calibration`; :attr:`InputSpec.pose_cameras`): its
perception network turns those cameras' pixels into points in the robot's base frame
(:mod:`factory.policy.perception`); the lerobot policy never reads it.

The model sees (lerobot feature names, so lerobot's policies and processors apply unchanged):

* ``observation.state`` (17,): arm joints (7, rad), gripper opening (m), then the tool pose in
  the robot's base frame: position (3, m) and the first two columns of its rotation matrix
  (6, the continuous "6D" rotation). The tool pose comes from the joints by forward kinematics
  of the demos' own Panda model, so it is exact and needs no world frame.
* ``observation.environment_state`` (24,) (``state`` only): the pick object's and the target's
  pose in the robot's base frame, each position (3, m) + 6D rotation (6), then the offsets
  from the tool to each of them (2 x 3, m, base frame): the quantity a reach is made of.
* ``observation.images.<cam>`` (3, H, W) float in [0, 1].
* ``observation.depth.<cam>`` (3, H, W) float in [0, 1]: depth in metres clipped to
  ``[0, depth_max_m]`` and divided by it, replicated to three channels (the ResNet encoders of
  lerobot's policies take three).

The model predicts (``train.action``):

* ``tool`` (default, the paper's end-effector actions): ``action`` (10,): the tool pose the
  dataset's joint target reaches, by forward kinematics, in the robot's base frame: position
  (3, m) + 6D rotation (6), then the gripper command (m). At execution the pose becomes joint
  targets by differential IK (mink) started at the previous command
  (:class:`ToolActionTracker`). Grasping an object is then "move to where it is", a nearly
  linear map that a small dataset can teach; joint targets would need the arm's inverse
  kinematics learned from the demos.
* ``tool_rel``: the same, with the position relative to the tool's measured position at the
  frame the action chunk is predicted from (``action[:3] = target - tool_now``, base frame):
  a reach is then the tool-to-object offset the model reads, and the normalisation range of
  the positions shrinks from the workspace to one chunk's motion.
* ``joint``: the dataset's 8-D action as it is (arm joint targets, rad, + gripper, m); like
  ``tool``, what LeRobot's own evaluation (``lerobot-eval`` on the ``factory`` env) runs.

Mobile datasets (``task=mobile_pick_place``, recognised by their ``subtask_index`` feature;
:mod:`factory.tasks.mobile_pick_place.dataset`) read ``observation.state`` (11,): arm joints,
gripper, base x, y (m, world) and yaw (rad), ``observation.ee_pose`` and ``subtask_index``, plus the
images of the five cameras (left, right, wrist, fisheye_front, fisheye_back) for ``rgb`` and
``rgbd``. The model then sees ``observation.state`` (21,): the 17 above (the tool pose by forward
kinematics of the arm, in the robot's base frame) then the base pose x, y (m, world) and its heading
as cos(yaw), sin(yaw); ``observation.environment_state`` (4,): the sub-task as a one-hot vector
(navigate_to_pick, pick, navigate_to_place, place); and predicts the arm action above followed by
the base target relative to the base pose at the frame the action chunk is predicted from: dx, dy
(m, in that pose's base frame) and dyaw (rad): 13 values for ``tool``/``tool_rel``, 11 for ``joint``
(:func:`base_relative`; at execution :func:`base_absolute` turns them back into the env's world
targets).

Why not the recorded world values: the recorded yaw is unwrapped (a drive's heading is
continuous), so one heading appears as yaw, yaw + 2 pi or yaw - 2 pi in different demos of one
scene (the same pick pose at 1.83 and -4.45 rad), which a policy cannot tell apart; and a world
target (x over the room's 5 m) normalised to [-1, 1] is learned to a few per cent of the room,
5-10 cm, ten times a frame's motion, so the base never comes to rest. Measured on 20 demos:
teacher-forced world targets were 13 cm off in ``navigate_to_pick`` (docs/POLICY.md).

Mobile datasets exported with ``observation.environment_state`` (the fixed task's 14 world
pose values; :mod:`factory.tasks.mobile_pick_place.dataset`) give ``state`` policies and
``train.vision=perception`` the object poses too: the model's ``observation.environment_state``
(28,) is then the 24 values above, in the frame of the arm's base, which rides on the mobile base
(recovered per frame from the joints and the world tool pose as below, so the objects move in it
as the base drives), followed by the sub-task one-hot (:attr:`InputSpec.mobile_poses`). A mobile
perception network reads the pixels of the wrist camera as points (forward kinematics, with
depth), the other cameras as images only (the head cameras' pose is not in the dataset, the
fisheye cameras are no pinhole cameras). Mobile datasets exported before the feature have no
object poses: ``state`` is proprioception and sub-task only (the policy cannot see where the
object is), and ``train.vision=perception`` and ``train.aux_state`` need a re-export.

Why the base frame: the dataset's poses are in the world frame, and every scene puts the robot
at another spot and heading. The base pose is recovered per frame from what every observation
has: the recorded world tool pose composed with the inverse of the tool pose that forward
kinematics gives in the base frame (the base turns only about +z). Objects seen from the
robot look alike in every scene, which is what lets a state policy work in held-out scenes.

The dataset path gets (T, ...) tensors from ``LeRobotDataset`` (video frames as (T, 3, H, W)
floats in [0, 1], depth packed as (high byte, low byte, 0)); the env path gets (n, ...) numpy
arrays (uint8 (n, H, W, 3) images, uint16 (n, H, W) millimetres). Both go through the same
functions below.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from factory.demos.record.calibration import (
    CALIBRATION_SIZE,
    CAMERA_POSES_KEY,
    cameras_of_names,
)
from factory.errors import PolicyError
from factory.tasks.mobile_pick_place import SUBTASKS as MOBILE_SUBTASKS
from factory.tasks.mobile_pick_place.dataset import SUBTASK_KEY

INPUTS = ("state", "rgb", "rgbd")
VISIONS = ("end_to_end", "perception")
"""``train.vision`` settings of image policies: ``end_to_end`` (lerobot's image encoder inside
the policy, trained by its loss) or ``perception`` (:mod:`factory.policy.perception`)."""
"""The ``train.inputs`` settings."""
ACTIONS = ("tool", "tool_rel", "joint")
"""The ``train.action`` settings: what the model predicts."""
CAMERAS = ("left", "right", "wrist")
STATE = "observation.state"
EE_POSE = "observation.ee_pose"
ENV_STATE = "observation.environment_state"
ACTION = "action"
IMAGE_PREFIX = "observation.images."
DEPTH_PREFIX = "observation.depth."
CAMERA_POSES = CAMERA_POSES_KEY
"""The cameras' calibration, 13 values per camera (:mod:`factory.demos.record.calibration`)."""
DEPTH_MAX_M = 2.0
"""Depth beyond this (m) is clipped: the workspace is within about 1.5 m of every camera."""
ROBOT_DIM = 17
"""Model ``observation.state``: 7 joints + gripper + tool position (3) + 6D rotation (6)."""
TOOL_POS = slice(8, 11)
"""Where the tool position (base frame, m) sits in the model's ``observation.state``."""
ENV_DIM = 24
"""Model ``observation.environment_state``: two poses of position (3) + 6D rotation (6), then
the two tool-to-object offsets (3 each)."""
OBJECT_POSES_DIM = 14
"""Dataset ``observation.environment_state`` of the fixed pick-and-place task: the pick object's
and the target's world poses (position + quaternion wxyz each), converted to :data:`ENV_DIM`
model values. Other tasks may record their own environment state, already in the robot's base
frame (:attr:`InputSpec.env_dim`)."""
ACTION_DIMS = {"tool": 10, "tool_rel": 10, "joint": 8}
"""Model ``action`` size per ``train.action``."""
MOBILE_CAMERAS = ("left", "right", "wrist", "fisheye_front", "fisheye_back")
"""Cameras of mobile datasets, in the order the model reads them."""
MOBILE_STATE_DIM = 11
"""Dataset ``observation.state`` of mobile episodes: arm joints (7), gripper, base x, y, yaw."""
BASE_DIM = 3
"""Base pose / base target columns (x, y in m, yaw in rad; world frame) of mobile episodes."""
BASE_RAW = slice(8, 11)
"""The base pose (x, y m, world; yaw rad, unwrapped) in a mobile dataset's ``observation.state``
and the base target in its ``action``."""
MOBILE_ROBOT_DIM = ROBOT_DIM + 4
"""Model ``observation.state`` of mobile policies: the 17 of :data:`ROBOT_DIM`, then the base's
x, y (m, world), cos(yaw) and sin(yaw)."""
SUBTASK_DIM = len(MOBILE_SUBTASKS)
"""Model ``observation.environment_state`` of mobile policies: the sub-task one-hot."""
REFRESH = "re-run stage=dataset force=true (datasets written before this feature lack it)"


@dataclass(frozen=True)
class InputSpec:
    """What a policy reads and how it is converted.

    Attributes:
        inputs: ``state``, ``rgb`` or ``rgbd``.
        cameras: cameras whose images (and depth, for ``rgbd``) are read, in CAMERAS order.
        image_size: (H, W) of the camera images (px); (0, 0) without images.
        depth_max_m: depth clipping range (m).
        action: what the model predicts (:data:`ACTIONS`).
        mobile: a mobile-manipulation dataset (``task=mobile_pick_place``): base pose in the
            state, the sub-task as input, the base target in the action.
        perception: ``train.vision=perception`` (:mod:`factory.policy.perception`): the
            cameras are read by a perception network that predicts the environment state, and
            the lerobot policy reads the robot state and that environment state (its model
            features are a state policy's; a mobile one's add the sub-task one-hot).
        pose_cameras: the cameras of the dataset's :data:`CAMERA_POSES`, in its order, where
            the perception network reads that calibration (``rgbd``, ``train.perception_points``
            and one of them among ``cameras``); empty: not read.
        env_dim: 0: the dataset's ``observation.environment_state`` holds the two objects'
            world poses (:data:`OBJECT_POSES_DIM`), which the model reads as :data:`ENV_DIM`
            base-frame values (:func:`env_features`); n > 0: the dataset records its task's
            own environment state of n values, read as it is (e.g. the articulated tasks' part
            joint and handle in the robot's base frame).
        poses: the dataset records the pick object's and the target's world poses
            (``observation.environment_state`` of the fixed task's :data:`OBJECT_POSES_DIM`
            values): what the auxiliary state loss (``train.aux_state``) and a perception
            network learn, and what a mobile ``state`` policy reads.
    """

    inputs: str
    cameras: tuple[str, ...] = ()
    image_size: tuple[int, int] = (0, 0)
    depth_max_m: float = DEPTH_MAX_M
    action: str = "joint"
    mobile: bool = False
    perception: bool = False
    pose_cameras: tuple[str, ...] = ()
    env_dim: int = 0
    poses: bool = False

    @property
    def mobile_poses(self) -> bool:
        """A mobile policy whose model ``observation.environment_state`` starts with the 24
        object values (:func:`env_features`) before the sub-task one-hot: a perception policy
        (predicted), or a ``state`` policy of a dataset with :attr:`poses` (recorded)."""
        return self.mobile and (self.perception or (self.inputs == "state" and self.poses))

    @property
    def action_dim(self) -> int:
        """Size of the model's ``action``."""
        return ACTION_DIMS[self.action] + (BASE_DIM if self.mobile else 0)

    @property
    def depth(self) -> bool:
        return self.inputs == "rgbd"

    def image_keys(self) -> list[str]:
        return [f"{IMAGE_PREFIX}{c}" for c in self.cameras]

    def depth_keys(self) -> list[str]:
        return [f"{DEPTH_PREFIX}{c}" for c in self.cameras] if self.depth else []

    def visual_keys(self) -> list[str]:
        return self.image_keys() + self.depth_keys()

    def raw_features(self) -> dict[str, list[int]]:
        """Env / dataset observation key -> shape of one observation as the env gives it."""
        h, w = self.image_size
        if self.mobile:
            out: dict[str, list[int]] = {STATE: [MOBILE_STATE_DIM], EE_POSE: [7], SUBTASK_KEY: [1]}
            if self.mobile_poses and not self.perception:  # a perception predicts them
                out[ENV_STATE] = [OBJECT_POSES_DIM]
        else:
            out = {STATE: [8], EE_POSE: [7]}
        if self.inputs == "state" and not self.mobile:
            out[ENV_STATE] = [self.env_dim or OBJECT_POSES_DIM]
        for k in self.image_keys():
            out[k] = [h, w, 3]
        for k in self.depth_keys():
            out[k] = [h, w]
        if self.pose_cameras:
            out[CAMERA_POSES] = [CALIBRATION_SIZE * len(self.pose_cameras)]
        return out

    def model_features(self) -> dict[str, list[int]]:
        """Model input key -> shape (lerobot's channel-first images); with ``perception``, the
        lerobot policy's inputs (the robot state and the predicted environment state)."""
        h, w = self.image_size
        if self.mobile:
            env = (ENV_DIM if self.mobile_poses else 0) + SUBTASK_DIM
            out: dict[str, list[int]] = {STATE: [MOBILE_ROBOT_DIM], ENV_STATE: [env]}
            if self.perception:
                return out
        elif self.perception:
            return {STATE: [ROBOT_DIM], ENV_STATE: [ENV_DIM]}
        else:
            out = {STATE: [ROBOT_DIM]}
        if self.inputs == "state" and not self.mobile:
            out[ENV_STATE] = [self.env_dim or ENV_DIM]
        for k in self.visual_keys():
            out[k] = [3, h, w]
        return out

    def env_model(
        self, state: np.ndarray, ee_pose: np.ndarray, env_state: np.ndarray
    ) -> np.ndarray:
        """Model ``observation.environment_state`` (..., :data:`ENV_DIM` or ``env_dim``) from
        the dataset's or env's state (..., 8; a mobile one's (..., 11)), ee_pose (..., 7) and
        environment state."""
        if self.env_dim:
            return np.asarray(env_state, np.float32)
        return env_features(state, ee_pose, env_state)

    def mobile_env(
        self,
        subtask: Any,
        state: np.ndarray,
        ee_pose: np.ndarray | None = None,
        env_state: np.ndarray | None = None,
    ) -> np.ndarray:
        """Model ``observation.environment_state`` of a mobile policy: the 24 object values of
        the recorded poses (:meth:`env_model`) where given, then the sub-task one-hot.

        Args:
            subtask: sub-task indices (``subtask_index``), one per state row.
            state: (..., 11) the dataset's or env's ``observation.state``.
            ee_pose: (..., 7) world tool poses; env_state: (..., 14) the objects' world
                poses; both None: the one-hot alone (a perception policy predicts the poses).

        Returns:
            (..., 28) or (..., 4) float32.
        """
        lead = np.asarray(state).shape[:-1]
        onehot = subtask_onehot(subtask, lead)
        if env_state is None or ee_pose is None:
            return onehot
        poses = self.env_model(state, ee_pose, env_state)
        return np.concatenate([poses, onehot], axis=-1).astype(np.float32)

    def dataset_keys(self) -> list[str]:
        """Dataset features read for training (observations and the action)."""
        return [*self.raw_features(), ACTION]


def input_spec(
    inputs: str,
    features: Mapping[str, Any],
    action: str = "joint",
    perception: bool = False,
    cameras: Sequence[str] | None = None,
    points: bool = False,
) -> InputSpec:
    """The inputs of a setting on a dataset with these features (``meta/info.json``).

    Args:
        perception: ``train.vision=perception`` (image inputs of a dataset with the object
            poses: :attr:`InputSpec.poses`).
        cameras: ``train.cameras``: the cameras an image policy reads (None or empty: every
            camera the dataset records).
        points: ``train.perception_points``: a perception policy with depth reads the
            dataset's :data:`CAMERA_POSES` where it has it and one of its cameras is read
            (:attr:`InputSpec.pose_cameras`).

    Raises:
        PolicyError: an unknown setting, or the dataset lacks a feature the setting reads
            (a camera named that it lacks: the ones it has listed).
    """
    spec = _input_spec(inputs, features, action, perception)
    if cameras and spec.cameras:
        unknown = [c for c in cameras if c not in spec.cameras]
        if unknown:
            raise PolicyError(
                f"train.cameras: the dataset has no {', '.join(unknown)} camera; it records "
                f"{', '.join(spec.cameras)}"
            )
        spec = replace(spec, cameras=tuple(c for c in spec.cameras if c in set(cameras)))
    calib = features.get(CAMERA_POSES)
    if spec.perception and spec.depth and points and calib:
        have = cameras_of_names(calib["names"])
        if set(have) & set(spec.cameras):
            spec = replace(spec, pose_cameras=have)
    return spec


def _input_spec(
    inputs: str, features: Mapping[str, Any], action: str, perception: bool
) -> InputSpec:
    """:func:`input_spec` with every camera the dataset records."""
    if inputs not in INPUTS:
        raise PolicyError(f"unknown train.inputs {inputs!r}: use one of {', '.join(INPUTS)}")
    if action not in ACTIONS:
        raise PolicyError(f"unknown train.action {action!r}: use one of {', '.join(ACTIONS)}")
    if perception and inputs == "state":
        raise PolicyError(
            "train.vision=perception reads the cameras: use train.inputs=rgb or rgbd, or "
            "train.vision=end_to_end"
        )
    if SUBTASK_KEY in features:
        return _mobile_spec(inputs, features, action, perception)
    need = [STATE, EE_POSE, ACTION]
    if inputs == "state" or perception:
        need.append(ENV_STATE)
    missing = [k for k in need if k not in features]
    if missing:
        raise PolicyError(
            f"the dataset lacks {', '.join(missing)} (train.inputs={inputs}): {REFRESH}"
        )
    poses = _records_poses(features)
    if inputs == "state":
        return InputSpec("state", action=action, env_dim=_own_env_dim(features), poses=poses)
    cams = tuple(c for c in CAMERAS if f"{IMAGE_PREFIX}{c}" in features)
    if not cams:
        raise PolicyError(
            f"the dataset has no camera images (train.inputs={inputs}): record demos with "
            "rendering on (demos.render=true), then stage=dataset, or use train.inputs=state"
        )
    if inputs == "rgbd":
        missing = [f"{DEPTH_PREFIX}{c}" for c in cams if f"{DEPTH_PREFIX}{c}" not in features]
        if missing:
            raise PolicyError(
                f"the dataset lacks {', '.join(missing)} (train.inputs=rgbd): export depth "
                "with stage=dataset force=true, or use train.inputs=rgb"
            )
    shape = features[f"{IMAGE_PREFIX}{cams[0]}"]["shape"]
    size = (int(shape[0]), int(shape[1]))
    return InputSpec(inputs, cams, size, action=action, perception=perception, poses=poses)


def _records_poses(features: Mapping[str, Any]) -> bool:
    """Whether a dataset's ``observation.environment_state`` is the two objects' world poses
    (:attr:`InputSpec.poses`)."""
    return ENV_STATE in features and _own_env_dim(features) == 0


def _own_env_dim(features: Mapping[str, Any]) -> int:
    """:attr:`InputSpec.env_dim` of a dataset: 0 where its ``observation.environment_state`` is
    the fixed task's two object poses (their names; without names, its width of
    :data:`OBJECT_POSES_DIM`), else its width."""
    from factory.tasks.pick_place.dataset import ENV_STATE_NAMES as OBJECT_POSE_NAMES

    feat = features[ENV_STATE]
    width = int(feat["shape"][0])
    names = feat.get("names")
    if names:
        return 0 if list(names) == OBJECT_POSE_NAMES else width
    return 0 if width == OBJECT_POSES_DIM else width


def _mobile_spec(
    inputs: str, features: Mapping[str, Any], action: str, perception: bool
) -> InputSpec:
    """:func:`input_spec` of a mobile dataset (``subtask_index`` among its features).

    Raises:
        PolicyError: the dataset lacks a feature or has another state/action layout, its
            cameras' images differ in size (lerobot's image policies need one size), or a
            perception policy is asked of a dataset without the object poses.
    """
    need = [STATE, EE_POSE, ACTION, SUBTASK_KEY]
    missing = [k for k in need if k not in features]
    if missing:
        raise PolicyError(
            f"the mobile dataset lacks {', '.join(missing)} (train.inputs={inputs}): {REFRESH}"
        )
    for key in (STATE, ACTION):
        got = int(features[key]["shape"][0])
        if got != MOBILE_STATE_DIM:
            raise PolicyError(
                f"the mobile dataset's {key} has {got} columns, expected {MOBILE_STATE_DIM} "
                f"(arm 7, gripper, base x, y, yaw): {REFRESH}"
            )
    poses = _records_poses(features)
    if perception and not poses:
        raise PolicyError(
            "train.vision=perception learns the object poses, which this mobile dataset does "
            f"not record (no {ENV_STATE}): {REFRESH}, or use train.vision=end_to_end"
        )
    if inputs == "state":
        return InputSpec("state", action=action, mobile=True, poses=poses)
    cams = tuple(c for c in MOBILE_CAMERAS if f"{IMAGE_PREFIX}{c}" in features)
    if not cams:
        raise PolicyError(
            f"the mobile dataset has no camera images (train.inputs={inputs}): record demos "
            "with rendering on (demos.render=true), then stage=dataset, or use "
            "train.inputs=state"
        )
    if inputs == "rgbd":
        missing = [f"{DEPTH_PREFIX}{c}" for c in cams if f"{DEPTH_PREFIX}{c}" not in features]
        if missing:
            raise PolicyError(
                f"the dataset lacks {', '.join(missing)} (train.inputs=rgbd): export depth "
                "with stage=dataset force=true, or use train.inputs=rgb"
            )
    sizes: dict[str, tuple[int, int]] = {}
    for c in cams:
        shape = features[f"{IMAGE_PREFIX}{c}"]["shape"]
        sizes[c] = (int(shape[0]), int(shape[1]))
    if len(set(sizes.values())) > 1:
        raise PolicyError(
            f"the mobile dataset's cameras differ in size ({sizes}; the fisheye images are "
            "square): image policies need one size, so record the demos with "
            "demos.width equal to demos.height, or use train.inputs=state"
        )
    return InputSpec(
        inputs, cams, sizes[cams[0]], action=action, mobile=True, perception=perception, poses=poses
    )


def spec_from_features(
    inputs: str,
    features: Mapping[str, list[int]],
    depth_max_m: float,
    action: str = "joint",
    perception: bool = False,
) -> InputSpec:
    """The spec recorded by a training run (``TrainInfo.features``: raw key -> shape), without
    :attr:`InputSpec.pose_cameras` (a perception network's settings name them). A state
    policy's environment state of other than :data:`OBJECT_POSES_DIM` values is its task's own
    (:attr:`InputSpec.env_dim`)."""
    mobile = SUBTASK_KEY in features
    env = features.get(ENV_STATE)
    env_dim = 0 if not env or int(env[0]) == OBJECT_POSES_DIM else int(env[0])
    cams = tuple(
        c for c in (MOBILE_CAMERAS if mobile else CAMERAS) if f"{IMAGE_PREFIX}{c}" in features
    )
    size = (0, 0)
    if cams:
        shape = features[f"{IMAGE_PREFIX}{cams[0]}"]
        size = (int(shape[0]), int(shape[1]))
    return InputSpec(
        inputs,
        cams,
        size,
        float(depth_max_m),
        action,
        mobile,
        perception,
        env_dim=env_dim,
        poses=bool(env) and env_dim == 0,
    )


# ---- geometry: poses in the robot's base frame


def rot6d(mat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 6): first column, then second column."""
    return np.concatenate([mat[..., :, 0], mat[..., :, 1]], axis=-1)


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions w, x, y, z (normalised here) -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


class _Kinematics:
    """Forward kinematics of the demos' Panda (base at the origin): tool pose in the base frame."""

    def __init__(self) -> None:
        import mujoco

        from factory.robots.panda import RobotIndex, robot_model

        self._mujoco = mujoco
        self.model = robot_model()
        self.data = mujoco.MjData(self.model)
        self.index = RobotIndex.of(self.model)
        self.lock = threading.Lock()

    def tool_poses(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 7) arm joints (rad) -> tool positions (N, 3) m, rotations (N, 3, 3), base frame."""
        n = len(joints)
        pos = np.empty((n, 3))
        rot = np.empty((n, 3, 3))
        m, d, site, qadr = self.model, self.data, self.index.site, self.index.qpos
        with self.lock:
            for i in range(n):
                d.qpos[qadr] = joints[i]
                self._mujoco.mj_kinematics(m, d)
                pos[i] = d.site_xpos[site]
                rot[i] = d.site_xmat[site].reshape(3, 3)
        return pos, rot

    def camera_poses(self, joints: np.ndarray, camera: str) -> np.ndarray:
        """(N, 7) arm joints (rad) -> the pose of a camera that rides on the arm (``wrist``),
        (N, 12) float32: position (m) then the rotation's rows (its columns are the camera's
        x right, y up and viewing -z axes), base frame; the nominal mount (an episode's
        appearance may move a camera by up to ``demos.appearance.camera_pos``)."""
        from factory.robots.panda import CAMERAS as MODEL_CAMERAS

        joints = np.asarray(joints, np.float64).reshape(-1, 7)
        cam = self.model.camera(MODEL_CAMERAS[camera]).id
        out = np.empty((len(joints), 12), np.float32)
        m, d, qadr = self.model, self.data, self.index.qpos
        with self.lock:
            for i in range(len(joints)):
                d.qpos[qadr] = joints[i]
                self._mujoco.mj_kinematics(m, d)
                self._mujoco.mj_camlight(m, d)  # cameras follow their bodies here
                out[i, :3] = d.cam_xpos[cam]
                out[i, 3:] = d.cam_xmat[cam]
        return out

    def camera_fovy(self, camera: str) -> float:
        """Vertical field of view of a camera on the arm (deg)."""
        from factory.robots.panda import CAMERAS as MODEL_CAMERAS

        return float(self.model.cam_fovy[self.model.camera(MODEL_CAMERAS[camera]).id])


@functools.lru_cache(maxsize=1)
def kinematics() -> _Kinematics:
    """The process's forward-kinematics model (built once: about a second)."""
    return _Kinematics()


def robot_features(state: np.ndarray) -> np.ndarray:
    """Model ``observation.state`` (..., 17) from the dataset's ``observation.state`` (..., 8)."""
    state = np.asarray(state, np.float64)
    flat = state.reshape(-1, 8)
    pos, rot = kinematics().tool_poses(flat[:, :7])
    out = np.concatenate([flat, pos, rot6d(rot)], axis=1)
    return out.reshape(*state.shape[:-1], ROBOT_DIM).astype(np.float32)


def mobile_robot_features(state: np.ndarray) -> np.ndarray:
    """Model ``observation.state`` (..., 21) from a mobile dataset's ``observation.state``
    (..., 11): :func:`robot_features` of the arm and gripper, then the base x, y (m, world) and
    its heading as cos(yaw), sin(yaw) (the same for yaw and yaw + 2 pi)."""
    state = np.asarray(state, np.float32)
    arm = robot_features(state[..., :8])
    yaw = np.asarray(state[..., BASE_RAW.stop - 1 : BASE_RAW.stop], np.float64)
    heading = np.concatenate([np.cos(yaw), np.sin(yaw)], axis=-1)
    return np.concatenate([arm, state[..., 8:10], heading], axis=-1).astype(np.float32)


def base_relative(target: np.ndarray, now: np.ndarray) -> np.ndarray:
    """World base targets -> the model's base action: relative to the base pose ``now``.

    Args:
        target: (..., H, 3) base targets x, y (m, world), yaw (rad, unwrapped).
        now: (..., 3) the base pose of the frame the chunk is predicted from (same frames).

    Returns:
        (..., H, 3): dx, dy (m, in the base frame of ``now``) and dyaw = yaw - yaw_now (rad).
    """
    target = np.asarray(target, np.float64)
    now = np.asarray(now, np.float64)[..., None, :]
    c, s = np.cos(now[..., 2]), np.sin(now[..., 2])
    dx, dy = target[..., 0] - now[..., 0], target[..., 1] - now[..., 1]
    out = np.stack([c * dx + s * dy, -s * dx + c * dy, target[..., 2] - now[..., 2]], axis=-1)
    return out.astype(np.float32)


def base_absolute(rel: np.ndarray, now: np.ndarray) -> np.ndarray:
    """The inverse of :func:`base_relative` for one action per env: (n, 3) relative base
    actions and the poses ``now`` (n, 3) they are relative to -> world targets (n, 3)."""
    rel = np.asarray(rel, np.float64)
    now = np.asarray(now, np.float64)
    c, s = np.cos(now[:, 2]), np.sin(now[:, 2])
    x = now[:, 0] + c * rel[:, 0] - s * rel[:, 1]
    y = now[:, 1] + s * rel[:, 0] + c * rel[:, 1]
    return np.stack([x, y, now[:, 2] + rel[:, 2]], axis=-1)


def chunk_actions(
    spec: InputSpec, actions: np.ndarray, robot_now: np.ndarray, base_now: np.ndarray | None
) -> np.ndarray:
    """Absolute model actions of an action window -> what the model is trained to predict
    from the window's current frame: ``tool_rel`` positions relative to the tool now
    (:func:`relative_to`), a mobile base target relative to the base pose now
    (:func:`base_relative`); otherwise unchanged.

    Args:
        actions: (..., H, A) from :func:`model_actions`.
        robot_now: (..., D) the model ``observation.state`` of the current frame.
        base_now: (..., 3) the dataset's base pose of the current frame (mobile; else None).
    """
    out = np.asarray(actions, np.float32)
    if spec.action == "tool_rel":
        out = relative_to(out, np.asarray(robot_now)[..., TOOL_POS])
    if spec.mobile:
        assert base_now is not None
        out = np.array(out, np.float32, copy=True)
        out[..., -BASE_DIM:] = base_relative(out[..., -BASE_DIM:], base_now)
    return out


def state_features(spec: InputSpec, state: np.ndarray) -> np.ndarray:
    """Model ``observation.state`` of the spec's layout (fixed: (..., 17); mobile: (..., 20))."""
    return mobile_robot_features(state) if spec.mobile else robot_features(state)


def subtask_onehot(index: Any, lead: tuple[int, ...]) -> np.ndarray:
    """Model ``observation.environment_state`` of mobile policies: the sub-task as a one-hot
    vector (..., 4) in :data:`MOBILE_SUBTASKS` order.

    Args:
        index: sub-task indices, any shape holding ``prod(lead)`` values (``(..., 1)`` or
            ``(...)``).
        lead: the leading shape of the result (the state's, without its last axis).

    Raises:
        PolicyError: an index outside the sub-tasks.
    """
    idx = np.asarray(index).reshape(-1).astype(np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= SUBTASK_DIM):
        raise PolicyError(
            f"sub-task indices {sorted(set(idx.tolist()))} are not indices into "
            f"{list(MOBILE_SUBTASKS)}: {REFRESH}"
        )
    out = np.zeros((idx.size, SUBTASK_DIM), np.float32)
    out[np.arange(idx.size), idx] = 1.0
    return out.reshape(*lead, SUBTASK_DIM)


def base_poses(state: np.ndarray, ee_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The robot base's world pose per frame from the joints and the world tool pose.

    Args:
        state: (N, 8) joints + gripper; ee_pose: (N, 7) world tool position + quaternion wxyz.

    Returns:
        base positions (N, 3) m and headings as rotations about +z (N, 3, 3), world frame.
    """
    pos_b, rot_b = kinematics().tool_poses(np.asarray(state, np.float64)[:, :7])
    rot_w = quat_to_mat(ee_pose[:, 3:7])
    base_rot = rot_w @ np.swapaxes(rot_b, -1, -2)
    yaw = np.arctan2(base_rot[:, 1, 0], base_rot[:, 0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    rz = np.zeros((len(yaw), 3, 3))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -s, s, c, 1.0
    base_pos = np.asarray(ee_pose[:, :3], np.float64) - np.einsum("nij,nj->ni", rz, pos_b)
    return base_pos, rz


def env_features(state: np.ndarray, ee_pose: np.ndarray, env_state: np.ndarray) -> np.ndarray:
    """Model ``observation.environment_state`` (..., 24) from the dataset's state (..., 8; a
    mobile one's (..., 11), whose first 8 columns are the arm's), ee_pose (..., 7, world) and
    environment_state (..., 14, world): both objects' poses in the arm's base frame, then the
    offsets from the tool to each (base frame, m). The base frame is recovered per frame
    (:func:`base_poses`), so on the mobile robot it follows the base."""
    lead = np.asarray(state).shape[:-1]
    s = np.asarray(state, np.float64)[..., :8].reshape(-1, 8)
    ee = np.asarray(ee_pose, np.float64).reshape(-1, 7)
    env = np.asarray(env_state, np.float64).reshape(-1, 14)
    base_pos, base_rot = base_poses(s, ee)
    inv = np.swapaxes(base_rot, -1, -2)
    tool = np.einsum("nij,nj->ni", inv, ee[:, :3] - base_pos)
    parts, offsets = [], []
    for k in (0, 7):
        p = np.einsum("nij,nj->ni", inv, env[:, k : k + 3] - base_pos)
        r = inv @ quat_to_mat(env[:, k + 3 : k + 7])
        parts += [p, rot6d(r)]
        offsets.append(p - tool)
    return np.concatenate(parts + offsets, axis=1).reshape(*lead, ENV_DIM).astype(np.float32)


# ---- actions


def rot6d_to_mat(r6: np.ndarray) -> np.ndarray:
    """(..., 6) 6D rotations (first two columns, not necessarily orthonormal) -> (..., 3, 3)
    rotation matrices by Gram-Schmidt."""
    r6 = np.asarray(r6, np.float64)
    a, b = r6[..., :3], r6[..., 3:]
    x = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-9)
    b = b - np.sum(x * b, axis=-1, keepdims=True) * x
    y = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-9)
    z = np.cross(x, y)
    return np.stack([x, y, z], axis=-1)


def model_actions(action: np.ndarray, kind: str) -> np.ndarray:
    """The dataset's actions (..., 8 + k) -> the model's (..., ``ACTION_DIMS[kind]`` + k).

    ``tool`` and ``tool_rel``: forward kinematics of the joint targets: tool position (3, m)
    and 6D rotation (6) in the base frame, then the gripper command (m) (``tool_rel`` subtracts
    the current tool position afterwards: :func:`relative_to`); ``joint``: unchanged. Columns
    past the eighth (the base target x, y, yaw of mobile datasets) follow unchanged.
    """
    action = np.asarray(action, np.float32)
    if kind == "joint":
        return action
    extra = action.shape[-1] - 8
    flat = action.reshape(-1, 8 + extra).astype(np.float64)
    pos, rot = kinematics().tool_poses(flat[:, :7])
    out = np.concatenate([pos, rot6d(rot), flat[:, 7:]], axis=1)
    return out.reshape(*action.shape[:-1], ACTION_DIMS["tool"] + extra).astype(np.float32)


def relative_to(actions: np.ndarray, tool_now: np.ndarray) -> np.ndarray:
    """``tool_rel``: tool actions (..., H, 10) with their positions made relative to the
    current tool position (..., 3) (base frame, m); rotation and gripper stay absolute."""
    out = np.array(actions, np.float32, copy=True)
    out[..., :3] -= np.asarray(tool_now, np.float32)[..., None, :]
    return out


class ToolActionTracker:
    """Turns predicted tool poses into the env's joint targets, one batch of envs at a time.

    Each env's target is reached by differential IK (joint limits kept) started at that env's
    previous joint command (at an episode's start: its measured joints), so the arm follows the
    predicted tool path smoothly, as the demos' planner moved it. The whole batch moves in one
    :class:`~factory.robots.ik_batch.BatchTracker` call (the step mink's tracker takes, one
    linear solve for all envs instead of a QP per env: 90 worlds cost about what 20 did).

    Args:
        iters: IK steps per action at most.
    """

    def __init__(self, iters: int = 20) -> None:
        self.iters = iters
        self._solver: Any = None
        self._prev: np.ndarray | None = None  # (n, 7) the last commands; NaN rows: none yet

    def reset(self) -> None:
        """New episodes: forget the previous commands."""
        self._prev = None

    def joints(
        self, tool: np.ndarray, state: np.ndarray, origin: np.ndarray | None = None
    ) -> np.ndarray:
        """Model actions (n, 10) -> env actions (n, 8).

        Args:
            tool: predicted tool position (3, m) + 6D rotation (6) in the base frame + gripper.
            state: the env's ``observation.state`` (n, 8) (measured joints, rad, + gripper).
            origin: ``tool_rel``: the tool positions (n, 3) the positions are relative to.
        """
        if self._solver is None:
            from factory.robots.ik import IKConfig
            from factory.robots.ik_batch import BatchTracker

            self._solver = BatchTracker(
                IKConfig(max_iters=self.iters, pos_tol=5e-4, rot_tol_deg=0.5)
            )
        tool = np.array(tool, np.float64, copy=True)
        if origin is not None:
            tool[:, :3] += np.asarray(origin, np.float64)
        n = len(tool)
        measured = np.asarray(state, np.float64)[:, :7]
        if self._prev is None or len(self._prev) != n:
            self._prev = np.full((n, 7), np.nan)
        seed = np.where(np.isnan(self._prev), measured, self._prev)
        q = self._solver.track(tool[:, :3], rot6d_to_mat(tool[:, 3:9]), seed)
        self._prev = q
        out = np.zeros((n, 8), np.float32)
        out[:, :7], out[:, 7] = q, tool[:, 9]
        return out


# ---- images


def depth_image(mm: Any, depth_max_m: float) -> Any:
    """Depth (..., H, W) in millimetres (any real tensor) -> (..., 3, H, W) float32 in [0, 1]:
    metres clipped to ``[0, depth_max_m]`` and divided by it, on three equal channels."""
    import torch

    d = (mm.to(torch.float32) / 1000.0).clamp(0.0, depth_max_m) / depth_max_m
    return d.unsqueeze(-3).expand(*d.shape[:-2], 3, *d.shape[-2:]).contiguous()


def unpack_depth_tensor(packed: Any) -> Any:
    """lerobot's decoded packed depth (..., 3, H, W) floats in [0, 1] -> (..., H, W) float mm
    (the inverse of :func:`factory.dataset.lerobot_export.pack_depth_mm`)."""
    import torch

    hi = torch.round(packed[..., 0, :, :] * 255.0)
    lo = torch.round(packed[..., 1, :, :] * 255.0)
    return hi * 256.0 + lo


# ---- the two paths


def convert_sample(spec: InputSpec, item: Mapping[str, Any]) -> dict[str, Any]:
    """A ``LeRobotDataset`` sample (tensors, (T, ...) with delta timestamps) -> model inputs,
    plus ``action`` and the ``*_is_pad`` masks."""
    import torch

    state = item[STATE].numpy()
    out: dict[str, Any] = {STATE: torch.from_numpy(state_features(spec, state))}
    if spec.mobile:
        poses = spec.mobile_poses and not spec.perception
        ee = item[EE_POSE].numpy() if poses else None
        env = item[ENV_STATE].numpy() if poses else None
        out[ENV_STATE] = torch.from_numpy(spec.mobile_env(item[SUBTASK_KEY], state, ee, env))
    elif spec.inputs == "state":
        env = spec.env_model(state, item[EE_POSE].numpy(), item[ENV_STATE].numpy())
        out[ENV_STATE] = torch.from_numpy(env)
    for k in spec.image_keys():
        out[k] = item[k].to(torch.float32)
    for k in spec.depth_keys():
        out[k] = depth_image(unpack_depth_tensor(item[k]), spec.depth_max_m)
    for k, v in item.items():
        if k == ACTION:
            act = model_actions(v.numpy(), spec.action)
            robot = out[STATE].numpy()
            now = robot[-1] if robot.ndim == 2 else robot
            base = (state[-1] if state.ndim == 2 else state)[BASE_RAW] if spec.mobile else None
            out[k] = torch.from_numpy(chunk_actions(spec, act, now, base))
        elif k.endswith("_is_pad"):
            out[k] = v
    return out


def convert_observation(
    spec: InputSpec, obs: Mapping[str, np.ndarray], device: Any = None
) -> dict[str, Any]:
    """An env observation (numpy, leading batch axis n, the contract's raw dtypes) -> model
    inputs (torch, (n, ...)), exactly as :func:`convert_sample` converts a dataset frame.

    Args:
        spec: what the policy reads.
        obs: the env's observation.
        device: where the images and depth are converted and left (a torch device; None: the
            CPU): their raw uint8 and uint16 values are copied there first (a quarter of the
            bytes of the converted floats) and converted there, the same values; the vectors
            stay on the CPU.
    """
    import torch

    state = np.asarray(obs[STATE], np.float32)
    out: dict[str, Any] = {STATE: torch.from_numpy(state_features(spec, state))}
    if spec.mobile:  # a perception policy's poses are predicted (LoadedPolicy.act)
        poses = spec.mobile_poses and not spec.perception
        ee = np.asarray(obs[EE_POSE]) if poses else None
        env = np.asarray(obs[ENV_STATE]) if poses else None
        out[ENV_STATE] = torch.from_numpy(spec.mobile_env(obs[SUBTASK_KEY], state, ee, env))
    elif spec.inputs == "state":
        env = spec.env_model(state, np.asarray(obs[EE_POSE]), np.asarray(obs[ENV_STATE]))
        out[ENV_STATE] = torch.from_numpy(env)
    for k in spec.image_keys():
        img = torch.from_numpy(np.ascontiguousarray(obs[k]))
        if device is not None:
            img = img.to(device, non_blocking=True)
        out[k] = img.permute(0, 3, 1, 2).to(torch.float32) / 255.0
    for k in spec.depth_keys():
        raw = np.asarray(obs[k])
        if device is not None and raw.dtype == np.uint16:  # torch moves uint16 as int16's bits
            mm = torch.from_numpy(raw.view(np.int16)).to(device, non_blocking=True)
            mm = mm.to(torch.int32) & 0xFFFF
        else:
            mm = torch.from_numpy(np.asarray(raw, np.int32))
            if device is not None:
                mm = mm.to(device, non_blocking=True)
        out[k] = depth_image(mm, spec.depth_max_m)
    return out
