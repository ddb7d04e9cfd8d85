"""The Panda on the Omron mobile base: composition, cache, cameras, driving, trajectory re-check."""

from __future__ import annotations

import math
import sys

import mujoco
import numpy as np
import pytest
from robot_models import require_robot_models

require_robot_models()
pytest.importorskip("ruckig")

from factory.nav import (
    BASE_COLLISION,
    OccupancyGrid,
    plan_se2_path,
    recheck_base_trajectory,
    time_base_path,
)
from factory.nav.grid import geom_points
from factory.robots import mobile_panda as mr
from factory.robots.mobile_panda import (
    BASE_FOOTPRINT,
    BASE_JOINTS,
    BASE_LIMITS,
    CAMERAS,
    FISHEYE_CAMERA_QUAT,
    FISHEYE_MOUNTS,
    FOOTPRINT_RADIUS,
    STOW_QPOS,
    MobileRobotIndex,
    add_mobile_robot,
    mobile_robot_model,
)

POSE = (1.0, -0.5, 0.7)


def _scene(pose=POSE, box: tuple[float, float] | None = None) -> mujoco.MjModel:
    """A floor, optionally a 0.4 m box at ``box`` (x, y), and the mobile robot at ``pose``."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    if box is not None:
        spec.worldbody.add_geom(
            name="box", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[*box, 0.4], size=[0.2, 0.2, 0.4]
        )
    add_mobile_robot(spec, pose)
    return spec.compile()


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mobile_robot_model(POSE)


def _yaw(quat: np.ndarray) -> float:
    return 2 * math.atan2(quat[3], quat[0])


def test_model_parts(model: mujoco.MjModel) -> None:
    idx = MobileRobotIndex.of(model)
    types = [model.jnt_type[model.joint(j).id] for j in BASE_JOINTS]
    assert types == [mujoco.mjtJoint.mjJNT_SLIDE] * 2 + [mujoco.mjtJoint.mjJNT_HINGE]
    assert model.nu == 12 and list(idx.ctrl_base) == [0, 1, 2]
    assert list(idx.ctrl_arm) == list(range(3, 10)) and list(idx.ctrl_fingers) == [10, 11]
    assert all(model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE for a in idx.ctrl_base)
    for cam in CAMERAS.values():
        assert model.camera(cam).id >= 0
        assert model.cam_bodyid[model.camera(cam).id] in idx.bodies  # they ride on the robot
    for mount in FISHEYE_MOUNTS.values():
        assert model.body(mount).parentid == idx.base_body
    # no torso lift, no robosuite velocity actuators: 3 base + 7 arm + 2 finger dofs
    assert model.nv == 12
    # qpos0 is the given pose, in world coordinates
    data = mujoco.MjData(model)
    assert np.allclose(data.qpos[idx.base_qpos], POSE)
    mujoco.mj_forward(model, data)
    assert np.allclose(data.xpos[idx.base_body][:2], POSE[:2])
    assert _yaw(data.xquat[idx.base_body]) == pytest.approx(POSE[2])
    # the slides move along world x and y even though the base starts turned
    data.qpos[idx.base_qpos] = [POSE[0] + 1.0, POSE[1] + 2.0, 0.0]
    mujoco.mj_forward(model, data)
    assert np.allclose(data.xpos[idx.base_body], [POSE[0] + 1.0, POSE[1] + 2.0, 0.0])
    assert _yaw(data.xquat[idx.base_body]) == pytest.approx(0.0)
    link0 = data.xpos[model.body("mobile/robot0_link0").id]
    assert np.allclose(link0 - data.xpos[idx.base_body], mr.ARM_MOUNT)


def test_stow_fits_the_footprint(model: mujoco.MjModel) -> None:
    idx = MobileRobotIndex.of(model)
    data = mujoco.MjData(model)
    idx.stow(data)
    mujoco.mj_forward(model, data)
    centre = data.xpos[idx.base_body][:2]
    for g in idx.geoms:
        pts = geom_points(model, data, int(g))
        assert np.linalg.norm(pts[:, :2] - centre, axis=1).max() <= FOOTPRINT_RADIUS
    # the folded arm touches nothing of the base (only the closed fingers touch each other)
    for c in data.contact[: data.ncon]:
        b1, b2 = (model.body(int(model.geom_bodyid[g])).name for g in c.geom)
        assert "finger" in b1 and "finger" in b2, (b1, b2)


def test_cameras_look_at_the_workspace(model: mujoco.MjModel) -> None:
    idx = MobileRobotIndex.of(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rig = mr.MobileCameraRig()
    base = data.xpos[idx.base_body]
    c, s = math.cos(POSE[2]), math.sin(POSE[2])
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    target = base + rot @ np.array(rig.workspace)
    for name in ("left", "right"):
        cid = model.camera(CAMERAS[name]).id
        view = -data.cam_xmat[cid].reshape(3, 3)[:, 2]
        to_target = target - data.cam_xpos[cid]
        assert view @ to_target / np.linalg.norm(to_target) == pytest.approx(1.0, abs=1e-6)
    left, right = (data.cam_xpos[model.camera(CAMERAS[n]).id] for n in ("left", "right"))
    assert (rot.T @ (left - base))[1] > 0 > (rot.T @ (right - base))[1]
    # a camera put in a fisheye mount with the documented quat looks out front / back
    q = np.zeros(9)
    mujoco.mju_quat2Mat(q, np.array(FISHEYE_CAMERA_QUAT))
    for name, sign in (("fisheye_front", 1.0), ("fisheye_back", -1.0)):
        bid = model.body(FISHEYE_MOUNTS[name]).id
        view = data.xmat[bid].reshape(3, 3) @ -q.reshape(3, 3)[:, 2]
        assert view @ (rot @ [sign, 0, 0]) == pytest.approx(1.0, abs=1e-6)


def test_drive_along_a_trajectory() -> None:
    """Feeding a timed trajectory to the base actuators drives the robot to its goal; the
    gravity-compensated, position-held arm stays near the stow pose."""
    start = (0.0, 0.0, 0.0)
    model = _scene(start)
    idx = MobileRobotIndex.of(model)
    data = mujoco.MjData(model)
    idx.stow(data)
    idx.drive_to(data, start)
    mujoco.mj_forward(model, data)
    # driving while turning, as SE(2) paths do: forward turning left, then sideways on
    poses = np.array([[0.0, 0.0, 0.0], [1.5, 0.0, math.pi / 2], [1.5, 1.0, math.pi]])
    traj = time_base_path(poses, BASE_LIMITS, dt=0.01)
    steps = round(traj.dt / model.opt.timestep)
    lag, arm_dev = 0.0, 0.0
    for k in range(len(traj.t)):
        idx.drive_to(data, traj.q[k])
        mujoco.mj_step(model, data, nstep=steps)
        lag = max(lag, float(np.linalg.norm(data.qpos[idx.base_qpos[:2]] - traj.q[k, :2])))
        arm_dev = max(arm_dev, float(np.abs(data.qpos[idx.qpos] - STOW_QPOS).max()))
    mujoco.mj_step(model, data, nstep=500)  # 1 s to settle
    final = data.qpos[idx.base_qpos]
    assert np.linalg.norm(final[:2] - [1.5, 1.0]) < 0.01
    assert final[2] == pytest.approx(math.pi, abs=0.02)
    assert lag < 0.08
    assert arm_dev < 0.05
    body = data.xpos[idx.base_body]
    assert np.allclose(body[:2], [1.5, 1.0], atol=0.01)


def test_grid_plan_and_recheck() -> None:
    """The robot is no obstacle of its own grid; an SE(2) path around a box passes the MuJoCo
    re-check, the straight path through it fails with ``base_collision``."""
    start, goal = (-1.0, 0.0, 0.0), (2.0, 0.0, 0.0)
    model = _scene(start, box=(0.5, 0.0))
    idx = MobileRobotIndex.of(model)
    data = mujoco.MjData(model)
    idx.stow(data)
    mujoco.mj_forward(model, data)
    raw = OccupancyGrid.from_model(model, data, bounds=(-2.0, -2.0, 3.0, 2.0))
    assert raw.free(np.array(start[:2]))  # the robot itself is not an obstacle
    assert not raw.free(np.array([0.5, 0.0]))

    through = time_base_path(np.array([start, goal]), dt=0.05)
    bad = recheck_base_trajectory(model, data.qpos, through.q, idx.base_qpos, idx.geoms)
    assert not bad.ok and bad.reason == BASE_COLLISION
    assert bad.max_penetration > 0.02
    assert bad.contact[1] == "world" and bad.contact[0].startswith("mobile/")

    res = plan_se2_path(raw, BASE_FOOTPRINT, np.array(start), np.array(goal), seed=2)
    assert res.ok, res.detail
    assert len(res.path) > 2  # around the box
    around = time_base_path(res.path, dt=0.05)
    good = recheck_base_trajectory(model, data.qpos, around.q, idx.base_qpos, idx.geoms)
    assert good.ok and good.reason == "" and good.max_penetration <= 0.02
    assert good.samples == len(around.t)


def test_cache_serves_without_robosuite(tmp_path, monkeypatch) -> None:
    """The composed model is exported once to FACTORY_ROBOT_CACHE; later builds read it there
    and need no robosuite."""
    monkeypatch.setenv("FACTORY_ROBOT_CACHE", str(tmp_path))
    mr._mobile_xml.cache_clear()
    try:
        first = mobile_robot_model()
        cache = mr.mobile_cache_dir()
        assert cache.parent == tmp_path and (cache / "robot.xml").is_file()
        assert any((cache / "files").glob("*omron*"))
        mr._mobile_xml.cache_clear()
        monkeypatch.setitem(sys.modules, "robosuite", None)  # import robosuite now fails
        second = mobile_robot_model()
        assert (second.nq, second.nu, second.ngeom) == (first.nq, first.nu, first.ngeom)
    finally:
        mr._mobile_xml.cache_clear()
