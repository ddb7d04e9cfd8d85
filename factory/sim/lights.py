"""Room lighting of a compiled scene: ceiling lights per room and a light in every lamp.

* **Ceiling lights**: a grid of downward spot lights just under the ceiling, one per
  :data:`CEILING_SPACING` metres of the room's width and length (at least one, at most
  :data:`MAX_CEILING`), with wide cones (:data:`CEILING_CUTOFF`) so that every light reaches
  the whole floor, and shadows (``castshadow``). Their diffuse intensity is split over the
  grid so that a large room is not brighter than a small one.
* **Lamp lights**: a warm light at the shade of every lamp (:data:`LAMP_CATEGORIES`), attached
  to the lamp's body and falling off with distance; it casts no shadow (its own shade would
  shadow the room).

MuJoCo's OpenGL renderer (EGL, OSMesa) draws only spot and directional lights (a ``point``
light lights nothing there) and at most eight lights per image, the headlight included:
ceiling lights are added with the rooms, before any lamp, so a scene of many rooms keeps its
ceiling lights first (the recording of demonstrations switches off the lights of the rooms
the robot is not in, :func:`factory.demos.record.appearance.room_lights`). Each shadow-casting light
costs one depth pass per rendered image.
"""

from __future__ import annotations

from dataclasses import dataclass

from factory.schema import Room, SceneObject

CEILING_SPACING = 3.0
"""Room length per ceiling light along each axis (m)."""

MAX_CEILING = 4
"""Most ceiling lights per room (a 2 x 2 grid)."""

CEILING_DROP = 0.05
"""Ceiling lights hang this far under the ceiling (m)."""

CEILING_CUTOFF = 70.0
"""Half-angle of a ceiling light's cone (deg)."""

CEILING_EXPONENT = 1.0
"""Spot exponent of a ceiling light (intensity falls as cos(angle) ** exponent)."""

CEILING_DIFFUSE = 0.6
"""Diffuse intensity of a room's ceiling lights together (per channel, 0..1)."""

CEILING_COLOR = (1.0, 0.97, 0.92)
"""Colour of ceiling lights (slightly warm white)."""

LAMP_CATEGORIES: dict[str, float] = {"floor_lamp": 0.8, "table_lamp": 0.75}
"""Lamp categories -> height of the bulb as a share of the lamp's height."""

LAMP_DIFFUSE = 0.35
"""Diffuse intensity of a lamp at 1 m (per channel)."""

LAMP_COLOR = (1.0, 0.84, 0.62)
"""Colour of lamp light (incandescent warm white)."""

LAMP_ATTENUATION = (1.0, 0.25, 0.25)
"""Constant, linear (1/m) and quadratic (1/m^2) attenuation of lamp light."""

LAMP_CUTOFF = 85.0
"""Half-angle of a lamp's downward cone (deg)."""


@dataclass(frozen=True)
class LightSpec:
    """One light to add to the model.

    Attributes:
        name: light name in the model (``<room>/ceiling_<k>`` or ``<object>/lamp``).
        kind: ``ceiling`` or ``lamp``.
        pos: position (m): world frame for ceiling lights, the lamp body's frame for lamps.
        dir: direction of the cone's axis (unit vector, same frame).
        diffuse: diffuse colour times intensity (per channel, 0..1).
        specular: specular colour (per channel).
        cutoff: half-angle of the cone (deg).
        exponent: spot exponent.
        attenuation: constant, linear (1/m) and quadratic (1/m^2) attenuation.
        castshadow: the light casts shadows.
    """

    name: str
    kind: str
    pos: tuple[float, float, float]
    dir: tuple[float, float, float]
    diffuse: tuple[float, float, float]
    specular: tuple[float, float, float]
    cutoff: float
    exponent: float
    attenuation: tuple[float, float, float] = (1.0, 0.0, 0.0)
    castshadow: bool = False


def ceiling_grid(width: float, length: float) -> tuple[int, int]:
    """Ceiling lights along a room's width and length (m): one per
    :data:`CEILING_SPACING`, rounded, at least one, at most :data:`MAX_CEILING` in all."""
    nx = max(1, round(width / CEILING_SPACING))
    ny = max(1, round(length / CEILING_SPACING))
    while nx * ny > MAX_CEILING:
        if nx >= ny:
            nx -= 1
        else:
            ny -= 1
    return nx, ny


def ceiling_lights(room: Room) -> list[LightSpec]:
    """The ceiling lights of a room (world frame), centred in the cells of its grid."""
    w, ln = room.dimensions.width, room.dimensions.length
    x0, y0, z0 = room.position.as_tuple()
    nx, ny = ceiling_grid(w, ln)
    n = nx * ny
    # Overlapping cones add up: the grid's lights share the room's intensity (a little more
    # than 1/n each, since a light's cone falls off towards the far corners).
    level = CEILING_DIFFUSE / n**0.7
    z = z0 + room.ceiling_height - CEILING_DROP
    r, g, b = CEILING_COLOR
    out: list[LightSpec] = []
    for i in range(nx):
        for j in range(ny):
            out.append(
                LightSpec(
                    name=f"{room.id}/ceiling_{i * ny + j}",
                    kind="ceiling",
                    pos=(x0 + (i + 0.5) * w / nx, y0 + (j + 0.5) * ln / ny, z),
                    dir=(0.0, 0.0, -1.0),
                    diffuse=(level * r, level * g, level * b),
                    specular=(0.1, 0.1, 0.1),
                    cutoff=CEILING_CUTOFF,
                    exponent=CEILING_EXPONENT,
                    castshadow=True,
                )
            )
    return out


def lamp_light(obj: SceneObject) -> LightSpec | None:
    """The light of a lamp object (in its body frame), ``None`` for other categories."""
    share = LAMP_CATEGORIES.get(obj.category)
    if share is None:
        return None
    h = obj.dimensions.height
    return LightSpec(
        name=f"{obj.id}/lamp",
        kind="lamp",
        pos=(0.0, 0.0, share * h),
        dir=(0.0, 0.0, -1.0),
        diffuse=(
            LAMP_DIFFUSE * LAMP_COLOR[0],
            LAMP_DIFFUSE * LAMP_COLOR[1],
            LAMP_DIFFUSE * LAMP_COLOR[2],
        ),
        specular=(0.05, 0.05, 0.05),
        cutoff=LAMP_CUTOFF,
        exponent=0.0,
        attenuation=LAMP_ATTENUATION,
        castshadow=False,
    )
