"""Parts of the hand-built living rooms of the mobile-task tests: the walled room, a coke can
and a desk.

(A helper module, not a conftest: test modules import it by name; the folder ``tests`` is on
the import path through its conftest.)
"""

from __future__ import annotations

from factory.schema import Physics, Placement, Room, SceneObject, Size3, Vec3, Wall


def living_room(width: float, length: float) -> Room:
    """The room ``living``: a ``width`` x ``length`` m floor at the origin, 2.7 m high, closed
    by four 2.5 m walls.

    Args:
        width: Extent along x (m).
        length: Extent along y (m).

    Returns:
        The room, with walls ``w0`` to ``w3`` counter-clockwise from the origin.
    """
    corners = [(0.0, 0.0), (width, 0.0), (width, length), (0.0, length)]
    walls = [
        Wall(id=f"w{i}", start=Vec3(*a, 0.0), end=Vec3(*b, 0.0), height=2.5)
        for i, (a, b) in enumerate(zip(corners, corners[1:] + corners[:1], strict=True))
    ]
    return Room(
        id="living",
        room_type="living_room",
        position=Vec3(0, 0, 0),
        dimensions=Size3(width, length, 2.7),
        walls=walls,
    )


def can(position: Vec3, support_id: str) -> SceneObject:
    """The can to pick (``can``, 0.3 kg), standing on top of a support.

    Args:
        position: Where the can stands (m).
        support_id: The object it stands on.

    Returns:
        The can, with task role ``pick``.
    """
    return SceneObject(
        id="can",
        room_id="living",
        category="can",
        position=position,
        dimensions=Size3(0.066, 0.066, 0.12),
        placement=Placement(kind="on_top", support_id=support_id),
        physics=Physics(mass=0.3),
        task_role="pick",
    )


def desk(x: float, y: float, task_role: str) -> SceneObject:
    """The desk (``desk``, 1.2 x 0.6 x 0.75 m, 30 kg) on the floor.

    Args:
        x: Its centre's x (m).
        y: Its centre's y (m).
        task_role: Its role in the task (``place_target`` or ``place_support``).

    Returns:
        The desk.
    """
    return SceneObject(
        id="desk",
        room_id="living",
        category="desk",
        position=Vec3(x, y, 0.0),
        dimensions=Size3(1.2, 0.6, 0.75),
        physics=Physics(mass=30.0),
        task_role=task_role,
    )
