"""The scene schema: typed dataclasses, JSON I/O and validation.

A scene is what every stage exchanges (``scenes/<scene_id>/scene.json``). It is a superset of
SAGE's layout JSON (see :mod:`factory.schema.sage`), with these conventions:

* Units are SI (metres, kilograms); angles in JSON are degrees.
* World frame: z up, the floor at z = 0.
* A room's ``position`` is its minimum corner; ``dimensions`` are width (x), length (y),
  height (z).
* An object's ``position`` is the bottom centre of the object in the world frame
  (``pos_obj_in_world``); its mesh lives in the object frame, z up, centred in x and y, with its
  bottom at z = 0.
* ``rotation`` is Euler x, y, z in degrees applied as ``R = Rz @ Ry @ Rx`` (then the
  translation). A plain yaw is ``rotation.z``.
* An object placed on a wall (``placement.kind == "wall"``) or marked ``physics.static`` is
  static; every other object is a free rigid body.

This module imports nothing else of factory but :mod:`factory.schema.errors`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from factory.schema.errors import SchemaError, SchemaVersionError, UnsafePathError
from factory.schema.migrate import upgrade

SCHEMA_VERSION = 2
"""Version of ``scene.json`` written by this factory (2 added ``SceneObject.joint_states`` and
``task_joint``). Older versions are upgraded on reading (:mod:`factory.schema.migrate`)."""

RESERVED_JOINT_NAMES: tuple[str, ...] = ("free",)
"""Names an object's joints may not take: the compiler names an object's free joint
``<object id>/free``."""

PlacementKind = Literal["floor", "wall", "on_top"]
PLACEMENT_KINDS: tuple[str, ...] = ("floor", "wall", "on_top")
SOURCES_PREFIXES: tuple[str, ...] = ("text", "image", "task", "sage10k", "augment:", "example")

ROOM_TOLERANCE = 0.05
"""How far (m) an object's centre may lie outside its room's footprint and still count as
inside: half a standard wall (wall-mounted objects sit on the wall's centre line)."""

_ID_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}$")


def check_id(value: str, what: str = "id") -> str:
    """Checks that ``value`` is safe as a file name and a MuJoCo name.

    Args:
        value: the id.
        what: what the id names, for the error message.

    Returns:
        ``value`` unchanged.

    Raises:
        UnsafePathError: if the id contains a path separator or ``..``.
        SchemaError: if the id is empty or has characters outside ``[A-Za-z0-9_.-]``.
    """
    if not isinstance(value, str) or not value:
        raise SchemaError(f"{what} must be a non-empty string, got {value!r}")
    if "/" in value or "\\" in value or ".." in value:
        raise UnsafePathError(
            f"{what} {value!r} contains a path ('/', '\\\\' or '..'): ids become directory "
            "names; use letters, digits, '_', '-' and '.' only"
        )
    if not _ID_RE.match(value):
        raise SchemaError(
            f"{what} {value!r} is not a valid id: use 1-128 characters of [A-Za-z0-9_.-], "
            "not starting with '.' or '-'"
        )
    return value


# --------------------------------------------------------------------------------------------
# Value types


@dataclass
class Vec3:
    """A point or vector in metres (JSON ``{"x", "y", "z"}``)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)


@dataclass
class Size3:
    """Extents in metres: width along x, length along y, height along z."""

    width: float
    length: float
    height: float

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.width, self.length, self.height)


@dataclass
class Euler:
    """Rotation as Euler angles in degrees, applied as ``R = Rz @ Ry @ Rx``."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0

    def quat_wxyz(self) -> tuple[float, float, float, float]:
        """The same rotation as a unit quaternion ``(w, x, y, z)`` (MuJoCo's order)."""
        hx, hy, hz = (math.radians(a) / 2.0 for a in (self.x, self.y, self.z))
        cx, sx = math.cos(hx), math.sin(hx)
        cy, sy = math.cos(hy), math.sin(hy)
        cz, sz = math.cos(hz), math.sin(hz)
        # q = qz * qy * qx
        w = cz * cy * cx + sz * sy * sx
        x = cz * cy * sx - sz * sy * cx
        y = cz * sy * cx + sz * cy * sx
        z = sz * cy * cx - cz * sy * sx
        return (w, x, y, z)


# --------------------------------------------------------------------------------------------
# Architecture


@dataclass
class Wall:
    """A straight wall segment; its centre line runs from ``start`` to ``end`` (world frame)."""

    id: str
    start: Vec3
    end: Vec3
    height: float
    thickness: float = 0.1
    material: str = "drywall"
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def length(self) -> float:
        return math.hypot(self.end.x - self.start.x, self.end.y - self.start.y)


@dataclass
class Door:
    """An opening in a wall: centred at ``position_on_wall`` (0..1 from start to end)."""

    id: str
    wall_id: str
    position_on_wall: float
    width: float
    height: float
    door_type: str = "standard"
    opens_inward: bool = True
    opening: bool = False
    material: str = "standard"
    extras: dict[str, Any] = field(default_factory=dict)


@dataclass
class Window:
    """A window in a wall, centred at ``position_on_wall``, from ``sill_height`` upwards."""

    id: str
    wall_id: str
    position_on_wall: float
    width: float
    height: float
    sill_height: float
    window_type: str = "standard"
    material: str = "standard"
    extras: dict[str, Any] = field(default_factory=dict)


@dataclass
class Room:
    """An axis-aligned room: ``position`` is its minimum corner (m)."""

    id: str
    room_type: str
    position: Vec3
    dimensions: Size3
    walls: list[Wall] = field(default_factory=list)
    doors: list[Door] = field(default_factory=list)
    windows: list[Window] = field(default_factory=list)
    floor_material: str = "hardwood"
    ceiling_height: float = 2.7
    extras: dict[str, Any] = field(default_factory=dict)

    def contains_xy(self, x: float, y: float, tol: float = 1e-6) -> bool:
        """Whether the point ``(x, y)`` (world frame, m) lies on the room's footprint."""
        return (
            self.position.x - tol <= x <= self.position.x + self.dimensions.width + tol
            and self.position.y - tol <= y <= self.position.y + self.dimensions.length + tol
        )


# --------------------------------------------------------------------------------------------
# Objects


@dataclass
class Placement:
    """How an object is supported.

    ``kind`` is ``floor`` (``support_id`` empty or the room id), ``wall`` (``support_id`` empty
    or a wall id; the object is static) or ``on_top`` (``support_id`` is another object's id).
    ``location`` is ``top``, ``inside`` or ``both`` (where on the support).
    """

    kind: PlacementKind = "floor"
    support_id: str | None = None
    location: str = "top"
    guidance: str = ""
    constraints: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class AssetRef:
    """Where an object's geometry comes from.

    ``backend`` is ``procedural``, ``mesh_library``, ``trellis`` or ``sage`` (imported from a
    SAGE scene); ``asset_id`` names the directory ``assets/<asset_id>/`` of the run, empty when
    the object has no geometry yet (it then compiles as a box of its dimensions); ``source`` and
    ``source_id`` keep SAGE's fields of the same names (its mesh is ``<source_id>.ply``).
    """

    backend: str
    asset_id: str = ""
    source: str = ""
    source_id: str = ""
    scale: Vec3 = field(default_factory=lambda: Vec3(1.0, 1.0, 1.0))


@dataclass
class Physics:
    """Rigid-body properties: ``mass`` (kg), sliding ``friction`` coefficient, ``static``."""

    mass: float = 1.0
    friction: float = 0.6
    static: bool = False


@dataclass
class Appearance:
    """Colour (``rgba`` in 0..1) and PBR parameters; ``None`` means "not specified"."""

    rgba: list[float] | None = None
    metallic: float | None = None
    roughness: float | None = None


@dataclass
class SceneObject:
    """One object: ``position`` is its bottom centre in the world frame (m).

    ``joint_states`` holds the positions of an articulated object's joints (the asset's
    ``meta.json: articulation.joints``) by joint name: radians for a hinge, metres for a slide,
    0 = closed; a joint left out is closed. ``task_joint`` names the joint the task acts on (a
    key of ``joint_states``), ``None`` when the task acts on no joint.
    """

    id: str
    room_id: str
    category: str
    position: Vec3
    dimensions: Size3
    rotation: Euler = field(default_factory=Euler)
    description: str = ""
    placement: Placement = field(default_factory=Placement)
    asset: AssetRef | None = None
    physics: Physics = field(default_factory=Physics)
    appearance: Appearance = field(default_factory=Appearance)
    license: str = ""
    task_role: str | None = None
    joint_states: dict[str, float] = field(default_factory=dict)
    task_joint: str | None = None
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def is_static(self) -> bool:
        """Wall-mounted objects and objects marked static do not move in simulation."""
        return self.physics.static or self.placement.kind == "wall"


@dataclass
class Task:
    """The manipulation task a scene is made for; objects carry their ``task_role``."""

    kind: str = "pick_place"
    instruction: str = ""


@dataclass
class Scene:
    """A whole scene: rooms, objects, and where it came from."""

    id: str
    rooms: list[Room]
    objects: list[SceneObject] = field(default_factory=list)
    description: str = ""
    source: str = "text"
    seed: int | None = None
    task: Task | None = None
    building_style: str = ""
    total_area: float | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    schema_version: int = SCHEMA_VERSION

    def room(self, room_id: str) -> Room:
        """The room with id ``room_id``; raises ``KeyError`` if none."""
        for r in self.rooms:
            if r.id == room_id:
                return r
        raise KeyError(room_id)

    def object(self, object_id: str) -> SceneObject:
        """The object with id ``object_id``; raises ``KeyError`` if none."""
        for o in self.objects:
            if o.id == object_id:
                return o
        raise KeyError(object_id)

    def with_dependents(self, ids: set[str]) -> set[str]:
        """``ids`` and every object standing on them, directly or not."""
        out = set(ids)
        grew = True
        while grew:
            grew = False
            for o in self.objects:
                if o.id not in out and o.placement.support_id in out:
                    out.add(o.id)
                    grew = True
        return out

    def bounds_xy(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of all rooms' footprints (m, world frame)."""
        xs0 = [r.position.x for r in self.rooms]
        ys0 = [r.position.y for r in self.rooms]
        xs1 = [r.position.x + r.dimensions.width for r in self.rooms]
        ys1 = [r.position.y + r.dimensions.length for r in self.rooms]
        return (min(xs0), min(ys0), max(xs1), max(ys1))


# --------------------------------------------------------------------------------------------
# Generic dict <-> dataclass conversion (strict: unknown keys and wrong types are errors)


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    if origin is typing.Union or origin is types.UnionType:
        args = typing.get_args(tp)
        if value is None:
            if type(None) in args:
                return None
            raise SchemaError(f"{where}: must not be null")
        inner = [a for a in args if a is not type(None)]
        return _convert(inner[0], value, where)
    if origin is Literal:
        allowed = typing.get_args(tp)
        if value not in allowed:
            raise SchemaError(f"{where}: {value!r} is not one of {list(allowed)}")
        return value
    if origin is list:
        if not isinstance(value, list):
            raise SchemaError(f"{where}: expected a list, got {type(value).__name__}")
        (item_tp,) = typing.get_args(tp)
        return [_convert(item_tp, v, f"{where}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, dict):
            raise SchemaError(f"{where}: expected an object, got {type(value).__name__}")
        return dict(value)
    if tp is Any:
        return value
    if dataclasses.is_dataclass(tp):
        return _from_dict(tp, value, where)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SchemaError(f"{where}: expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise SchemaError(f"{where}: must be finite, got {value}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SchemaError(f"{where}: expected an integer, got {value!r}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise SchemaError(f"{where}: expected true/false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise SchemaError(f"{where}: expected a string, got {value!r}")
        return value
    raise TypeError(f"unsupported schema type {_type_name(tp)} at {where}")  # pragma: no cover


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _check_version(data: Any, document: str, kind: str, expected: int, remedy: str) -> None:
    """Raises unless ``data`` is a dict whose ``schema_version`` is ``expected``.

    Args:
        document: what ``data`` is, for the type error (``"scene JSON"``).
        kind: what the version belongs to (``"scene"``).
        remedy: what to do about another version.
    """
    if not isinstance(data, dict):
        raise SchemaError(f"{document} must be an object, got {type(data).__name__}")
    version = data.get("schema_version")
    if version != expected:
        raise SchemaVersionError(
            f"{kind} schema_version is {version!r}, this factory reads {expected}: {remedy}"
        )


def _from_dict(cls: Any, data: Any, where: str) -> Any:
    if not isinstance(data, dict):
        raise SchemaError(f"{where}: expected an object, got {type(data).__name__}")
    hints = _hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise SchemaError(
            f"{where}: unknown key(s) {unknown} for {cls.__name__}; allowed: {sorted(names)}"
        )
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name in data:
            kwargs[f.name] = _convert(hints[f.name], data[f.name], f"{where}.{f.name}")
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise SchemaError(f"{where}: missing required key {f.name!r}")
    return cls(**kwargs)


def to_dict(obj: Any) -> dict[str, Any]:
    """A dataclass artifact as a JSON-ready dict (field order kept)."""
    return dataclasses.asdict(obj)


# --------------------------------------------------------------------------------------------
# Validation


def _positive(value: float, where: str) -> None:
    if not (value > 0.0):
        raise SchemaError(f"{where} must be > 0, got {value}")


def _check_joints(obj: SceneObject, where: str) -> None:
    """Checks an object's ``joint_states`` and ``task_joint`` (``where`` names the object)."""
    if not isinstance(obj.joint_states, dict):
        raise SchemaError(f"{where}: joint_states must be an object {{joint name: value}}")
    for name, value in obj.joint_states.items():
        check_id(name, f"{where}: joint_states key")
        if name in RESERVED_JOINT_NAMES:
            raise SchemaError(
                f"{where}: joint_states key {name!r} is reserved (reserved: "
                f"{list(RESERVED_JOINT_NAMES)}): name the asset's joints"
            )
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SchemaError(
                f"{where}: joint_states[{name!r}] must be a number (rad or m), got {value!r}"
            )
        if not math.isfinite(value):
            raise SchemaError(f"{where}: joint_states[{name!r}] must be finite, got {value}")
    if obj.task_joint is not None and obj.task_joint not in obj.joint_states:
        raise SchemaError(
            f"{where}: task_joint {obj.task_joint!r} is not a key of joint_states (allowed: "
            f"{sorted(obj.joint_states)}): list the joint in joint_states (0 = closed)"
        )


def validate(scene: Scene) -> Scene:
    """Checks a scene's internal consistency.

    Checks: ``schema_version``, safe ids, unique ids, positive dimensions, walls/doors/windows
    refer to existing walls, every object's centre lies inside some room (within
    :data:`ROOM_TOLERANCE`), every ``room_id`` and
    ``support_id`` exists, ``on_top`` supports form no cycle, ``joint_states`` names are safe
    ids (not :data:`RESERVED_JOINT_NAMES`) with finite values, and ``task_joint`` is one of them.
    (Whether the joints are the asset's and the values within their ranges is checked by the
    compiler, which reads the assets.)

    Returns:
        the scene, unchanged.

    Raises:
        SchemaVersionError: wrong ``schema_version``.
        SchemaError: any other violation; the message names the offending item.
    """
    if scene.schema_version != SCHEMA_VERSION:
        raise SchemaVersionError(
            f"scene schema_version is {scene.schema_version}, this factory reads "
            f"{SCHEMA_VERSION}: regenerate the scene or use a matching factory version"
        )
    check_id(scene.id, "scene id")
    if not scene.source or not scene.source.startswith(SOURCES_PREFIXES):
        raise SchemaError(
            f"scene {scene.id!r}: source {scene.source!r} must start with one of "
            f"{list(SOURCES_PREFIXES)}"
        )
    if not scene.rooms:
        raise SchemaError(f"scene {scene.id!r} has no rooms: a scene needs at least one room")

    room_ids: set[str] = set()
    wall_ids: dict[str, str] = {}
    for i, room in enumerate(scene.rooms):
        where = f"scene {scene.id!r}: rooms[{i}] {room.id!r}"
        check_id(room.id, f"{where}: room id")
        if room.id in room_ids:
            raise SchemaError(f"{where}: duplicate room id")
        room_ids.add(room.id)
        for name, value in zip(
            ("width", "length", "height"), room.dimensions.as_tuple(), strict=True
        ):
            _positive(value, f"{where}: dimensions.{name}")
        _positive(room.ceiling_height, f"{where}: ceiling_height")
        local_walls: dict[str, Wall] = {}
        for j, wall in enumerate(room.walls):
            wwhere = f"{where}: walls[{j}] {wall.id!r}"
            check_id(wall.id, f"{wwhere}: wall id")
            if wall.id in wall_ids and wall_ids[wall.id] == room.id:
                raise SchemaError(f"{wwhere}: duplicate wall id")
            wall_ids[wall.id] = room.id
            local_walls[wall.id] = wall
            _positive(wall.height, f"{wwhere}: height")
            _positive(wall.thickness, f"{wwhere}: thickness")
            _positive(wall.length, f"{wwhere}: length (start and end coincide)")
        openings: list[Door | Window] = [*room.doors, *room.windows]
        for op in openings:
            kind = "door" if isinstance(op, Door) else "window"
            owhere = f"{where}: {kind} {op.id!r}"
            check_id(op.id, f"{owhere}: id")
            if op.wall_id not in local_walls:
                raise SchemaError(
                    f"{owhere}: wall_id {op.wall_id!r} is not a wall of this room "
                    f"(walls: {sorted(local_walls)})"
                )
            if not 0.0 <= op.position_on_wall <= 1.0:
                raise SchemaError(
                    f"{owhere}: position_on_wall must be in [0, 1], got {op.position_on_wall}"
                )
            _positive(op.width, f"{owhere}: width")
            _positive(op.height, f"{owhere}: height")
            if isinstance(op, Window) and op.sill_height < 0:
                raise SchemaError(f"{owhere}: sill_height must be >= 0, got {op.sill_height}")

    object_ids: set[str] = set()
    for obj in scene.objects:
        check_id(obj.id, f"scene {scene.id!r}: object id")
        if obj.id in object_ids:
            raise SchemaError(f"scene {scene.id!r}: duplicate object id {obj.id!r}")
        object_ids.add(obj.id)

    supports: dict[str, str] = {}
    for i, obj in enumerate(scene.objects):
        where = f"scene {scene.id!r}: objects[{i}] {obj.id!r}"
        for name, value in zip(
            ("width", "length", "height"), obj.dimensions.as_tuple(), strict=True
        ):
            _positive(value, f"{where}: dimensions.{name}")
        _positive(obj.physics.mass, f"{where}: physics.mass")
        if obj.physics.friction < 0:
            raise SchemaError(f"{where}: physics.friction must be >= 0")
        if obj.room_id not in room_ids:
            raise SchemaError(
                f"{where}: room_id {obj.room_id!r} does not exist (rooms: {sorted(room_ids)})"
            )
        x, y = obj.position.x, obj.position.y
        if not any(r.contains_xy(x, y, ROOM_TOLERANCE) for r in scene.rooms):
            r = scene.room(obj.room_id)
            raise SchemaError(
                f"{where}: position ({x:.3f}, {y:.3f}) lies outside every room (its room "
                f"{r.id!r} spans x {r.position.x:.3f}..{r.position.x + r.dimensions.width:.3f},"
                f" y {r.position.y:.3f}..{r.position.y + r.dimensions.length:.3f}): move it"
                " inside a room"
            )
        sup = obj.placement.support_id
        kind = obj.placement.kind
        if kind == "on_top":
            if sup is None or sup not in object_ids or sup == obj.id:
                raise SchemaError(
                    f"{where}: placement on_top needs support_id naming another object; "
                    f"{sup!r} does not exist"
                )
            supports[obj.id] = sup
        elif kind == "wall":
            if sup is not None and sup != "wall" and sup not in wall_ids:
                raise SchemaError(f"{where}: support_id {sup!r} is not a wall id")
        elif sup is not None and sup != "floor" and sup not in room_ids:
            raise SchemaError(f"{where}: support_id {sup!r} is not a room id (floor placement)")
        if obj.appearance.rgba is not None and (
            len(obj.appearance.rgba) != 4 or not all(0 <= c <= 1 for c in obj.appearance.rgba)
        ):
            raise SchemaError(f"{where}: appearance.rgba must be 4 numbers in [0, 1]")
        _check_joints(obj, where)

    for start in supports:
        seen = {start}
        cur = supports.get(start)
        while cur is not None:
            if cur in seen:
                raise SchemaError(f"scene {scene.id!r}: on_top supports form a cycle at {cur!r}")
            seen.add(cur)
            cur = supports.get(cur)
    return scene


# --------------------------------------------------------------------------------------------
# JSON I/O


def scene_from_dict(data: Any) -> Scene:
    """Builds and validates a :class:`Scene` from its JSON dict.

    A dict of an older ``schema_version`` is upgraded first
    (:func:`factory.schema.migrate.upgrade`).

    Raises:
        SchemaVersionError: missing or unsupported ``schema_version``.
        SchemaError: malformed or inconsistent content.
    """
    data = upgrade(data)
    _check_version(
        data,
        "scene JSON",
        "scene",
        SCHEMA_VERSION,
        "regenerate the scene or use a matching factory version",
    )
    scene: Scene = _from_dict(Scene, data, "scene")
    return validate(scene)


def scene_to_json(scene: Scene) -> str:
    """The scene as canonical JSON text (2-space indent, trailing newline)."""
    return json.dumps(to_dict(scene), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def scene_from_json(text: str, origin: str = "scene JSON") -> Scene:
    """Parses and validates scene JSON text; ``origin`` names it in error messages."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise SchemaError(
            f"{origin} is not valid JSON (line {e.lineno}, column {e.colno}: {e.msg}); "
            "the file is truncated or corrupt"
        ) from None
    try:
        return scene_from_dict(data)
    except SchemaError as e:
        raise type(e)(f"{origin}: {e}") from None


def load_scene(path: str | Path) -> Scene:
    """Reads and validates ``scene.json``."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SchemaError(f"scene file {p} does not exist") from None
    except UnicodeDecodeError:
        raise SchemaError(f"scene file {p} is not UTF-8 text") from None
    return scene_from_json(text, origin=str(p))
