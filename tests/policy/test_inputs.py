"""Inputs of a policy: the settings, the base-frame geometry and the depth conversion, the
same for a dataset sample and an env observation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from robot_models import require_robot_models

from factory.errors import PolicyError
from factory.policy.inputs import (
    ENV_STATE,
    INPUTS,
    InputSpec,
    input_spec,
    quat_to_mat,
    rot6d,
)


def _features(cams: tuple[str, ...] = ("left", "wrist"), depth: bool = True, env: bool = True):
    feats = {
        "observation.state": {"dtype": "float32", "shape": [8]},
        "observation.ee_pose": {"dtype": "float32", "shape": [7]},
        "action": {"dtype": "float32", "shape": [8]},
    }
    if env:
        feats[ENV_STATE] = {"dtype": "float32", "shape": [14]}
    for c in cams:
        feats[f"observation.images.{c}"] = {"dtype": "video", "shape": [32, 48, 3]}
        if depth:
            feats[f"observation.depth.{c}"] = {"dtype": "video", "shape": [32, 48, 3]}
    return feats


def test_settings_read_what_they_name() -> None:
    state = input_spec("state", _features())
    assert state.raw_features() == {
        "observation.state": [8],
        "observation.ee_pose": [7],
        ENV_STATE: [14],
    }
    assert state.model_features() == {"observation.state": [17], ENV_STATE: [24]}
    assert state.action == "joint" and state.action_dim == 8
    assert input_spec("state", _features(), "tool").action_dim == 10
    rgb = input_spec("rgb", _features())
    assert rgb.cameras == ("left", "wrist") and rgb.image_size == (32, 48)
    assert ENV_STATE not in rgb.raw_features() and not rgb.depth_keys()
    assert rgb.raw_features()["observation.images.left"] == [32, 48, 3]
    rgbd = input_spec("rgbd", _features())
    assert rgbd.raw_features()["observation.depth.wrist"] == [32, 48]
    assert rgbd.model_features()["observation.depth.wrist"] == [3, 32, 48]
    assert set(INPUTS) == {"state", "rgb", "rgbd"}


def test_a_task_s_own_environment_state_is_read_as_recorded() -> None:
    """A dataset whose environment state is not the two objects' poses (the articulated tasks'
    part joint and handle, already in the base frame) is read as it is, by a trained policy's
    recorded spec too; the fixed task's named object poses still become the 24 model values."""
    from factory.policy.inputs import spec_from_features
    from factory.tasks.articulated.dataset import ENV_STATE_NAMES as PART_NAMES
    from factory.tasks.pick_place.dataset import ENV_STATE_NAMES as OBJECT_NAMES

    feats = _features(cams=())
    feats[ENV_STATE] = {"dtype": "float32", "shape": [len(PART_NAMES)], "names": PART_NAMES}
    own = input_spec("state", feats, "tool")
    assert own.env_dim == len(PART_NAMES) == 11
    assert own.raw_features()[ENV_STATE] == [11] and own.model_features()[ENV_STATE] == [11]
    env = np.random.default_rng(0).normal(size=(5, 11)).astype(np.float32)
    assert np.array_equal(own.env_model(np.zeros((5, 8)), np.zeros((5, 7)), env), env)
    again = spec_from_features("state", own.raw_features(), 2.0, "tool")
    assert again.env_dim == 11 and again.model_features() == own.model_features()
    feats[ENV_STATE] = {"dtype": "float32", "shape": [14], "names": OBJECT_NAMES}
    objects = input_spec("state", feats)
    assert objects.env_dim == 0 and objects.model_features()[ENV_STATE] == [24]
    assert spec_from_features("state", objects.raw_features(), 2.0).env_dim == 0


@pytest.mark.parametrize(
    ("inputs", "feats", "words"),
    [
        ("state", _features(env=False), "observation.environment_state"),
        ("rgbd", _features(depth=False), "observation.depth.left"),
        ("rgb", _features(cams=()), "no camera images"),
        ("pointcloud", _features(), "unknown train.inputs"),
        ("state:velocity", _features(), "unknown train.action"),
    ],
)
def test_missing_features_are_one_line_errors(inputs: str, feats: dict, words: str) -> None:
    inputs, _, action = inputs.partition(":")
    with pytest.raises(PolicyError) as e:
        input_spec(inputs, feats, action or "joint")
    msg = str(e.value)
    assert words in msg and "\n" not in msg
    if inputs == "state" and not action:
        assert "stage=dataset force=true" in msg


def _yaw_rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _mat_to_quat(m: np.ndarray) -> np.ndarray:
    import mujoco

    q = np.empty(4)
    mujoco.mju_mat2Quat(q, m.reshape(9))
    return q


def test_poses_in_the_base_frame_do_not_depend_on_where_the_robot_stands() -> None:
    """The same arm and objects seen from the base give the same features wherever the robot
    stands in the world and whichever way it faces."""
    require_robot_models()
    from factory.policy.inputs import base_poses, env_features, kinematics, robot_features

    joints = np.array(
        [[0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785], [0.3, 0.1, -0.2, -2.0, 0.1, 2.2, 0.5]]
    )
    state = np.concatenate([joints, [[0.08], [0.02]]], axis=1).astype(np.float32)
    pos_b, rot_b = kinematics().tool_poses(joints)
    # two objects in the base frame
    obj_pos = np.array([[0.55, 0.1, 0.02], [0.45, -0.2, 0.0]])
    obj_rot = [_yaw_rot(0.7), _yaw_rot(-1.2)]
    feats = []
    for base_xyz, yaw in (((0.0, 0.0, 0.0), 0.0), ((3.1, -2.4, 0.9), 2.5)):
        rz, t = _yaw_rot(yaw), np.asarray(base_xyz)
        ee = np.array(
            [np.concatenate([rz @ pos_b[i] + t, _mat_to_quat(rz @ rot_b[i])]) for i in range(2)]
        )
        env = np.concatenate(
            [np.concatenate([rz @ obj_pos[k] + t, _mat_to_quat(rz @ obj_rot[k])]) for k in range(2)]
        )
        env = np.stack([env, env]).astype(np.float32)
        got_pos, got_rot = base_poses(state, ee.astype(np.float32))
        assert np.allclose(got_pos, t, atol=1e-5) and np.allclose(got_rot, rz, atol=1e-5)
        feats.append(env_features(state, ee.astype(np.float32), env))
    assert np.allclose(feats[0], feats[1], atol=2e-5)
    assert np.allclose(feats[0][0, :3], obj_pos[0], atol=1e-5)
    assert np.allclose(feats[0][0, 3:9], rot6d(obj_rot[0]), atol=1e-5)
    # the tool-to-object offsets, base frame
    assert np.allclose(feats[0][:, 18:21], obj_pos[0] - pos_b, atol=1e-5)
    assert np.allclose(feats[0][:, 21:24], obj_pos[1] - pos_b, atol=1e-5)
    robot = robot_features(state)
    assert robot.shape == (2, 17) and np.allclose(robot[:, 8:11], pos_b, atol=1e-5)


def test_quaternions_and_rotations_agree_with_mujoco() -> None:
    import mujoco

    q = np.array([0.3, -0.2, 0.9, 0.1])
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, q / np.linalg.norm(q))
    assert np.allclose(quat_to_mat(q), m.reshape(3, 3))


def test_depth_is_converted_identically_from_the_dataset_and_from_the_env() -> None:
    """The dataset's packed depth video (decoded to floats in [0, 1]) and the env's uint16
    millimetres become the same image."""
    require_robot_models()
    import torch

    from factory.dataset.lerobot_export import pack_depth_mm, unpack_depth_mm
    from factory.policy.inputs import convert_observation, convert_sample

    rng = np.random.default_rng(1)
    mm = rng.integers(0, 6000, size=(2, 32, 48)).astype(np.uint16)
    mm[0, 0, :3] = [0, 1999, 65535]
    packed = pack_depth_mm(mm)  # (2, H, W, 3) uint8, what the video stores exactly
    decoded = torch.from_numpy(packed).permute(0, 3, 1, 2).float() / 255.0  # lerobot's view
    assert np.array_equal(unpack_depth_mm(decoded[0]), mm[0])
    spec = InputSpec("rgbd", ("left",), (32, 48))
    img = rng.integers(0, 256, size=(2, 32, 48, 3)).astype(np.uint8)
    state = np.tile(np.array([0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785, 0.08], np.float32), (2, 1))
    ee = np.tile(np.array([0.4, 0.0, 0.4, 0, 1, 0, 0], np.float32), (2, 1))
    sample = {
        "observation.state": torch.from_numpy(state),
        "observation.ee_pose": torch.from_numpy(ee),
        "observation.images.left": torch.from_numpy(img).permute(0, 3, 1, 2).float() / 255.0,
        "observation.depth.left": decoded,
        "action": torch.zeros(2, 8),
        "action_is_pad": torch.zeros(2, dtype=torch.bool),
    }
    from_data = convert_sample(spec, sample)
    obs = {
        "observation.state": state,
        "observation.ee_pose": ee,
        "observation.images.left": img,
        "observation.depth.left": mm,
    }
    from_env = convert_observation(spec, obs)
    assert set(from_env) | {"action", "action_is_pad"} == set(from_data)
    for k, v in from_env.items():
        assert v.shape == from_data[k].shape, k
        assert torch.allclose(v, from_data[k], atol=1e-6), k
    depth = from_env["observation.depth.left"]
    assert depth.shape == (2, 3, 32, 48) and float(depth.min()) >= 0 and float(depth.max()) <= 1
    assert math.isclose(float(depth[0, 0, 0, 1]), 1.999 / 2.0, rel_tol=1e-6)
    assert float(depth[0, 2, 0, 2]) == 1.0  # beyond the range: clipped


def test_tool_actions_are_the_joint_targets_tool_pose_and_track_back_to_it() -> None:
    """``train.action=tool``: the model's action is the forward kinematics of the dataset's
    joint target; the tracker's IK turns a path of such poses back into joint targets that
    reach them (to 1 mm, 1 degree), starting from the measured joints."""
    require_robot_models()
    from factory.policy.inputs import (
        ToolActionTracker,
        kinematics,
        model_actions,
        rot6d_to_mat,
    )

    start = np.array([0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785])
    end = np.array([0.4, 0.2, -0.3, -2.0, 0.2, 2.3, 0.3])
    path = np.linspace(start, end, 20)
    action = np.concatenate([path, np.full((20, 1), 0.04)], axis=1).astype(np.float32)
    tool = model_actions(action, "tool")
    assert tool.shape == (20, 10) and np.allclose(tool[:, 9], 0.04)
    pos, rot = kinematics().tool_poses(path)
    assert np.allclose(tool[:, :3], pos, atol=1e-5)
    assert np.allclose(rot6d_to_mat(tool[:, 3:9]), rot, atol=1e-5)
    assert np.array_equal(model_actions(action, "joint"), action)

    tracker = ToolActionTracker()
    state = np.concatenate([start, [0.08]])[None].astype(np.float32)
    for t in range(20):
        joints = tracker.joints(tool[t : t + 1], state)
        assert joints.shape == (1, 8) and joints[0, 7] == pytest.approx(0.04)
        got_pos, got_rot = kinematics().tool_poses(joints[:, :7].astype(np.float64))
        assert np.linalg.norm(got_pos[0] - pos[t]) < 1e-3
        cos = (np.trace(got_rot[0].T @ rot[t]) - 1) / 2
        assert math.degrees(math.acos(min(1.0, cos))) < 1.0
    # a new episode starts from the measured joints again
    tracker.reset()
    first = tracker.joints(tool[:1], state)
    assert np.allclose(first[0, :7], start, atol=0.05)


def _raw_observation(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """An env observation of two worlds: state, tool pose, one camera's RGB and depth (mm,
    some beyond int16's range)."""
    mm = rng.integers(0, 65536, size=(2, 32, 48)).astype(np.uint16)
    mm[0, 0, :4] = [0, 1999, 40000, 65535]
    return {
        "observation.state": np.tile(
            np.array([0.0, -0.35, 0.0, -2.3, 0.0, 1.95, 0.785, 0.08], np.float32), (2, 1)
        ),
        "observation.ee_pose": np.tile(np.array([0.4, 0, 0.4, 0, 1, 0, 0], np.float32), (2, 1)),
        "observation.images.left": rng.integers(0, 256, size=(2, 32, 48, 3)).astype(np.uint8),
        "observation.depth.left": mm,
    }


def _devices() -> list[str]:
    import torch

    return ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", _devices())
def test_images_converted_on_a_device_are_the_same_values(device: str) -> None:
    """``convert_observation(..., device)``: the images' and depth's raw bytes are moved to the
    device and converted there (uint16 millimetres above 32,767 included), to the values the
    CPU conversion gives; the vectors stay on the CPU. On the GPU machine also on CUDA."""
    import torch

    from factory.policy.inputs import convert_observation

    spec = InputSpec("rgbd", ("left",), (32, 48))
    obs = _raw_observation(np.random.default_rng(3))
    host = convert_observation(spec, obs)
    moved = convert_observation(spec, obs, torch.device(device))
    assert set(host) == set(moved)
    for k in ("observation.images.left", "observation.depth.left"):
        assert moved[k].device.type == device and moved[k].dtype == torch.float32, k
        assert torch.equal(moved[k].cpu(), host[k]), k
    assert moved["observation.state"].device.type == "cpu"
    assert float(host["observation.depth.left"][0, 0, 0, 2]) == 1.0  # 40 m: beyond the range
