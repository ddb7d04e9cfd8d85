"""Inverse kinematics of the tool site with mink (differential IK as a QP, joint limits kept).

IK runs on the robot alone (base at the origin), so targets are tool poses in the robot base
frame; collisions with the scene are checked by the caller in the composed model.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from factory.robots.panda import HOME_QPOS, PANDA, TOOL_SITE, RobotIndex, robot_model


@dataclass(frozen=True)
class IKConfig:
    """IK parameters.

    Attributes:
        pos_tol: position error accepted (m).
        rot_tol_deg: orientation error accepted (deg).
        max_iters: QP steps per attempt.
        restarts: random seeds tried after the given seeds.
        dt: integration step of the differential IK (s).
        posture_cost: weight pulling towards the seed posture.
    """

    pos_tol: float = 0.002
    rot_tol_deg: float = 1.0
    max_iters: int = 150
    restarts: int = 6
    dt: float = 0.1
    posture_cost: float = 1e-2


class IKSolver:
    """Tool-site IK for the Panda.

    Args:
        cfg: parameters.
        seed: random seed of the restarts.
    """

    def __init__(self, cfg: IKConfig | None = None, seed: int = 0) -> None:
        import mink

        self._mink = mink
        self.cfg = cfg or IKConfig()
        self.model = robot_model()
        self.robot = RobotIndex.of(self.model)
        self.configuration = mink.Configuration(self.model)
        self.frame = mink.FrameTask(
            frame_name=TOOL_SITE, frame_type="site", position_cost=1.0, orientation_cost=1.0
        )
        self.posture = mink.PostureTask(self.model, cost=self.cfg.posture_cost)
        self.limits = [mink.ConfigurationLimit(self.model)]
        self.rng = np.random.default_rng(seed)
        self._lo = np.array(PANDA.q_min) + 0.01
        self._hi = np.array(PANDA.q_max) - 0.01

    def _attempt(
        self, target: np.ndarray, q0: np.ndarray, best_effort: bool = False
    ) -> np.ndarray | None:
        mink = self._mink
        q = self.model.qpos0.copy()
        q[self.robot.qpos] = np.clip(q0, self._lo, self._hi)
        self.configuration.update(q)
        self.frame.set_target(mink.SE3.from_matrix(target))
        self.posture.set_target(q)
        tasks = [self.frame, self.posture]
        for _ in range(self.cfg.max_iters):
            err = self.frame.compute_error(self.configuration)
            if (
                np.linalg.norm(err[:3]) < self.cfg.pos_tol
                and np.degrees(np.linalg.norm(err[3:])) < self.cfg.rot_tol_deg
            ):
                return np.array(self.configuration.q[self.robot.qpos])
            vel = mink.solve_ik(
                self.configuration,
                tasks,
                self.cfg.dt,
                solver="daqp",
                damping=1e-4,
                limits=self.limits,
            )
            self.configuration.integrate_inplace(vel, self.cfg.dt)
        return np.array(self.configuration.q[self.robot.qpos]) if best_effort else None

    def track(self, pose_tool_in_base: np.ndarray, q0: np.ndarray) -> np.ndarray:
        """Joint positions (7,) moved from ``q0`` towards a tool pose: up to ``max_iters``
        differential-IK steps, no restarts; where the pose is out of reach, the closest
        configuration found (a tracking controller's step, not a solve).

        Args:
            pose_tool_in_base: the target (4, 4), robot base frame.
            q0: the start configuration (7,) (rad), e.g. the previous command.
        """
        q = self._attempt(pose_tool_in_base, q0, best_effort=True)
        assert q is not None
        return q

    def solve(
        self,
        pose_tool_in_base: np.ndarray,
        seeds: Sequence[np.ndarray] = (),
        accept: object = None,
    ) -> np.ndarray | None:
        """Joint positions (7,) reaching a tool pose, or None.

        Args:
            pose_tool_in_base: the target (4, 4), robot base frame.
            seeds: start configurations tried first (then the home pose, then random ones).
            accept: optional ``q -> bool`` (e.g. a collision check); solutions it rejects are
                skipped and the next seed is tried.
        """
        starts = [np.asarray(s, float) for s in seeds] + [HOME_QPOS]
        starts += [self.rng.uniform(self._lo, self._hi) for _ in range(self.cfg.restarts)]
        for q0 in starts:
            q = self._attempt(pose_tool_in_base, q0)
            if q is not None and (accept is None or accept(q)):  # type: ignore[operator]
                return q
        return None

    def solutions(
        self,
        pose_tool_in_base: np.ndarray,
        seeds: Sequence[np.ndarray] = (),
        accept: object = None,
        restarts: int | None = None,
    ) -> Iterator[np.ndarray]:
        """The joint positions (7,) reaching a tool pose from each start in turn, as
        :meth:`solve` tries them (the seeds, the home pose, then ``restarts`` random ones,
        ``cfg.restarts`` when None), those ``accept`` rejects skipped: several arm branches
        of one pose, for a caller that needs more of the pose than reaching it (a straight
        line out of it)."""
        n = self.cfg.restarts if restarts is None else restarts
        starts = [np.asarray(s, float) for s in seeds] + [HOME_QPOS]
        for k in range(len(starts) + n):
            q0 = starts[k] if k < len(starts) else self.rng.uniform(self._lo, self._hi)
            q = self._attempt(pose_tool_in_base, q0)
            if q is not None and (accept is None or accept(q)):  # type: ignore[operator]
                yield q

    def tool_pose(self, q: np.ndarray) -> np.ndarray:
        """Forward kinematics: tool pose (4, 4) in the base frame at arm joints ``q`` (7,)."""
        data = mujoco.MjData(self.model)
        data.qpos[self.robot.qpos] = q
        mujoco.mj_kinematics(self.model, data)
        out = np.eye(4)
        out[:3, :3] = data.site_xmat[self.robot.site].reshape(3, 3)
        out[:3, 3] = data.site_xpos[self.robot.site]
        return out
