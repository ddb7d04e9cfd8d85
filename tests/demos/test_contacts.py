"""``factory.demos.record.contacts`` (``robot_penetration``)."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from factory.demos.record.contacts import robot_penetration

XML = """<mujoco><worldbody><geom type='plane' size='2 2 .1'/>
<body pos='0 0 0.05'><freejoint/><geom type='box' size='.1 .1 .1'/></body>
<body pos='0 0 0.2'><freejoint/><geom type='box' size='.1 .1 .1'/></body>
<body pos='0.15 0 0.05'><freejoint/><geom type='sphere' size='.1'/></body>
</worldbody></mujoco>"""


def _one_by_one(data: mujoco.MjData, robot: np.ndarray, allowed: np.ndarray) -> float:
    """The check contact by contact: the deepest robot-to-scene contact not allowed."""
    worst = 0.0
    for c in data.contact[: data.ncon]:
        g1, g2 = int(c.geom[0]), int(c.geom[1])
        if robot[g1] != robot[g2] and not allowed[g2 if robot[g1] else g1]:
            worst = max(worst, -float(c.dist))
    return worst


def test_robot_penetration_over_every_split_of_the_geoms() -> None:
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon > 3
    seen = set()
    for robot_bits in itertools.product([False, True], repeat=model.ngeom):
        for allowed_bits in itertools.product([False, True], repeat=model.ngeom):
            robot, allowed = np.array(robot_bits), np.array(allowed_bits)
            got = robot_penetration(model, data, robot, allowed)
            assert got == _one_by_one(data, robot, allowed)
            seen.add(round(got, 6))
    assert len(seen) > 2  # depths found, not only zeros
