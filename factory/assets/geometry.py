"""Building blocks of procedural assets: parts with a visual mesh and exact convex collision.

Every part is watertight, and its collision is a list of convex meshes of at most
:data:`MAX_HULL_VERTICES` vertices that together cover exactly the part's solid (a box is
its own collision; a hollow shell is a ring of convex wall segments plus a bottom). An asset
is a list of parts in the object frame: z up, centred in x and y, bottom at z = 0 (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh

from factory.assets.articulation import JointSpec
from factory.assets.uv import revolve_labels
from factory.schema.asset import HandleMeta

MAX_HULL_VERTICES = 64


@dataclass
class Part:
    """One piece of an asset.

    Attributes:
        visual: watertight visual mesh (object frame, m).
        collision: convex pieces covering the part's solid.
        material: physical material key (see :mod:`.physics`).
        rgba: colour (0..1).
        fill: solid fraction for mass (1: solid; < 1: a box standing in for a frame, a
            cushion or an appliance's hollow body).
        name: what the part is (``top``, ``leg_0``, ``shell`` ...).
        mapping: how its texture is laid on (:mod:`.uv`): ``planar``, ``revolved``,
            ``sphere`` or ``rounded``.
        labels: for ``revolved`` parts, each vertex's (section, profile point) of the
            revolve (:func:`.uv.revolve_labels`; the UVs are made from them and the final
            mesh); for ``rounded`` parts (:func:`.primitives.rounded_box`), each vertex's
            unit offset direction from the inner box, the radius and the box's rotation
            (V, 13, :func:`.uv.rounded_uv`); else ``None``.
        link: the moving link that carries it (``""``: the root body; see
            :class:`~.articulation.JointSpec`).
        handle: the name of the handle it is a piece of (``""``: none; see :mod:`.handles`).
    """

    visual: trimesh.Trimesh
    collision: list[trimesh.Trimesh]
    material: str
    rgba: tuple[float, float, float, float]
    fill: float = 1.0
    name: str = "part"
    mapping: str = "planar"
    labels: np.ndarray | None = None
    link: str = ""
    handle: str = ""

    @property
    def volume(self) -> float:
        """Solid volume (m³) from the convex pieces."""
        return float(sum(c.volume for c in self.collision))


@dataclass(frozen=True)
class Support:
    """An upward support surface: rectangle ``[x0, x1] x [y0, y1]`` at height ``z`` (m), with
    ``clearance`` (m) of free height above it (the next board; large for open tops); ``link``
    is the link carrying it (``""``: the root) and ``access`` the joint to open first to reach
    it (``""``: none). Closed pose, object frame."""

    name: str
    z: float
    rect: tuple[float, float, float, float]
    clearance: float = 10.0
    link: str = ""
    access: str = ""


@dataclass(frozen=True)
class Container:
    """An interior volume: axis-aligned box ``lo..hi`` (m, object frame, closed pose), on
    ``link`` (``""``: the root), reached by opening ``access`` first (``""``: open)."""

    name: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    link: str = ""
    access: str = ""


@dataclass
class Shape:
    """Parts plus their annotations: support surfaces, interior volumes and, for an
    articulated shape, the joints of its links (tree order: a parent's joint first) and the
    handles on them (each handle's pieces are the parts whose ``handle`` is its name)."""

    parts: list[Part] = field(default_factory=list)
    supports: list[Support] = field(default_factory=list)
    containers: list[Container] = field(default_factory=list)
    joints: list[JointSpec] = field(default_factory=list)
    handles: list[HandleMeta] = field(default_factory=list)

    def add(self, part: Part) -> Part:
        self.parts.append(part)
        return part


def _convex(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    hull = mesh.convex_hull
    if len(hull.vertices) > MAX_HULL_VERTICES:  # pragma: no cover - primitives stay small
        raise ValueError(f"convex piece has {len(hull.vertices)} vertices")
    return hull


def box(
    extents: tuple[float, float, float],
    center: tuple[float, float, float],
    material: str,
    rgba: tuple[float, float, float, float],
    name: str = "box",
    fill: float = 1.0,
    yaw: float = 0.0,
) -> Part:
    """A solid box of ``extents`` centred at ``center``, turned by ``yaw`` (rad) about z."""
    m = trimesh.creation.box(extents=extents)
    if yaw:
        m.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
    m.apply_translation(center)
    return Part(m, [m.copy()], material, rgba, fill, name)


def cylinder(
    radius: float,
    height: float,
    z0: float,
    material: str,
    rgba: tuple[float, float, float, float],
    xy: tuple[float, float] = (0.0, 0.0),
    sections: int = 20,
    name: str = "cylinder",
    fill: float = 1.0,
    radius_top: float | None = None,
) -> Part:
    """A solid cylinder (or frustum with ``radius_top``) from ``z0`` to ``z0 + height``."""
    r1 = radius if radius_top is None else radius_top
    profile = np.array([[0, 0], [radius, 0], [r1, height], [0, height]], dtype=float)
    m = trimesh.creation.revolve(profile, sections=sections)
    labels = revolve_labels(m, profile, sections)
    m.apply_translation([xy[0], xy[1], z0])
    return Part(m, [_convex(m)], material, rgba, fill, name, "revolved", labels)


def ellipsoid(
    radii: tuple[float, float, float],
    center: tuple[float, float, float],
    material: str,
    rgba: tuple[float, float, float, float],
    name: str = "ellipsoid",
    fill: float = 1.0,
) -> Part:
    """A solid ellipsoid (42-vertex icosphere scaled)."""
    m = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    m.apply_scale(radii)
    m.apply_translation(center)
    return Part(m, [_convex(m)], material, rgba, fill, name, "sphere")


def shell(
    r_bottom: float,
    r_top: float,
    height: float,
    wall: float,
    bottom: float,
    material: str,
    rgba: tuple[float, float, float, float],
    z0: float = 0.0,
    segments: int = 12,
    name: str = "shell",
    xy: tuple[float, float] = (0.0, 0.0),
) -> Part:
    """A hollow, open-topped vessel (cup, bowl, vase, bin): outer radius ``r_bottom`` at the
    base to ``r_top`` at the rim, walls ``wall`` thick, a base ``bottom`` thick.

    Visual: the revolved profile (watertight). Collision: a base disc plus ``segments``
    convex wall pieces whose outer and inner faces are chords of the wall, so the interior is
    really empty and things can sit inside.
    """
    if wall * 2 >= min(r_bottom, r_top):
        wall = 0.25 * min(r_bottom, r_top)
    bottom = min(bottom, 0.5 * height)
    profile = [
        [0.0, 0.0],
        [r_bottom, 0.0],
        [r_top, height],
        [r_top - wall, height],
        [_lerp(r_bottom, r_top, bottom / height) - wall, bottom],
        [0.0, bottom],
    ]
    visual = trimesh.creation.revolve(np.array(profile, dtype=float), sections=4 * segments)
    labels = revolve_labels(visual, np.array(profile, dtype=float), 4 * segments)
    visual.apply_translation([xy[0], xy[1], z0])
    pieces = []
    base_profile = np.array(
        [[0, 0], [r_bottom, 0], [_lerp(r_bottom, r_top, bottom / height), bottom], [0, bottom]],
        dtype=float,
    )
    base = trimesh.creation.revolve(base_profile, sections=24)
    base.apply_translation([xy[0], xy[1], z0])
    pieces.append(_convex(base))
    rb = _lerp(r_bottom, r_top, bottom / height)
    for k in range(segments):
        a0, a1 = 2 * math.pi * k / segments, 2 * math.pi * (k + 1) / segments
        pts = []
        for a in (a0, (a0 + a1) / 2, a1):
            c, s = math.cos(a), math.sin(a)
            for r, z in ((rb, bottom), (r_top, height)):
                pts.append([r * c, r * s, z])
                pts.append([(r - wall) * c, (r - wall) * s, z])
        seg = trimesh.Trimesh(np.array(pts) + np.array([xy[0], xy[1], z0])).convex_hull
        pieces.append(seg)
    return Part(visual, pieces, material, rgba, 1.0, name, "revolved", labels)


def _lerp(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


def frame_box(
    extents: tuple[float, float, float],
    thickness: float,
    material: str,
    rgba: tuple[float, float, float, float],
    open_front: bool = True,
    open_top: bool = False,
    boards: int = 0,
    z0: float = 0.0,
    name: str = "case",
) -> tuple[list[Part], list[Support], list[Container]]:
    """A case of panels (cabinet, shelf, crate): back, sides, bottom, top (unless
    ``open_top``), front (unless ``open_front``) and ``boards`` evenly spaced shelves.

    Returns:
        parts, the support surfaces (bottom, boards, top) and the interior container(s).
    """
    w, ln, h = extents
    t = min(thickness, 0.2 * min(w, ln, h))
    parts = [
        box((w, t, h), (0, ln / 2 - t / 2, z0 + h / 2), material, rgba, f"{name}_back"),
        box((t, ln - t, h), (-w / 2 + t / 2, -t / 2, z0 + h / 2), material, rgba, f"{name}_left"),
        box((t, ln - t, h), (w / 2 - t / 2, -t / 2, z0 + h / 2), material, rgba, f"{name}_right"),
        box((w - 2 * t, ln - t, t), (0, -t / 2, z0 + t / 2), material, rgba, f"{name}_bottom"),
    ]
    inner_w, inner_l = w - 2 * t, ln - t
    y_front = -ln / 2 if open_front else -ln / 2 + t
    if not open_front:
        parts.append(
            box(
                (w - 2 * t, t, h - t),
                (0, -ln / 2 + t / 2, z0 + (h - t) / 2 + t),
                material,
                rgba,
                f"{name}_front",
            )
        )
        inner_l -= t
    top_z = h if open_top else h - t
    if not open_top:
        parts.append(
            box((w - 2 * t, ln - t, t), (0, -t / 2, z0 + h - t / 2), material, rgba, f"{name}_top")
        )
    rect = (-inner_w / 2, y_front, inner_w / 2, ln / 2 - t)
    # inside a closed case nothing can be put from outside: only its top is a support
    supports = [Support(f"{name}_floor", z0 + t, rect)] if open_front else []
    containers = []
    levels = [z0 + t]
    for b in range(boards):
        zb = z0 + t + (top_z - t) * (b + 1) / (boards + 1)
        parts.append(
            box(
                (inner_w, inner_l, t),
                (0, -t / 2 + (0 if open_front else t / 2), zb - t / 2 + t / 2),
                material,
                rgba,
                f"{name}_board_{b}",
            )
        )
        if open_front:
            supports.append(Support(f"{name}_board_{b}", zb + t / 2, rect))
        levels.append(zb + t / 2)
    levels.append(z0 + top_z)
    # free height above each inner level: up to the next board (or the top panel)
    inner = [sp for sp in supports if not sp.name.endswith("_top")]
    supports = [
        Support(
            sp.name,
            sp.z,
            sp.rect,
            (levels[i + 1] - t if i < len(levels) - 2 else levels[i + 1]) - sp.z,
        )
        for i, sp in enumerate(inner)
    ] + [sp for sp in supports if sp.name.endswith("_top")]
    for i in range(len(levels) - 1):
        containers.append(
            Container(
                f"{name}_interior_{i}",
                (rect[0], rect[1], levels[i]),
                (rect[2], rect[3], levels[i + 1] - (t if i < len(levels) - 2 else 0)),
            )
        )
    if not open_top:
        supports.append(Support(f"{name}_top", z0 + h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return parts, supports, containers


def assemble(shape: Shape) -> trimesh.Trimesh:
    """The visual mesh of all parts (watertight: each part is)."""
    mesh = trimesh.util.concatenate([p.visual for p in shape.parts])
    assert isinstance(mesh, trimesh.Trimesh)
    return mesh
