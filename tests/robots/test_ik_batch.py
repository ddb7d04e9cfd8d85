"""The batched tool tracker against mink's (``factory.robots.ik_batch``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from factory.robots.ik import IKConfig, IKSolver
from factory.robots.ik_batch import BatchTracker, bounded_step, rotation_error
from factory.robots.panda import HOME_QPOS

pytest.importorskip("mink")

CFG = IKConfig(max_iters=20, pos_tol=5e-4, rot_tol_deg=0.5)  # the policy's tracker


def _path(n: int, frames: int) -> tuple[np.ndarray, list, list]:
    """Start joints (n, 7) near home and, per frame, tool targets drifting 4 mm and 0.5 deg a
    frame with 1 mm of noise: ``scripts/bench_tool_tracker.py``'s paths (the benchmark's and
    this test's are the same)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "bench_tool_tracker.py"
    spec = importlib.util.spec_from_file_location("_bench_tool_tracker", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench.paths(n, frames, far=False)


def test_batch_tracker_follows_mink_on_a_tool_path() -> None:
    """Frame by frame from the previous command, 90 arms, some driven to a joint limit: both
    trackers reach every target within the tolerances (but where a joint binds) and stay within
    1e-3 rad of each other."""
    n = 90
    q0, pos, rot = _path(n, 40)
    mink_ik, batch = IKSolver(CFG), BatchTracker(CFG)
    qm, qb = q0.copy(), q0.copy()
    bound = np.zeros(n, bool)
    for p, r in zip(pos, rot, strict=True):
        for i in range(n):
            target = np.eye(4)
            target[:3, :3], target[:3, 3] = r[i], p[i]
            qm[i] = mink_ik.track(target, qm[i])
        qb = batch.track(p, r, qb)
        got_p, got_r, _ = batch.kinematics(qb)
        reached = (np.linalg.norm(got_p - p, axis=1) < CFG.pos_tol) & (
            np.degrees(np.linalg.norm(rotation_error(r, got_r), axis=1)) < CFG.rot_tol_deg
        )
        at_limit = (np.abs(qb - batch.lo) < 1e-3) | (np.abs(qb - batch.hi) < 1e-3)
        assert (reached | at_limit.any(axis=1)).all()  # a bound joint may leave it short
        assert np.abs(qm - qb).max() < 1e-3
        bound = bound | at_limit.any(axis=1)
    assert bound.any()  # the path takes some arms to a joint limit, where the QP's bound acts


def test_batch_tracker_out_of_reach_steps_as_mink() -> None:
    """Targets out of reach: the first step is mink's bounded QP step (further steps differ:
    mink linearises the error through SE(3)'s log, and both trackers then wander from one
    linearisation to the next), the joints stay inside their limits, an arm at its target
    stays."""
    q0 = np.tile(np.asarray(HOME_QPOS, float), (3, 1))
    pos, rot, _ = BatchTracker(CFG).kinematics(q0)
    far = pos.copy()
    far[:2] += np.array([[1.0, 0.0, 0.0], [0.0, -0.8, 0.3]])
    for steps in (1, 20):
        cfg = IKConfig(max_iters=steps, pos_tol=CFG.pos_tol, rot_tol_deg=CFG.rot_tol_deg)
        batch, mink_ik = BatchTracker(cfg), IKSolver(cfg)
        q = batch.track(far, rot, q0)
        assert np.isfinite(q).all()
        assert ((q >= batch.lo - 1e-9) & (q <= batch.hi + 1e-9)).all()
        np.testing.assert_allclose(
            q[2], np.clip(q0[2], batch._start_lo, batch._start_hi), atol=1e-12
        )
        if steps == 1:  # the first step is mink's bounded QP step
            for i in range(2):
                target = np.eye(4)
                target[:3, :3], target[:3, 3] = rot[i], far[i]
                np.testing.assert_allclose(q[i], mink_ik.track(target, q0[i]), atol=1e-6)


def test_bounded_step_is_the_box_qp() -> None:
    """The bounded step against scipy's L-BFGS-B on random box QPs, some bounds binding."""
    from scipy.optimize import Bounds, minimize

    rng = np.random.default_rng(3)
    n, k = 20, 7
    a = rng.normal(0, 1, (n, 6, k))
    h = np.swapaxes(a, -1, -2) @ a + 1e-3 * np.eye(k)
    g = rng.normal(0, 2, (n, k))
    lo, hi = -rng.uniform(0.05, 1.0, (n, k)), rng.uniform(0.05, 1.0, (n, k))
    got = bounded_step(h, g, lo, hi)
    bound = 0
    for i in range(n):

        def f(v: np.ndarray, i: int = i) -> float:
            return float(0.5 * v @ h[i] @ v - g[i] @ v)

        ref = minimize(
            f,
            np.zeros(k),
            jac=lambda v, i=i: h[i] @ v - g[i],
            bounds=Bounds(lo[i], hi[i]),
            method="L-BFGS-B",
            options={"maxiter": 20000, "ftol": 1e-16, "gtol": 1e-12},
        )
        assert f(got[i]) <= f(ref.x) + 1e-7
        assert ((got[i] >= lo[i] - 1e-12) & (got[i] <= hi[i] + 1e-12)).all()
        bound += int(np.isclose(got[i], lo[i]).any() or np.isclose(got[i], hi[i]).any())
    assert bound > n // 2


def test_rotation_error_is_the_rotation_vector() -> None:
    rng = np.random.default_rng(0)
    a = Rotation.random(6, random_state=1).as_matrix()
    vec = rng.normal(0, 0.8, (6, 3))
    vec[0] = [np.pi - 1e-5, 0, 0]  # near pi
    b = Rotation.from_rotvec(vec).as_matrix() @ a
    got = rotation_error(b, a)
    np.testing.assert_allclose(got[1:], vec[1:], atol=1e-8)
    assert abs(np.linalg.norm(got[0]) - (np.pi - 1e-5)) < 1e-4
