"""Lossless conversion between SAGE's layout JSON and our :class:`~factory.schema.scene.Scene`.

SAGE's layout file (``<layout_id>.json``) is a ``FloorPlan``: ``id, rooms, total_area,
building_style, description, created_from_text, policy_analysis``; each room holds its
``walls, doors, objects, windows``. Points are ``{x, y, z}``, sizes ``{width, length, height}``.
An object's ``place_id`` is ``"floor"`` or a room id (floor), ``"wall"`` or a wall id (wall
mounted, static), or another object's id (on top). ``rotation`` is Euler x, y, z in degrees
(``R = Rz @ Ry @ Rx``); ``position`` is the object's bottom centre.

A *packed* SAGE scene is a folder (or zip) with the layout JSON, ``objects/<source_id>.ply``
(+ ``objects/<source_id>_texture.png``) and optionally ``materials/``.

Import keeps every field: the ones we understand map onto our schema, any others go to
``extras["sage"]`` of the matching item and are written back on export, so
``scene_to_sage(sage_to_scene(d)) == d`` for every layout SAGE itself writes.
"""

from __future__ import annotations

import json
import shutil
import stat
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from factory.schema.errors import SchemaError, UnsafePathError
from factory.schema.scene import (
    Appearance,
    AssetRef,
    Door,
    Euler,
    Physics,
    Placement,
    Room,
    Scene,
    SceneObject,
    Size3,
    Vec3,
    Wall,
    Window,
    check_id,
    validate,
)

SAGE_SOURCE = "sage10k"

_FLOORPLAN_KEYS = (
    "id",
    "rooms",
    "total_area",
    "building_style",
    "description",
    "created_from_text",
    "policy_analysis",
)
_ROOM_KEYS = (
    "id",
    "room_type",
    "position",
    "dimensions",
    "walls",
    "doors",
    "objects",
    "windows",
    "floor_material",
    "ceiling_height",
)
_WALL_KEYS = ("id", "start_point", "end_point", "height", "thickness", "material")
_DOOR_KEYS = (
    "id",
    "wall_id",
    "position_on_wall",
    "width",
    "height",
    "door_type",
    "opens_inward",
    "opening",
    "door_material",
)
_WINDOW_KEYS = (
    "id",
    "wall_id",
    "position_on_wall",
    "width",
    "height",
    "sill_height",
    "window_type",
    "window_material",
)
_OBJECT_KEYS = (
    "id",
    "room_id",
    "type",
    "description",
    "position",
    "rotation",
    "dimensions",
    "source",
    "source_id",
    "place_id",
    "place_location",
    "place_guidance",
    "placement_constraints",
    "mass",
)
_OPTIONAL_OBJECT_KEYS = ("metallic", "roughness")


# --------------------------------------------------------------------------------------------
# Small readers with clear errors


def _req(d: dict[str, Any], key: str, where: str) -> Any:
    if key not in d:
        raise SchemaError(f"SAGE layout: {where} is missing {key!r}")
    return d[key]


def _num(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SchemaError(f"SAGE layout: {where} must be a number, got {value!r}")
    return float(value)


def _point(d: Any, where: str) -> Vec3:
    if not isinstance(d, dict):
        raise SchemaError(f"SAGE layout: {where} must be an object {{x, y, z}}, got {d!r}")
    return Vec3(
        _num(_req(d, "x", where), f"{where}.x"),
        _num(_req(d, "y", where), f"{where}.y"),
        _num(d.get("z", 0.0), f"{where}.z"),
    )


def _euler(d: Any, where: str) -> Euler:
    if not isinstance(d, dict):
        raise SchemaError(f"SAGE layout: {where} must be an object {{x, y, z}}, got {d!r}")
    return Euler(*(_num(d.get(k, 0.0), f"{where}.{k}") for k in ("x", "y", "z")))


def _size(d: Any, where: str) -> Size3:
    if not isinstance(d, dict):
        raise SchemaError(f"SAGE layout: {where} must be {{width, length, height}}, got {d!r}")
    return Size3(*(_num(_req(d, k, where), f"{where}.{k}") for k in ("width", "length", "height")))


def _extras(d: dict[str, Any], known: tuple[str, ...]) -> dict[str, Any]:
    rest = {k: v for k, v in d.items() if k not in known}
    return {"sage": rest} if rest else {}


def _list(d: dict[str, Any], key: str, where: str) -> list[Any]:
    value = d.get(key, [])
    if not isinstance(value, list):
        raise SchemaError(f"SAGE layout: {where}.{key} must be a list")
    return value


def _dict(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SchemaError(f"SAGE layout: {where} must be an object, got {type(value).__name__}")
    return value


# --------------------------------------------------------------------------------------------
# SAGE -> Scene


def sage_to_scene(layout: Any) -> Scene:
    """Converts a SAGE layout dict into a validated :class:`Scene`.

    Args:
        layout: the parsed ``<layout_id>.json``.

    Returns:
        the scene, with ``source == "sage10k"``; objects keep SAGE's ``source``/``source_id`` in
        :class:`AssetRef` (``backend == "sage"``, ``asset_id`` empty until meshes are imported).

    Raises:
        SchemaError: the layout is malformed (the message names the item and field).
    """
    layout = _dict(layout, "the layout")
    scene_id = check_id(str(_req(layout, "id", "the layout")), "SAGE layout id")
    rooms_raw = _list(layout, "rooms", "the layout")
    rooms: list[Room] = []
    objects: list[SceneObject] = []
    wall_ids: set[Any] = set()
    room_ids = {r.get("id") for r in rooms_raw if isinstance(r, dict)}
    for r in rooms_raw:
        for w in _list(_dict(r, "a room"), "walls", "a room"):
            if isinstance(w, dict):
                wall_ids.add(w.get("id"))
    for i, r in enumerate(rooms_raw):
        rw = f"rooms[{i}]"
        walls = [
            Wall(
                id=str(_req(w, "id", f"{rw}.walls[{j}]")),
                start=_point(_req(w, "start_point", f"{rw}.walls[{j}]"), f"{rw}.walls[{j}].start"),
                end=_point(_req(w, "end_point", f"{rw}.walls[{j}]"), f"{rw}.walls[{j}].end"),
                height=_num(_req(w, "height", f"{rw}.walls[{j}]"), f"{rw}.walls[{j}].height"),
                thickness=_num(w.get("thickness", 0.1), f"{rw}.walls[{j}].thickness"),
                material=str(w.get("material", "drywall")),
                extras=_extras(w, _WALL_KEYS),
            )
            for j, w in enumerate(_dict(x, f"{rw}.walls[]") for x in _list(r, "walls", rw))
        ]
        doors = [
            Door(
                id=str(_req(d, "id", f"{rw}.doors[{j}]")),
                wall_id=str(_req(d, "wall_id", f"{rw}.doors[{j}]")),
                position_on_wall=_num(
                    _req(d, "position_on_wall", f"{rw}.doors[{j}]"), f"{rw}.doors[{j}]"
                ),
                width=_num(_req(d, "width", f"{rw}.doors[{j}]"), f"{rw}.doors[{j}].width"),
                height=_num(_req(d, "height", f"{rw}.doors[{j}]"), f"{rw}.doors[{j}].height"),
                door_type=str(d.get("door_type", "standard")),
                opens_inward=bool(d.get("opens_inward", True)),
                opening=bool(d.get("opening", False)),
                material=str(d.get("door_material", "standard")),
                extras=_extras(d, _DOOR_KEYS),
            )
            for j, d in enumerate(_dict(x, f"{rw}.doors[]") for x in _list(r, "doors", rw))
        ]
        windows = [
            Window(
                id=str(_req(d, "id", f"{rw}.windows[{j}]")),
                wall_id=str(_req(d, "wall_id", f"{rw}.windows[{j}]")),
                position_on_wall=_num(
                    _req(d, "position_on_wall", f"{rw}.windows[{j}]"), f"{rw}.windows[{j}]"
                ),
                width=_num(_req(d, "width", f"{rw}.windows[{j}]"), f"{rw}.windows[{j}].width"),
                height=_num(_req(d, "height", f"{rw}.windows[{j}]"), f"{rw}.windows[{j}].height"),
                sill_height=_num(
                    _req(d, "sill_height", f"{rw}.windows[{j}]"), f"{rw}.windows[{j}].sill"
                ),
                window_type=str(d.get("window_type", "standard")),
                material=str(d.get("window_material", "standard")),
                extras=_extras(d, _WINDOW_KEYS),
            )
            for j, d in enumerate(_dict(x, f"{rw}.windows[]") for x in _list(r, "windows", rw))
        ]
        room = Room(
            id=str(_req(r, "id", rw)),
            room_type=str(r.get("room_type", "room")),
            position=_point(_req(r, "position", rw), f"{rw}.position"),
            dimensions=_size(_req(r, "dimensions", rw), f"{rw}.dimensions"),
            walls=walls,
            doors=doors,
            windows=windows,
            floor_material=str(r.get("floor_material", "hardwood")),
            ceiling_height=_num(r.get("ceiling_height", 2.7), f"{rw}.ceiling_height"),
            extras=_extras(r, _ROOM_KEYS),
        )
        rooms.append(room)
        for j, o in enumerate(_list(r, "objects", rw)):
            objects.append(_object(_dict(o, f"{rw}.objects[{j}]"), room.id, room_ids, wall_ids))

    top_extras = {k: layout[k] for k in ("created_from_text", "policy_analysis") if k in layout}
    top_extras.update({k: v for k, v in layout.items() if k not in _FLOORPLAN_KEYS})
    total_area = layout.get("total_area")
    scene = Scene(
        id=scene_id,
        rooms=rooms,
        objects=objects,
        description=str(layout.get("description", "")),
        source=SAGE_SOURCE,
        building_style=str(layout.get("building_style", "")),
        total_area=None if total_area is None else _num(total_area, "total_area"),
        extras={"sage": top_extras} if top_extras else {},
    )
    return validate(scene)


def _object(o: dict[str, Any], room_id: str, room_ids: set[Any], wall_ids: set[Any]) -> SceneObject:
    where = f"object {o.get('id', '?')!r}"
    place_id = str(o.get("place_id", "floor"))
    kind: Any
    if place_id == "floor" or place_id in room_ids:
        kind, support = "floor", (None if place_id == "floor" else place_id)
    elif place_id == "wall" or place_id in wall_ids:
        kind, support = "wall", (None if place_id == "wall" else place_id)
    else:
        kind, support = "on_top", place_id
    appearance = Appearance(
        metallic=None if "metallic" not in o else _num(o["metallic"], f"{where}.metallic"),
        roughness=None if "roughness" not in o else _num(o["roughness"], f"{where}.roughness"),
    )
    constraints = o.get("placement_constraints") or []
    if not isinstance(constraints, list):
        raise SchemaError(f"SAGE layout: {where}.placement_constraints must be a list")
    return SceneObject(
        id=str(_req(o, "id", where)),
        room_id=str(o.get("room_id", room_id)),
        category=str(_req(o, "type", where)),
        description=str(o.get("description", "")),
        position=_point(_req(o, "position", where), f"{where}.position"),
        rotation=_euler(o.get("rotation", {}), f"{where}.rotation"),
        dimensions=_size(_req(o, "dimensions", where), f"{where}.dimensions"),
        placement=Placement(
            kind=kind,
            support_id=support,
            location=str(o.get("place_location", "top")),
            guidance=str(o.get("place_guidance", "Standard placement for the object")),
            constraints=constraints,
        ),
        asset=AssetRef(
            backend="sage",
            source=str(o.get("source", "unknown")),
            source_id=str(o.get("source_id", "")),
        ),
        physics=Physics(mass=_num(o.get("mass", 1.0), f"{where}.mass"), static=kind == "wall"),
        appearance=appearance,
        extras=_extras(o, _OBJECT_KEYS + _OPTIONAL_OBJECT_KEYS),
    )


# --------------------------------------------------------------------------------------------
# Scene -> SAGE


def _p(v: Vec3) -> dict[str, float]:
    return {"x": v.x, "y": v.y, "z": v.z}


def _s(v: Size3) -> dict[str, float]:
    return {"width": v.width, "length": v.length, "height": v.height}


def _sage_extras(extras: dict[str, Any]) -> dict[str, Any]:
    value = extras.get("sage", {})
    return dict(value) if isinstance(value, dict) else {}


def _place_id(obj: SceneObject) -> str:
    if obj.placement.support_id is not None:
        return obj.placement.support_id
    return "wall" if obj.placement.kind == "wall" else "floor"


def scene_to_sage(scene: Scene) -> dict[str, Any]:
    """Converts a scene to SAGE's layout dict (the inverse of :func:`sage_to_scene`).

    Fields SAGE has no place for (friction, rgba, license, task roles, joint states and the
    task joint) are not written: SAGE's format has no joints, so an articulated object is
    written as one rigid object of its closed dimensions
    (``factory.scenes.sage_assets.export_sage`` puts the joint states in a side file).
    """
    rooms = []
    for room in scene.rooms:
        objs = []
        for o in scene.objects:
            if o.room_id != room.id:
                continue
            asset = o.asset or AssetRef(backend="procedural", asset_id="")
            d: dict[str, Any] = {
                "id": o.id,
                "room_id": o.room_id,
                "type": o.category,
                "description": o.description,
                "position": _p(o.position),
                "rotation": {"x": o.rotation.x, "y": o.rotation.y, "z": o.rotation.z},
                "dimensions": _s(o.dimensions),
                "source": asset.source or asset.backend,
                "source_id": asset.source_id or asset.asset_id,
                "place_id": _place_id(o),
                "place_location": o.placement.location,
                "place_guidance": o.placement.guidance,
                "placement_constraints": o.placement.constraints,
                "mass": o.physics.mass,
            }
            if o.appearance.metallic is not None:
                d["metallic"] = o.appearance.metallic
            if o.appearance.roughness is not None:
                d["roughness"] = o.appearance.roughness
            d.update(_sage_extras(o.extras))
            objs.append(d)
        rd: dict[str, Any] = {
            "id": room.id,
            "room_type": room.room_type,
            "position": _p(room.position),
            "dimensions": _s(room.dimensions),
            "walls": [
                {
                    "id": w.id,
                    "start_point": _p(w.start),
                    "end_point": _p(w.end),
                    "height": w.height,
                    "thickness": w.thickness,
                    "material": w.material,
                    **_sage_extras(w.extras),
                }
                for w in room.walls
            ],
            "doors": [
                {
                    "id": d.id,
                    "wall_id": d.wall_id,
                    "position_on_wall": d.position_on_wall,
                    "width": d.width,
                    "height": d.height,
                    "door_type": d.door_type,
                    "opens_inward": d.opens_inward,
                    "opening": d.opening,
                    "door_material": d.material,
                    **_sage_extras(d.extras),
                }
                for d in room.doors
            ],
            "objects": objs,
            "windows": [
                {
                    "id": w.id,
                    "wall_id": w.wall_id,
                    "position_on_wall": w.position_on_wall,
                    "width": w.width,
                    "height": w.height,
                    "sill_height": w.sill_height,
                    "window_type": w.window_type,
                    "window_material": w.material,
                    **_sage_extras(w.extras),
                }
                for w in room.windows
            ],
            "floor_material": room.floor_material,
            "ceiling_height": room.ceiling_height,
            **_sage_extras(room.extras),
        }
        rooms.append(rd)
    extras = _sage_extras(scene.extras)
    total_area = scene.total_area
    if total_area is None:
        total_area = sum(r.dimensions.width * r.dimensions.length for r in scene.rooms)
    out: dict[str, Any] = {
        "id": scene.id,
        "rooms": rooms,
        "total_area": total_area,
        "building_style": scene.building_style,
        "description": scene.description,
        "created_from_text": extras.pop("created_from_text", scene.description),
        "policy_analysis": extras.pop("policy_analysis", {}),
    }
    out.update(extras)
    return out


# --------------------------------------------------------------------------------------------
# Packed scenes (folder or zip)


@dataclass
class SagePackage:
    """A SAGE scene found on disk.

    Attributes:
        layout: the parsed layout JSON.
        layout_path: where it was read.
        meshes: ``source_id -> path of <source_id>.ply``.
        textures: ``source_id -> path of <source_id>_texture.png``.
        root: the package folder (``None`` for a bare layout JSON).
    """

    layout: dict[str, Any]
    layout_path: Path
    meshes: dict[str, Path] = field(default_factory=dict)
    textures: dict[str, Path] = field(default_factory=dict)
    root: Path | None = None


def check_member_name(name: str) -> PurePosixPath:
    """Rejects archive member names that would land outside the extraction folder."""
    p = PurePosixPath(name.replace("\\", "/"))
    if p.is_absolute() or ".." in p.parts or (p.parts and ":" in p.parts[0]):
        raise UnsafePathError(
            f"archive member {name!r} has an unsafe path (absolute or with '..'): refusing to "
            "extract; repack the archive with relative paths"
        )
    return p


def extract_zip(archive: str | Path, dest: str | Path) -> Path:
    """Extracts a SAGE zip safely into ``dest`` (checked before anything is written).

    Raises:
        UnsafePathError: a member has an absolute path, ``..``, or is a symbolic link.
        SchemaError: the file is not a zip archive.
    """
    archive, dest = Path(archive), Path(dest)
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as e:
        raise SchemaError(f"{archive} is not a readable zip archive ({e})") from None
    with zf:
        for info in zf.infolist():
            check_member_name(info.filename)
            if stat.S_ISLNK(info.external_attr >> 16):
                raise UnsafePathError(
                    f"archive member {info.filename!r} is a symbolic link: refusing to extract"
                )
        dest.mkdir(parents=True, exist_ok=True)
        for info in zf.infolist():
            target = dest / check_member_name(info.filename)
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(info) as src, open(target, "wb") as out:
                shutil.copyfileobj(src, out)
    return dest


def _find_layout(folder: Path) -> Path:
    candidates = sorted(
        p for p in folder.rglob("*.json") if p.is_file() and "materials" not in p.parts
    )
    layouts = []
    for p in candidates:
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError):
            continue
        if isinstance(data, dict) and "rooms" in data and "id" in data:
            layouts.append(p)
    if not layouts:
        raise SchemaError(f"{folder}: no SAGE layout JSON (an object with 'id' and 'rooms')")
    if len(layouts) > 1:
        raise SchemaError(
            f"{folder}: several layout JSON files ({[p.name for p in layouts]}); "
            "import them one folder at a time"
        )
    return layouts[0]


def read_layout_json(path: Path) -> dict[str, Any]:
    """Reads a SAGE layout JSON file with a clear error on bad JSON."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise SchemaError(
            f"{path} is not valid JSON (line {e.lineno}, column {e.colno}: {e.msg}); "
            "the file is truncated or corrupt"
        ) from None
    except UnicodeDecodeError:
        raise SchemaError(f"{path} is not UTF-8 text") from None
    return _dict(data, str(path))


def read_package(folder_or_json: str | Path) -> SagePackage:
    """Finds a SAGE layout and its meshes in a folder (already extracted) or a JSON file.

    Mesh files are looked up as ``objects/<source_id>.ply`` next to the layout; a ``source_id``
    with a path in it is refused.
    """
    path = Path(folder_or_json)
    if path.is_dir():
        layout_path, root = _find_layout(path), path
    elif path.is_file():
        layout_path, root = path, path.parent
    else:
        raise SchemaError(f"SAGE input {path} does not exist")
    layout = read_layout_json(layout_path)
    pkg = SagePackage(layout=layout, layout_path=layout_path, root=root)
    objects_dir = layout_path.parent / "objects"
    if not objects_dir.is_dir():
        objects_dir = root / "objects"
    for r in layout.get("rooms", []) if isinstance(layout.get("rooms"), list) else []:
        if not isinstance(r, dict):
            continue
        for o in r.get("objects", []) if isinstance(r.get("objects"), list) else []:
            if not isinstance(o, dict):
                continue
            sid = o.get("source_id")
            if not isinstance(sid, str) or not sid:
                continue
            check_id(sid, f"object {o.get('id')!r} source_id")
            ply = objects_dir / f"{sid}.ply"
            if ply.is_file():
                pkg.meshes[sid] = ply
                tex = objects_dir / f"{sid}_texture.png"
                if tex.is_file():
                    pkg.textures[sid] = tex
    return pkg
