"""The Panda hand's finger targets (``FingerTargets``)."""

from __future__ import annotations

import numpy as np

from factory.robots.panda import FingerTargets


def test_gripper_ctrls_is_gripper_ctrl_of_each_opening() -> None:
    openings = np.array([0.08, 0.1, 0.04, 0.0, -0.02, -0.5])
    fingers = FingerTargets()
    want = np.stack([fingers.gripper_ctrl(float(o)) for o in openings])
    np.testing.assert_array_equal(fingers.gripper_ctrls(openings), want)
    assert fingers.gripper_ctrls(np.zeros(0)).shape == (0, 2)
