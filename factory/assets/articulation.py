"""Joints of procedural shapes: the shape-level joint, its physics, and link poses.

A shape's moving links hang from their parents by one joint each (:class:`JointSpec`, object
frame, closed pose: every joint at 0). :func:`link_transform` moves a link by its own joint,
:func:`pose_of` composes a link's pose through its parents, and :func:`swept_box` bounds what
the links fill over their ranges. A joint's physics (:class:`JointPhysics`) comes from the
catalogue's ``articulation`` field, per role, over :data:`JOINT_DEFAULTS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from factory.assets.errors import AssetError, CatalogError
from factory.schema.asset import (
    JOINT_KINDS,
    JOINT_ROLES,
    ROOT_LINK,
    UNIT_TOLERANCE,
    Articulation,
    SweptBox,
)
from factory.schema.joint_pose import Posed as _Posed
from factory.schema.joint_pose import link_transform

JOINT_DEFAULTS: dict[str, dict[str, Any]] = {
    "door": {"range": [0.0, 110.0], "damping": 0.3, "friction": 0.4, "armature": 0.01},
    "drawer": {"range": [0.0, 0.8], "damping": 4.0, "friction": 3.0, "armature": 0.0},
    "flap": {"range": [0.0, 90.0], "damping": 0.5, "friction": 0.5, "spring": [2.0, 0.0]},
    "lid": {"range": [0.0, 100.0], "damping": 0.3, "friction": 0.3, "hold": True},
    "seat": {"range": [0.0, 95.0], "damping": 0.2, "friction": 0.2, "hold": True},
}
"""Joint physics per role, as the catalogue writes them (:func:`parse_physics` reads these
first, then a category's ``articulation`` entry over them): ``range`` in degrees for hinges
and as fractions of the link's travel (the template's range) for slides; ``damping``
(N m s/rad or N s/m), ``friction`` = frictionloss (N m or N), ``armature`` (kg m^2 or kg),
``spring: [stiffness N m/rad or N/m, reference deg or m]``, ``hold`` (friction set to hold
the link against gravity, applied when the asset is built). All at the asset's own mass."""

PHYSICS_FIELDS: tuple[str, ...] = ("range", "damping", "friction", "armature", "spring", "hold")
"""The keys of one role's entry in the catalogue's ``articulation`` field."""

HOLD_MARGIN = 1.3
"""``hold``: frictionloss = this x the largest gravity torque of the link over its range."""


@dataclass(frozen=True)
class JointSpec:
    """The joint of a shape's moving link (object frame, closed pose).

    Attributes:
        name: unique among the shape's joints (a safe id, not ``free``).
        kind: ``hinge`` (position in rad) or ``slide`` (m); see ``JOINT_KINDS``.
        role: what the link is (``door``, ``drawer``, ...; see ``JOINT_ROLES``).
        link: the link it moves (the ``Part.link`` of its parts).
        anchor: a point on the axis (m, object frame).
        axis: unit direction (object frame); a positive position opens the link.
        range: ``(lo, hi)`` (rad or m) with ``lo <= 0 <= hi``; for a slide, the full travel.
        parent: the link it hangs from (``""``: the root).
    """

    name: str
    kind: str
    role: str
    link: str
    anchor: tuple[float, float, float]
    axis: tuple[float, float, float]
    range: tuple[float, float]
    parent: str = ROOT_LINK

    def __post_init__(self) -> None:
        where = f"joint {self.name!r}"
        if self.kind not in JOINT_KINDS:
            raise AssetError(f"{where}: kind {self.kind!r} is not one of {list(JOINT_KINDS)}")
        if self.role not in JOINT_ROLES:
            raise AssetError(f"{where}: role {self.role!r} is not one of {list(JOINT_ROLES)}")
        if abs(float(np.linalg.norm(self.axis)) - 1.0) > UNIT_TOLERANCE:
            raise AssetError(f"{where}: axis {self.axis} must be a unit vector")
        lo, hi = self.range
        if not lo <= 0.0 <= hi or lo >= hi:
            raise AssetError(f"{where}: range {self.range} needs lo <= 0 <= hi and lo < hi")
        if not self.link or self.link == self.parent:
            raise AssetError(f"{where}: link {self.link!r} must be named and not its parent")


@dataclass(frozen=True)
class JointPhysics:
    """A role's joint physics, at the asset's own mass.

    Attributes:
        range: ``(lo, hi)``: degrees for a hinge, fractions of the template's travel for a
            slide.
        damping: N m s/rad or N s/m.
        frictionloss: dry friction (N m or N).
        armature: added inertia (kg m^2 or kg).
        stiffness: spring stiffness (N m/rad or N/m).
        springref: the spring's rest position (deg for a hinge, m for a slide).
        hold: set ``frictionloss`` to :data:`HOLD_MARGIN` x the largest gravity torque.
    """

    range: tuple[float, float]
    damping: float = 0.0
    frictionloss: float = 0.0
    armature: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    hold: bool = False


class Shape(Protocol):
    """What this module reads of a :class:`~.geometry.Shape` (a protocol: the geometry module
    imports this one)."""

    parts: list[Any]
    supports: list[Any]
    containers: list[Any]
    joints: list[JointSpec]
    handles: list[Any]


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _physics(name: str, role: str, raw: Mapping[str, Any]) -> JointPhysics:
    def fail(key: str, why: str) -> CatalogError:
        return CatalogError(f"catalogue entry {name!r}, field 'articulation.{role}.{key}': {why}")

    for key in raw:
        if key not in PHYSICS_FIELDS:
            raise fail(str(key), f"unknown; valid keys: {', '.join(PHYSICS_FIELDS)}")
    rng = raw["range"]
    if not (isinstance(rng, list | tuple) and len(rng) == 2 and all(map(_number, rng))):
        raise fail("range", f"expected [lo, hi] (deg, or travel fractions), got {rng!r}")
    if not rng[0] <= 0.0 <= rng[1] or rng[0] >= rng[1]:
        raise fail("range", f"expected lo <= 0 <= hi and lo < hi, got {list(rng)}")
    values = {}
    for key in ("damping", "friction", "armature"):
        v = raw.get(key, 0.0)
        if not _number(v) or v < 0:
            raise fail(key, f"expected a number >= 0, got {v!r}")
        values[key] = float(v)
    spring = raw.get("spring", [0.0, 0.0])
    if not (
        isinstance(spring, list | tuple)
        and len(spring) == 2
        and all(map(_number, spring))
        and spring[0] >= 0
    ):
        raise fail("spring", f"expected [stiffness >= 0, reference], got {spring!r}")
    hold = raw.get("hold", False)
    if not isinstance(hold, bool):
        raise fail("hold", f"expected true or false, got {hold!r}")
    return JointPhysics(
        range=(float(rng[0]), float(rng[1])),
        damping=values["damping"],
        frictionloss=values["friction"],
        armature=values["armature"],
        stiffness=float(spring[0]),
        springref=float(spring[1]),
        hold=hold,
    )


def parse_physics(name: str, raw: Any) -> dict[str, JointPhysics]:
    """A category's ``articulation`` field: role -> physics, each over the role's
    :data:`JOINT_DEFAULTS` (every role has an entry).

    Args:
        name: the category (for messages).
        raw: ``{role: {range, damping, friction, armature, spring, hold}}`` or ``None``.

    Raises:
        CatalogError: naming the category, the field and the valid roles, keys or values.
    """
    raw = {} if raw is None else raw
    if not isinstance(raw, Mapping):
        raise CatalogError(
            f"catalogue entry {name!r}, field 'articulation': expected a mapping of roles "
            f"({', '.join(JOINT_ROLES)}), got {raw!r}"
        )
    for role, entry in raw.items():
        if role not in JOINT_ROLES:
            raise CatalogError(
                f"catalogue entry {name!r}, field 'articulation.{role}': unknown role; valid "
                f"roles: {', '.join(JOINT_ROLES)}"
            )
        if not isinstance(entry, Mapping):
            raise CatalogError(
                f"catalogue entry {name!r}, field 'articulation.{role}': expected a mapping of "
                f"{', '.join(PHYSICS_FIELDS)}, got {entry!r}"
            )
    return {
        role: _physics(name, role, {**JOINT_DEFAULTS[role], **raw.get(role, {})})
        for role in JOINT_ROLES
    }


def applied(joint: JointSpec, physics: JointPhysics) -> JointSpec:
    """``joint`` with its range from ``physics`` (degrees -> rad for a hinge; fractions of
    the joint's travel for a slide)."""
    lo, hi = physics.range
    if joint.kind == "hinge":
        rng = (math.radians(lo), math.radians(hi))
    else:
        travel = joint.range[1] if joint.range[1] > 0 else -joint.range[0]
        rng = (lo * travel, hi * travel)
    return replace(joint, range=rng)


def _compose(
    parents: Mapping[str, str],
    joints: Mapping[str, _Posed],
    values: Mapping[str, float],
    link: str,
) -> np.ndarray:
    chain: list[str] = []
    seen = set()
    while link != ROOT_LINK:
        if link not in parents:
            raise KeyError(f"link {link!r} is not one of {sorted(parents)}")
        if link in seen:  # pragma: no cover - validated trees have no cycles
            raise KeyError(f"link {link!r} is its own ancestor")
        seen.add(link)
        chain.append(link)
        link = parents[link]
    tf = np.eye(4)
    for name in reversed(chain):  # root first
        tf = tf @ link_transform(joints[name], values.get(name, 0.0))
    return tf


def pose_of(art: Articulation, joint_states: Mapping[str, float], link: str) -> np.ndarray:
    """A link's (4, 4) pose in the object frame (relative to its closed pose) with the joints
    at ``joint_states`` (rad or m by joint name; missing joints closed), through its parents.

    Raises:
        KeyError: ``link`` is not a link of ``art`` (the root, ``""``, is the identity).
    """
    parents = {x.name: x.parent for x in art.links}
    by_link = {j.link: j for j in art.joints}
    values = {j.link: float(joint_states.get(j.name, 0.0)) for j in art.joints}
    return _compose(parents, by_link, values, link)


def shape_pose(shape: Shape, joint_states: Mapping[str, float], link: str) -> np.ndarray:
    """:func:`pose_of` for a shape's joints (before it is an asset)."""
    parents = {j.link: j.parent for j in shape.joints}
    by_link = {j.link: j for j in shape.joints}
    values = {j.link: float(joint_states.get(j.name, 0.0)) for j in shape.joints}
    return _compose(parents, by_link, values, link)


def swept_box(shape: Shape, steps: int = 9) -> SweptBox:
    """The axis-aligned box (m, object frame) the shape fills with every link moved over its
    joint's range (``steps`` values per joint, both limits included; each joint is swept with
    the others at each of their values, so nested links are covered).

    Hinges sweep arcs: ``steps`` samples bound the arc within ``1 - cos(range / (2 (steps-1)))``
    of its radius, and the box is grown by that to cover it.
    """
    pts_of: dict[str, list[np.ndarray]] = {}
    for p in shape.parts:
        pts_of.setdefault(p.link, []).append(np.asarray(p.visual.vertices, dtype=float))
    root = np.concatenate(pts_of.get(ROOT_LINK, [np.zeros((1, 3))]))
    lo, hi = root.min(axis=0), root.max(axis=0)
    grids = {j.name: np.linspace(j.range[0], j.range[1], steps) for j in shape.joints}
    by_link = {j.link: j for j in shape.joints}
    for j in shape.joints:
        # the link and its ancestors' joints take every grid value together
        chain, link = [], j.link
        while link != ROOT_LINK:
            chain.append(by_link[link])
            link = by_link[link].parent
        pts = np.concatenate(
            [v for name, vs in pts_of.items() if _under(shape, name, j.link) for v in vs]
            or [np.zeros((0, 3))]
        )
        if not len(pts):
            continue
        grow = 0.0
        for x in chain:
            if x.kind == "hinge":
                ext = float(np.linalg.norm(pts - np.asarray(x.anchor), axis=1).max())
                grow += ext * (1 - math.cos((x.range[1] - x.range[0]) / (2 * (steps - 1))))
        mesh = np.meshgrid(*(grids[x.name] for x in chain), indexing="ij")
        for values in zip(*(m.ravel() for m in mesh), strict=True):
            states = {x.name: float(v) for x, v in zip(chain, values, strict=True)}
            tf = shape_pose(shape, states, j.link)
            moved = pts @ tf[:3, :3].T + tf[:3, 3]
            lo = np.minimum(lo, moved.min(axis=0) - grow)
            hi = np.maximum(hi, moved.max(axis=0) + grow)
    return SweptBox(lo=[float(v) for v in lo], hi=[float(v) for v in hi])


def _under(shape: Shape, link: str, ancestor: str) -> bool:
    """Whether ``link`` is ``ancestor`` or hangs from it."""
    parents = {j.link: j.parent for j in shape.joints}
    while link != ROOT_LINK:
        if link == ancestor:
            return True
        link = parents.get(link, ROOT_LINK)
    return False


def fuse(shape: Shape) -> Shape:
    """``shape`` as one rigid body, closed: every part on the root, no joints, no handles
    (the parts are the closed pose already)."""
    for p in shape.parts:
        p.link = ROOT_LINK
        p.handle = ""
    shape.joints = []
    shape.handles = []
    shape.supports = [replace(s, link=ROOT_LINK, access="") for s in shape.supports]
    shape.containers = [replace(c, link=ROOT_LINK, access="") for c in shape.containers]
    return shape
