"""The procedural category registry: what each category is, its sizes, materials and mass.

The catalogue is data: ``factory/data/catalog/categories_*.yaml`` (read in file-name order),
one entry per category. ``CATEGORIES`` (category name -> :class:`Category`) is built from it
when this module is imported, through :data:`TEMPLATE_KINDS` (template kind -> builder).
``dims`` are typical extents (width x, length y, height z; m), ``mass`` the documented
plausible range (kg) that generated assets fall in, ``placement`` where such an object usually
goes, ``rooms`` the room types that hold it (the keys of ``factory/data/rooms/room_types.yaml``,
the room programs' file: one list of room types for both floors), ``synonyms`` words that
name it, ``fill`` the solid fraction of the shape's volume (a box standing in for a hollow
appliance, a frame or a cushion is mostly air; calibrated so that the typical size falls
inside the documented mass range), ``articulation`` the joint physics per front role of an
articulated template (:func:`.articulation.parse_physics`).

A bad entry raises :class:`CatalogError`, naming the category, the field and the valid
choices.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from factory.assets import appliances, cabinets, grammar
from factory.assets import templates as T
from factory.assets.articulation import JointPhysics, parse_physics
from factory.assets.errors import CatalogError as CatalogError
from factory.assets.physics import MATERIALS

RGBA = tuple[float, float, float, float]

DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "catalog"
"""The catalogue's data files (inside the package)."""

PLACEMENTS = ("floor", "wall", "on_top")
GROUPS = ("furniture", "appliance", "electronics", "decor", "manipulable")
FIELDS = (
    "template",
    "dims",
    "materials",
    "mass",
    "placement",
    "rooms",
    "synonyms",
    "colors",
    "group",
    "fill",
    "extra",
    "description",
    "articulation",
    "fixed",
    "articulated_as",
)
REQUIRED = ("template", "dims", "materials", "mass")


@dataclass(frozen=True)
class Category:
    """One procedural category (``articulated``: its template has moving links;
    ``articulation``: joint physics per role, over ``articulation.JOINT_DEFAULTS``;
    ``fixed``: fixed to the floor or wall in simulation, as built-in furniture is, so that
    pulling its doors and drawers does not move it; ``articulated_as``: the articulated
    category that stands for this rigid one where assets are built articulated, e.g. a
    refrigerator's ``upright_fridge``)."""

    template: T.Template
    dims: tuple[float, float, float]
    materials: tuple[str, str]
    mass: tuple[float, float]
    placement: str = "floor"
    rooms: tuple[str, ...] = ()
    synonyms: tuple[str, ...] = ()
    colors: tuple[RGBA, RGBA] | None = None
    group: str = "furniture"
    fill: float = 1.0
    extra: dict[str, str] = field(default_factory=dict)
    description: str = ""
    articulated: bool = False
    articulation: dict[str, JointPhysics] = field(default_factory=dict)
    fixed: bool = False
    articulated_as: str = ""


@dataclass(frozen=True)
class TemplateKind:
    """A template kind of the data: its builder and parameters.

    Attributes:
        build: the template itself (no parameters) or a factory called with the parameters.
        params: parameter name -> type (``number``, ``bool``, ``int_pair`` or ``any``, which
            the factory validates); empty for a plain template.
        required: the parameters that must be given.
        articulated: its shapes have moving links (``Shape.joints``).
    """

    build: Callable[..., Any]
    params: Mapping[str, str] = field(default_factory=dict)
    required: tuple[str, ...] = ()
    articulated: bool = False


TEMPLATE_KINDS: dict[str, TemplateKind] = {
    "table": TemplateKind(T.table),
    "desk": TemplateKind(T.desk),
    "chair": TemplateKind(T.chair),
    "stool": TemplateKind(T.stool),
    "sofa": TemplateKind(T.sofa),
    "bed": TemplateKind(T.bed),
    "pillow": TemplateKind(T.pillow),
    "case": TemplateKind(
        T.case,
        {"boards": "int_pair", "open_front": "bool", "open_top": "bool"},
        ("boards", "open_front"),
    ),
    "basin": TemplateKind(T.basin, {"depth_ratio": "number"}, ("depth_ratio",)),
    "vessel": TemplateKind(
        T.vessel,
        {"r_ratio": "number", "wall": "number", "handle": "bool", "lid": "bool"},
        ("r_ratio", "wall"),
    ),
    "block": TemplateKind(T.block, {"fill": "number"}),
    "fruit": TemplateKind(T.fruit, {"elong": "number"}),
    "refrigerator": TemplateKind(T.refrigerator),
    "oven": TemplateKind(T.oven),
    "dishwasher": TemplateKind(T.dishwasher),
    "washing_machine": TemplateKind(T.washing_machine),
    "microwave": TemplateKind(T.microwave),
    "appliance": TemplateKind(T.appliance),
    "screen": TemplateKind(T.screen),
    "laptop": TemplateKind(T.laptop),
    "panel": TemplateKind(T.panel),
    "clock": TemplateKind(T.clock),
    "lamp": TemplateKind(T.lamp),
    "plant": TemplateKind(T.plant),
    "curtain": TemplateKind(T.curtain),
    "rack": TemplateKind(T.rack),
    "book": TemplateKind(T.book),
    "plate": TemplateKind(T.plate),
    "bottle": TemplateKind(T.bottle),
    "can": TemplateKind(T.can),
    "banana": TemplateKind(T.banana),
    "ball": TemplateKind(T.ball),
    "teddy": TemplateKind(T.teddy),
    "dumbbell": TemplateKind(T.dumbbell),
    "piano": TemplateKind(T.piano),
    "toilet": TemplateKind(T.toilet),
    "cabinet": TemplateKind(
        cabinets.cabinet,
        {
            "handles": "any",
            "drawer_share": "number",
            "drawers": "any",
            "doors": "any",
            "hinge": "any",
            "shelves": "any",
            "rail": "bool",
            "glazed": "bool",
        },
        articulated=True,
    ),
    "hinged_fridge": TemplateKind(
        appliances.hinged_fridge, {"handles": "any", "hinge": "any"}, articulated=True
    ),
    "hinged_microwave": TemplateKind(
        appliances.hinged_microwave, {"handles": "any"}, articulated=True
    ),
    "hinged_washer": TemplateKind(
        appliances.hinged_washer, {"handles": "any", "hinge": "any"}, articulated=True
    ),
    "parts": TemplateKind(grammar.parts, {"parts": "any", "containers": "any"}, ("parts",)),
}
"""Template kind (the data's ``template: {kind: ...}``) -> builder and parameters."""


def _fail(name: str, fld: str, why: str) -> CatalogError:
    return CatalogError(f"catalogue entry {name!r}, field {fld!r}: {why}")


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _numbers(name: str, fld: str, value: Any, n: int) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n or not all(map(_is_number, value)):
        raise _fail(name, fld, f"expected a list of {n} numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _strings(name: str, fld: str, value: Any) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) and v for v in value):
        raise _fail(name, fld, f"expected a list of non-empty strings, got {value!r}")
    return tuple(value)


def _choice(name: str, fld: str, value: Any, choices: tuple[str, ...] | list[str]) -> str:
    if value not in choices:
        raise _fail(name, fld, f"{value!r} is not one of: {', '.join(choices)}")
    return str(value)


def _param(name: str, fld: str, value: Any, kind: str) -> Any:
    if kind == "number" and _is_number(value):
        return float(value)
    if kind == "bool" and isinstance(value, bool):
        return value
    if kind == "int_pair" and (
        isinstance(value, list | tuple)
        and len(value) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
    ):
        return (int(value[0]), int(value[1]))
    if kind == "any":
        return value
    raise _fail(name, fld, f"expected a {kind.replace('_', ' ')}, got {value!r}")


def build_template(name: str, spec: Any) -> T.Template:
    """The template an entry's ``template`` field names, built with its parameters.

    Raises:
        CatalogError: unknown kind, unknown or missing parameter, bad value.
    """
    if not isinstance(spec, Mapping) or "kind" not in spec:
        raise _fail(name, "template", f"expected a mapping with a 'kind', got {spec!r}")
    kind = _choice(name, "template.kind", spec["kind"], sorted(TEMPLATE_KINDS))
    tk = TEMPLATE_KINDS[kind]
    params = {k: v for k, v in spec.items() if k != "kind"}
    for key in params:
        if key not in tk.params:
            valid = ", ".join(tk.params) or "none"
            raise _fail(
                name, f"template.{key}", f"unknown parameter of {kind!r}; valid parameters: {valid}"
            )
    for key in tk.required:
        if key not in params:
            raise _fail(
                name, f"template.{key}", f"missing: {kind!r} needs {', '.join(tk.required)}"
            )
    if not tk.params:
        return tk.build
    args = {k: _param(name, f"template.{k}", v, tk.params[k]) for k, v in params.items()}
    try:
        return tk.build(**args)
    except grammar.GrammarError as e:
        fld, _, why = str(e).partition(": ")
        raise _fail(name, f"template.{fld}", why) from None


def build_category(name: str, entry: Any, room_types: tuple[str, ...] = ()) -> Category:
    """One :class:`Category` from its data entry (a mapping of :data:`FIELDS`).

    Args:
        name: the category name (snake_case).
        entry: the entry's fields.
        room_types: the valid room types (empty: any).

    Raises:
        CatalogError: naming the category, the field and the valid choices.
    """
    if not isinstance(name, str) or not name.replace("_", "").isalnum() or name != name.lower():
        raise _fail(str(name), "name", "expected a lower-case snake_case name")
    if not isinstance(entry, Mapping):
        raise _fail(name, "entry", f"expected a mapping of fields, got {entry!r}")
    for key in entry:
        if key not in FIELDS:
            raise _fail(name, str(key), f"unknown field; valid fields: {', '.join(FIELDS)}")
    for key in REQUIRED:
        if key not in entry:
            raise _fail(name, key, f"missing; required fields: {', '.join(REQUIRED)}")
    dims = _numbers(name, "dims", entry["dims"], 3)
    if min(dims) <= 0:
        raise _fail(name, "dims", f"extents must be positive (m), got {dims}")
    mats = _strings(name, "materials", entry["materials"])
    if len(mats) != 2:
        raise _fail(name, "materials", f"expected [primary, secondary], got {list(mats)}")
    for m in mats:
        _choice(name, "materials", m, list(MATERIALS))
    lo, hi = _numbers(name, "mass", entry["mass"], 2)
    if not 0 < lo < hi:
        raise _fail(name, "mass", f"expected [lo, hi] with 0 < lo < hi (kg), got {[lo, hi]}")
    rooms = _strings(name, "rooms", entry.get("rooms", []))
    if room_types:
        for r in rooms:
            _choice(name, "rooms", r, room_types)
    colors = None
    if entry.get("colors") is not None:
        raw = entry["colors"]
        if not isinstance(raw, list | tuple) or len(raw) != 2:
            raise _fail(name, "colors", f"expected two [r, g, b, a] colours, got {raw!r}")
        c0, c1 = (_numbers(name, "colors", c, 4) for c in raw)
        if not all(0 <= v <= 1 for v in c0 + c1):
            raise _fail(name, "colors", "colour channels must be within 0..1")
        colors = (c0, c1)
    fill = entry.get("fill", 1.0)
    if not _is_number(fill) or fill <= 0:
        raise _fail(name, "fill", f"expected a positive number, got {fill!r}")
    extra = entry.get("extra", {})
    if not isinstance(extra, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in extra.items()
    ):
        raise _fail(name, "extra", "expected a mapping of strings to strings")
    description = entry.get("description", "")
    if not isinstance(description, str):
        raise _fail(name, "description", "expected a string")
    fixed = entry.get("fixed", False)
    if not isinstance(fixed, bool):
        raise _fail(name, "fixed", f"expected true or false, got {fixed!r}")
    articulated_as = entry.get("articulated_as", "")
    if not isinstance(articulated_as, str):
        raise _fail(name, "articulated_as", f"expected a category name, got {articulated_as!r}")
    return Category(
        template=build_template(name, entry["template"]),
        dims=(dims[0], dims[1], dims[2]),
        materials=(mats[0], mats[1]),
        mass=(lo, hi),
        placement=_choice(name, "placement", entry.get("placement", "floor"), PLACEMENTS),
        rooms=rooms,
        synonyms=_strings(name, "synonyms", entry.get("synonyms", [])),
        colors=colors,  # type: ignore[arg-type]
        group=_choice(name, "group", entry.get("group", "furniture"), GROUPS),
        fill=float(fill),
        extra=dict(extra),
        description=description,
        articulated=TEMPLATE_KINDS[entry["template"]["kind"]].articulated,
        articulation=parse_physics(name, entry.get("articulation"))
        if "articulation" in entry or TEMPLATE_KINDS[entry["template"]["kind"]].articulated
        else {},
        fixed=fixed,
        articulated_as=articulated_as,
    )


def read_yaml(path: Path) -> Any:
    """A data file (YAML, safe loader) of the catalogue or the room programs.

    Raises:
        CatalogError: the file is not valid YAML.
    """
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        return yaml.load(path.read_text(encoding="utf-8"), Loader=loader)
    except yaml.YAMLError as e:
        raise CatalogError(f"catalogue file {path.name}: not valid YAML ({e})") from None


ROOMS_FILE = DATA_DIR.parent / "rooms" / "room_types.yaml"
"""The room programs' data file (read by :mod:`factory.scenes.rooms`): its keys are the room
types a category may name."""


def load_catalog(folder: Path = DATA_DIR, rooms_file: Path = ROOMS_FILE) -> dict[str, Category]:
    """Every category of the catalogue's data files, in file then entry order.

    Raises:
        CatalogError: a bad entry, a file that is not a mapping, or a name defined twice.
    """
    rooms_doc = read_yaml(rooms_file)
    if not isinstance(rooms_doc, Mapping) or not rooms_doc:
        raise CatalogError(f"room types file {rooms_file.name}: expected a mapping of room types")
    room_types = tuple(str(r) for r in rooms_doc)
    out: dict[str, Category] = {}
    for path in sorted(folder.glob("categories_*.yaml")):
        doc = read_yaml(path)
        if not isinstance(doc, Mapping):
            raise CatalogError(f"catalogue file {path.name}: expected a mapping of categories")
        for name, entry in doc.items():
            if name in out:
                raise _fail(str(name), "name", f"defined twice (again in {path.name})")
            out[name] = build_category(name, entry, room_types)
    moving = sorted(n for n, c in out.items() if c.articulated)
    for name, cat in out.items():
        if cat.articulated_as and cat.articulated_as not in moving:
            raise _fail(
                name,
                "articulated_as",
                f"{cat.articulated_as!r} is not an articulated category (articulated: "
                f"{', '.join(moving)})",
            )
    return out


CATEGORIES: dict[str, Category] = load_catalog()
