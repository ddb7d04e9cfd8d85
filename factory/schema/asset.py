"""The asset contract: ``assets/<asset_id>/meta.json`` in a run directory.

An asset folder holds a visual mesh (OBJ, in the object frame: z up, centred in x and y, bottom
at z = 0, metres), an optional texture, and the convex collision parts the compiler uses. With
no collision parts listed, MuJoCo collides with the convex hull of the visual mesh.

An articulated asset (``meta.json: articulation``, schema version 2) has moving links: each link
claims some of the asset's ``collision`` and ``visual_parts`` entries by index (whatever no link
claims is the root body) and hangs from its parent by one hinge or slide joint. Every pose in
``meta.json`` (``extents``, meshes, anchors, handles, supports) is the closed pose, all joints at
0; joint anchors, axes and handles are in the object frame.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from factory.schema.errors import SchemaError, SchemaVersionError
from factory.schema.scene import RESERVED_JOINT_NAMES, _from_dict, check_id, to_dict

ASSET_SCHEMA_VERSION = 2
"""Version of ``meta.json`` written now (2 added ``articulation``)."""

READABLE_ASSET_VERSIONS = (1, 2)
"""``meta.json`` versions this factory reads: a version-1 meta reads as version 2 with
``articulation=None``, so an older run's cached assets stay valid (the asset cache rebuilds an
asset whose meta it cannot read)."""

ROOT_LINK = ""
"""The name that stands for an articulated asset's root body (a link's ``parent``; a support's,
container's or visual part's ``link``)."""

JOINT_KINDS: tuple[str, ...] = ("hinge", "slide")
"""Joint types: ``hinge`` (position in rad, about ``axis`` through ``anchor``) and ``slide``
(position in m, along ``axis``)."""

JOINT_ROLES: tuple[str, ...] = ("door", "drawer", "flap", "lid", "seat")
"""What a joint's link is: a side-hinged ``door``, a sliding ``drawer``, a bottom-hinged ``flap``
(oven, dishwasher), a top ``lid`` (chest, laptop, bin) or a ``seat`` (toilet)."""

HANDLE_STYLES: tuple[str, ...] = ("bar", "knob", "pull", "edge")
"""Handle shapes: a ``bar`` on posts, a round ``knob``, a ``pull`` (cup or recessed grip) or a
graspable ``edge`` of the moving panel itself."""

UNIT_TOLERANCE = 1e-6
"""How far from 1 the norm of a direction (joint axis, handle ``along``/``normal``) may be, and
how far from 0 the cosine between a handle's ``along`` and ``normal``."""

JointKind = Literal["hinge", "slide"]
JointRole = Literal["door", "drawer", "flap", "lid", "seat"]
HandleStyle = Literal["bar", "knob", "pull", "edge"]


@dataclass
class HandleMeta:
    """A graspable handle of a link, in its closed pose (object frame).

    Attributes:
        name: unique among the asset's handles.
        style: one of :data:`HANDLE_STYLES`.
        center: the handle's centre (m).
        along: unit direction of its long axis (a knob: any direction across the normal).
        normal: unit direction out of the front it is mounted on (the grasp approaches along
            ``-normal``); perpendicular to ``along``.
        length: extent along ``along`` (m).
        thickness: extent of its grip across ``along`` (m).
        clearance: free space between the grip and the front behind it (m).
        collision: indices into the asset's ``collision`` list of its own pieces (a subset of
            its link's).
    """

    name: str
    style: HandleStyle
    center: list[float]
    along: list[float]
    normal: list[float]
    length: float
    thickness: float
    clearance: float
    collision: list[int] = field(default_factory=list)


@dataclass
class LinkMeta:
    """A moving body of an articulated asset.

    Attributes:
        name: unique among the asset's links (the compiled body is ``<object id>/<name>``).
        parent: :data:`ROOT_LINK` or the name of a link listed before it (links are in tree
            order).
        collision: indices into the asset's ``collision`` list of the pieces it carries.
        visual: indices into the asset's ``visual_parts`` list of the pieces it carries.
        handles: its handles.
    """

    name: str
    parent: str = ROOT_LINK
    collision: list[int] = field(default_factory=list)
    visual: list[int] = field(default_factory=list)
    handles: list[HandleMeta] = field(default_factory=list)


@dataclass
class JointMeta:
    """The joint that moves one link relative to its parent.

    Attributes:
        name: unique among the asset's joints (the compiled joint is ``<object id>/<name>``;
            not one of ``RESERVED_JOINT_NAMES``).
        kind: one of :data:`JOINT_KINDS`.
        role: one of :data:`JOINT_ROLES`.
        link: the link it moves.
        anchor: a point on the joint axis (m, object frame, closed pose).
        axis: unit direction (object frame); a positive position opens the link.
        range: ``[lo, hi]`` limits of the position (rad or m), ``lo <= 0 <= hi``, ``lo < hi``;
            0 is closed.
        damping: N m s/rad or N s/m, at the asset's own mass.
        frictionloss: dry friction (N m or N), at the asset's own mass.
        armature: added inertia (kg m^2 or kg).
        stiffness: spring stiffness (N m/rad or N/m) towards ``springref``.
        springref: the spring's rest position (rad or m).
        rest: intervals ``[a, b]`` inside ``range`` where the link stays put with the other
            joints closed (gravity and spring within the friction, or pushing into a limit,
            and the centre of mass over the footprint).
    """

    name: str
    kind: JointKind
    role: JointRole
    link: str
    anchor: list[float]
    axis: list[float]
    range: list[float]
    damping: float = 0.0
    frictionloss: float = 0.0
    armature: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    rest: list[list[float]] = field(default_factory=list)


@dataclass
class SweptBox:
    """The axis-aligned box (m, object frame) the asset fills over all its joints' ranges."""

    lo: list[float]
    hi: list[float]


@dataclass
class Articulation:
    """The moving parts of an asset: links in tree order, one joint per link, the swept box."""

    links: list[LinkMeta]
    joints: list[JointMeta]
    swept: SweptBox

    def joint(self, name: str) -> JointMeta:
        """The joint named ``name``; raises ``KeyError`` if none."""
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)

    def link(self, name: str) -> LinkMeta:
        """The link named ``name``; raises ``KeyError`` if none."""
        for link in self.links:
            if link.name == name:
                return link
        raise KeyError(name)


@dataclass
class AssetMeta:
    """What an asset folder holds (paths are relative to the folder).

    Attributes:
        asset_id: the folder name (content hash based).
        backend: ``procedural``, ``mesh_library``, ``trellis`` or ``sage``.
        visual: visual mesh file (OBJ).
        texture: texture image (PNG) for the visual mesh's UVs, if any.
        collision: convex collision part files (OBJ); empty means the visual mesh's hull.
        extents: ``(width, length, height)`` of the visual mesh's bounding box (m), closed.
        license: the asset's license (SPDX id or free text).
        provenance: where it came from (source files and their sha256, generator, seed).
        category: what the asset is (``mug``, ``bed`` ...), if known.
        visual_parts: coloured visual pieces ``{file, rgba, metallic, roughness}``; when given,
            they replace ``visual`` in the compiled scene (``visual`` stays the whole mesh).
        supports: upward support surfaces ``{name, z, rect: [x0, y0, x1, y1]}`` (object frame);
            an articulated asset's may add ``link`` (the link carrying it, ``""`` the root) and
            ``access`` (the joint to open first to reach it, ``""`` none).
        containers: interior volumes ``{name, lo: [x, y, z], hi: [x, y, z]}`` (object frame),
            with ``link`` and ``access`` as supports.
        mass: mass (kg) from volume x density, if known.
        friction: sliding friction of the main material, if known.
        materials: the materials used.
        request: the normalised request the asset was made from.
        articulation: the moving links and their joints; ``None``: one rigid body (and every
            version-1 meta).
    """

    asset_id: str
    backend: str
    visual: str
    extents: list[float]
    texture: str | None = None
    collision: list[str] = field(default_factory=list)
    license: str = "unknown"
    provenance: dict[str, Any] = field(default_factory=dict)
    category: str = ""
    visual_parts: list[dict[str, Any]] = field(default_factory=list)
    supports: list[dict[str, Any]] = field(default_factory=list)
    containers: list[dict[str, Any]] = field(default_factory=list)
    mass: float | None = None
    friction: float | None = None
    materials: list[str] = field(default_factory=list)
    request: dict[str, Any] = field(default_factory=dict)
    articulation: Articulation | None = None
    schema_version: int = ASSET_SCHEMA_VERSION

    def __post_init__(self) -> None:
        validate_articulation(self)


# --------------------------------------------------------------------------------------------
# Validation


def _vector(value: list[float], where: str, unit: bool = False) -> None:
    if len(value) != 3:
        raise SchemaError(f"{where} must hold 3 numbers (x, y, z), got {value!r}")
    if unit:
        norm = math.sqrt(sum(v * v for v in value))
        if abs(norm - 1.0) > UNIT_TOLERANCE:
            raise SchemaError(
                f"{where} must be a unit vector (norm 1 within {UNIT_TOLERANCE:g}), got "
                f"{value!r} (norm {norm:.6g})"
            )


def _choice(value: str, allowed: tuple[str, ...], where: str) -> None:
    if value not in allowed:
        raise SchemaError(f"{where} {value!r} is not one of {list(allowed)}")


def _name(value: str, seen: set[str], where: str, what: str) -> None:
    check_id(value, f"{where} name")
    if value in RESERVED_JOINT_NAMES:
        raise SchemaError(
            f"{where} name {value!r} is reserved (reserved: {list(RESERVED_JOINT_NAMES)})"
        )
    if value in seen:
        raise SchemaError(f"{where}: duplicate {what} name {value!r}")
    seen.add(value)


def _indices(values: list[int], size: int, claimed: dict[int, str], owner: str, where: str) -> None:
    for k in values:
        if not 0 <= k < size:
            raise SchemaError(
                f"{where}: index {k} is out of range (the list has {size} entries: 0..{size - 1})"
            )
        if k in claimed:
            raise SchemaError(f"{where}: index {k} is already claimed by {claimed[k]!r}")
        claimed[k] = owner


def _check_handle(h: HandleMeta, link: LinkMeta, seen: set[str], where: str) -> None:
    _name(h.name, seen, where, "handle")
    where = f"{where} {h.name!r}"
    _choice(h.style, HANDLE_STYLES, f"{where}: style")
    _vector(h.center, f"{where}: center")
    _vector(h.along, f"{where}: along", unit=True)
    _vector(h.normal, f"{where}: normal", unit=True)
    cos = sum(a * n for a, n in zip(h.along, h.normal, strict=True))
    if abs(cos) > UNIT_TOLERANCE:
        raise SchemaError(f"{where}: along and normal must be perpendicular (cosine {cos:.3g})")
    for key in ("length", "thickness"):
        if not getattr(h, key) > 0:
            raise SchemaError(f"{where}: {key} must be > 0 (m), got {getattr(h, key)}")
    if not h.clearance >= 0:
        raise SchemaError(f"{where}: clearance must be >= 0 (m), got {h.clearance}")
    extra = sorted(set(h.collision) - set(link.collision))
    if extra:
        raise SchemaError(
            f"{where}: collision indices {extra} are not its link's (allowed: "
            f"{sorted(link.collision)})"
        )


def _check_joint(j: JointMeta, links: list[str], seen: set[str], where: str) -> None:
    _name(j.name, seen, where, "joint")
    where = f"{where} {j.name!r}"
    _choice(j.kind, JOINT_KINDS, f"{where}: kind")
    _choice(j.role, JOINT_ROLES, f"{where}: role")
    if j.link not in links:
        raise SchemaError(f"{where}: link {j.link!r} is not a link of the asset (links: {links})")
    _vector(j.anchor, f"{where}: anchor")
    _vector(j.axis, f"{where}: axis", unit=True)
    unit = "rad" if j.kind == "hinge" else "m"
    if len(j.range) != 2 or not j.range[0] <= 0.0 <= j.range[1] or j.range[0] >= j.range[1]:
        raise SchemaError(
            f"{where}: range must be [lo, hi] ({unit}) with lo <= 0 <= hi and lo < hi (0 is "
            f"closed), got {j.range!r}"
        )
    for key in ("damping", "frictionloss", "armature", "stiffness"):
        if not getattr(j, key) >= 0:
            raise SchemaError(f"{where}: {key} must be >= 0, got {getattr(j, key)}")
    lo, hi = j.range
    for k, interval in enumerate(j.rest):
        if len(interval) != 2 or not lo <= interval[0] <= interval[1] <= hi:
            raise SchemaError(
                f"{where}: rest[{k}] must be [a, b] ({unit}) with {lo} <= a <= b <= {hi} (inside "
                f"range), got {interval!r}"
            )


def _check_link_key(item: dict[str, Any], key: str, allowed: list[str], where: str) -> None:
    value = item.get(key, "")
    if value not in allowed:
        raise SchemaError(f"{where}.{key} {value!r} is not one of {allowed}")


def validate_articulation(meta: AssetMeta) -> AssetMeta:
    """Checks an asset's ``articulation`` and the ``link``/``access`` keys of its supports,
    containers and visual parts.

    Checks: safe, unique link, joint and handle names (not :data:`RESERVED_JOINT_NAMES`);
    parents are the root or earlier links; one joint per link; kinds, roles and handle
    styles from their lists; unit axes and handle directions, ``along`` perpendicular to
    ``normal``; ranges with ``lo <= 0 <= hi``; rest intervals inside the range; link indices
    inside the ``collision`` and ``visual_parts`` lists, each claimed by one link at most;
    handle pieces among their link's; ``swept.lo <= swept.hi``.

    Returns:
        ``meta``, unchanged.

    Raises:
        SchemaError: the first violation; the message names the item, the field and the
            allowed values.
    """
    art = meta.articulation
    if art is not None:
        _check_articulation(meta, art)
    link_names = [ROOT_LINK] if art is None else [ROOT_LINK, *(x.name for x in art.links)]
    joint_names = [""] if art is None else ["", *(j.name for j in art.joints)]
    for group in ("supports", "containers", "visual_parts"):
        for i, item in enumerate(getattr(meta, group)):
            where = f"asset {meta.asset_id!r}: {group}[{i}]"
            _check_link_key(item, "link", link_names, where)
            if group != "visual_parts":
                _check_link_key(item, "access", joint_names, where)
    return meta


def _check_articulation(meta: AssetMeta, art: Articulation) -> None:
    """The checks of :func:`validate_articulation` on ``art`` itself (``meta`` gives the
    lists its indices point into)."""
    pre = f"asset {meta.asset_id!r}: articulation"
    names: set[str] = set()
    handles: set[str] = set()
    claimed_collision: dict[int, str] = {}
    claimed_visual: dict[int, str] = {}
    earlier: list[str] = [ROOT_LINK]
    for i, link in enumerate(art.links):
        where = f"{pre}.links[{i}]"
        _name(link.name, names, where, "link")
        if link.parent not in earlier:
            raise SchemaError(
                f"{where} {link.name!r}: parent {link.parent!r} is not the root or an earlier "
                f"link (allowed: {earlier})"
            )
        earlier.append(link.name)
        where = f"{where} {link.name!r}"
        _indices(
            link.collision, len(meta.collision), claimed_collision, link.name, f"{where}.collision"
        )
        _indices(link.visual, len(meta.visual_parts), claimed_visual, link.name, f"{where}.visual")
        for k, h in enumerate(link.handles):
            _check_handle(h, link, handles, f"{where}.handles[{k}]")
    joints: set[str] = set()
    moved: dict[str, str] = {}
    links = earlier[1:]
    for i, joint in enumerate(art.joints):
        where = f"{pre}.joints[{i}]"
        _check_joint(joint, links, joints, where)
        if joint.link in moved:
            raise SchemaError(
                f"{where} {joint.name!r}: link {joint.link!r} already moves by joint "
                f"{moved[joint.link]!r} (one joint per link)"
            )
        moved[joint.link] = joint.name
    still = [x for x in links if x not in moved]
    if still:
        raise SchemaError(f"{pre}: links {still} have no joint (each link needs one)")
    _vector(art.swept.lo, f"{pre}.swept.lo")
    _vector(art.swept.hi, f"{pre}.swept.hi")
    if not all(a <= b for a, b in zip(art.swept.lo, art.swept.hi, strict=True)):
        raise SchemaError(f"{pre}.swept: lo {art.swept.lo} must be <= hi {art.swept.hi}")


# --------------------------------------------------------------------------------------------
# JSON I/O


def asset_meta_from_dict(data: Any, origin: str = "meta.json") -> AssetMeta:
    """Parses an asset's ``meta.json`` dict, checking its ``schema_version`` and content.

    A version-1 meta (before ``articulation``) reads as version 2 without it.

    Args:
        data: the parsed JSON.
        origin: names the file in error messages.

    Raises:
        SchemaVersionError: a missing or unreadable ``schema_version``.
        SchemaError: malformed content (the message names the field).
    """
    version = data.get("schema_version") if isinstance(data, dict) else None
    if version not in READABLE_ASSET_VERSIONS or isinstance(version, bool):
        raise SchemaVersionError(
            f"{origin}: asset schema_version is {version!r}, this factory reads "
            f"{list(READABLE_ASSET_VERSIONS)}: delete the asset folder to rebuild it"
        )
    if version == 1:
        if "articulation" in data:
            raise SchemaError(
                f"{origin}: a version-1 meta has no 'articulation' (it came in version 2)"
            )
        data = {**data, "schema_version": ASSET_SCHEMA_VERSION}
    try:
        meta: AssetMeta = _from_dict(AssetMeta, data, origin)
    except SchemaError as e:
        message = str(e)
        raise type(e)(message if message.startswith(origin) else f"{origin}: {message}") from None
    return meta


def load_asset_meta(folder: str | Path) -> AssetMeta:
    """Reads ``<folder>/meta.json``."""
    path = Path(folder) / "meta.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SchemaError(f"asset {Path(folder).name!r} has no meta.json at {path}") from None
    except json.JSONDecodeError as e:
        raise SchemaError(f"{path} is not valid JSON ({e.msg}); delete the asset folder") from None
    return asset_meta_from_dict(data, str(path))


def asset_meta_to_json(meta: AssetMeta) -> str:
    """``meta.json`` text (checked again: the meta may have changed since it was built)."""
    validate_articulation(meta)
    return json.dumps(to_dict(meta), indent=2) + "\n"
