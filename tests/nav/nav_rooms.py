"""A hand-built MuJoCo room for the navigation tests: 6 x 4 m, walls, known obstacles.

(A helper module, not a conftest: test modules import it by name.)
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

ROOM = (0.0, 0.0, 6.0, 4.0)
"""(xmin, ymin, xmax, ymax) of the room (m): the walls are centred on these lines."""
WALL_T = 0.1
OBSTACLE = (3.0, 2.0, 0.4, 0.6)
"""Box obstacle: centre x, y and half sizes x, y (m); 0.8 m high, on the floor."""
DOOR = (1.4, 2.6)
"""The doorway of the dividing wall at x = 3: y from, y to (m)."""


def build_room(
    obstacle: bool = True,
    divider: str | None = None,
    extras: bool = False,
    door: tuple[float, float] = DOOR,
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The test room compiled, with forward kinematics done.

    Args:
        obstacle: a box in the middle of the room (``OBSTACLE``).
        divider: ``None``; ``"open"`` a wall at x = 3 with a doorway ``DOOR``; ``"blocked"``
            the same wall with a cylinder standing in the doorway.
        door: the doorway of the divider (y from, y to; m).
        extras: also a floor slab, a high shelf (above the band), a 45-degree box, an upright
            cylinder, a mesh prism, a free sphere, a visual-only box and a body named like the
            robot (``mobile/...``).
    """
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    wb = spec.worldbody
    wb.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    x0, y0, x1, y1 = ROOM
    h = 2.5
    box = mujoco.mjtGeom.mjGEOM_BOX
    for name, pos, size in (
        ("south", [(x0 + x1) / 2, y0, h / 2], [(x1 - x0) / 2, WALL_T / 2, h / 2]),
        ("north", [(x0 + x1) / 2, y1, h / 2], [(x1 - x0) / 2, WALL_T / 2, h / 2]),
        ("west", [x0, (y0 + y1) / 2, h / 2], [WALL_T / 2, (y1 - y0) / 2, h / 2]),
        ("east", [x1, (y0 + y1) / 2, h / 2], [WALL_T / 2, (y1 - y0) / 2, h / 2]),
    ):
        wb.add_geom(name=f"wall/{name}", type=box, pos=pos, size=size)
    if obstacle:
        cx, cy, hx, hy = OBSTACLE
        wb.add_geom(name="obstacle", type=box, pos=[cx, cy, 0.4], size=[hx, hy, 0.4])
    if divider is not None:
        d0, d1 = door
        for k, (a, b) in enumerate(((y0, d0), (d1, y1))):
            wb.add_geom(
                name=f"divider/{k}",
                type=box,
                pos=[3.0, (a + b) / 2, h / 2],
                size=[WALL_T / 2, (b - a) / 2, h / 2],
            )
        wb.add_geom(  # the lintel over the door: above the robot's band
            name="divider/lintel",
            type=box,
            pos=[3.0, (d0 + d1) / 2, 2.25],
            size=[0.05, (d1 - d0) / 2, 0.25],
        )
        if divider == "blocked":
            wb.add_geom(
                name="blocker",
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                pos=[3.0, (d0 + d1) / 2, 0.5],
                size=[0.35, 0.5, 0],
            )
    if extras:
        wb.add_geom(name="slab", type=box, pos=[3.0, 2.0, -0.005], size=[3.0, 2.0, 0.0055])
        wb.add_geom(name="shelf", type=box, pos=[1.0, 3.0, 2.05], size=[0.3, 0.3, 0.05])
        wb.add_geom(
            name="diamond",
            type=box,
            pos=[1.0, 1.0, 0.3],
            size=[0.3, 0.3, 0.3],
            quat=[math.cos(math.pi / 8), 0, 0, math.sin(math.pi / 8)],
        )
        wb.add_geom(
            name="drum",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            pos=[5.0, 1.0, 0.4],
            size=[0.3, 0.4, 0],
        )
        prism = np.array(
            [[0, 0, 0], [0.6, 0, 0], [0, 0.6, 0], [0, 0, 0.5], [0.6, 0, 0.5], [0, 0.6, 0.5]], float
        )
        spec.add_mesh(name="prism", uservert=prism.ravel().tolist())
        wb.add_geom(
            name="prism", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="prism", pos=[4.5, 3.0, 0]
        )
        ball = wb.add_body(name="ball", pos=[1.0, 2.0, 0.1])
        ball.add_freejoint()
        ball.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0])
        wb.add_geom(
            name="ghost",
            type=box,
            pos=[2.0, 3.3, 0.3],
            size=[0.2, 0.2, 0.3],
            contype=0,
            conaffinity=0,
        )
        robot = wb.add_body(name="mobile/robot0_base", pos=[4.2, 0.7, 0])
        robot.add_geom(name="mobile/box", type=box, pos=[0, 0, 0.2], size=[0.3, 0.3, 0.2])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data
