"""The procedural backend: category + parameters + seed -> a finished asset (meshes + meta).

Sizes: the request's dimensions (m) are met exactly (the template builds to them); when a
request gives none, the category's typical size is varied by up to +-8 % per seed. Colours and
materials come from the request (resolved from text) or the category's defaults, with a small
per-seed shade variation.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import trimesh

from factory.assets.articulation import JointPhysics, applied, fuse, swept_box
from factory.assets.catalog import CATEGORIES, Category
from factory.assets.errors import AssetError as AssetError
from factory.assets.geometry import Shape, assemble
from factory.assets.physics import material
from factory.schema.asset import SweptBox

MIN_DIM = 0.003
MAX_DIM = 12.0


@dataclass
class AssetSpec:
    """A fully resolved request for one asset.

    Attributes:
        category: a key of :data:`CATEGORIES` (procedural) or free text (other backends).
        dims: ``(width, length, height)`` in m, or ``None`` for the category's typical size.
        materials: primary and secondary material names, or ``None`` for the defaults.
        colors: primary and secondary rgba, or ``None`` for the material/category colours.
        style: a style word (kept for provenance and variation).
        seed: the random seed.
        text: the original text request, if any.
        finish: condition kinds for the surfaces (``rust``, ``dust``, ``polished``, ``gold``,
            ...: :mod:`factory.textures.conditions`), read from the text or given by the scene.
        texture_size: texture images' size (px).
        rig: for an articulated category, ``joints`` (moving links) or ``fused`` (one rigid
            body, closed; also what ``""`` builds); ``""`` for the others.
    """

    category: str
    dims: tuple[float, float, float] | None = None
    materials: tuple[str, str] | None = None
    colors: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    style: str = ""
    seed: int = 0
    text: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    finish: tuple[str, ...] = ()
    texture_size: int = 256
    rig: str = ""

    def key(self) -> dict[str, Any]:
        """The normalised request (what the asset id hashes; ``finish``, ``texture_size`` and
        ``rig`` only when set, so assets without them keep their ids)."""
        looks: dict[str, Any] = {}
        finish = sorted(set(self.finish) - {"clean"})  # "clean" changes nothing
        if finish:
            looks["finish"] = finish
        if self.texture_size != 256:
            looks["texture_size"] = int(self.texture_size)
        if self.rig:
            looks["rig"] = self.rig
        return looks | {
            "category": self.category,
            "dims": None if self.dims is None else [round(float(v), 6) for v in self.dims],
            "materials": None if self.materials is None else list(self.materials),
            "colors": None
            if self.colors is None
            else [[round(float(c), 4) for c in col] for col in self.colors],
            "style": self.style,
            "seed": int(self.seed),
        }


@dataclass
class Generated:
    """A generated asset before it is written to the cache (``physics``: by joint name, for
    the shape's joints; ``swept``: the box its links fill over their ranges, if any)."""

    shape: Shape
    dims: tuple[float, float, float]
    mass: float
    friction: float
    metallic: float
    roughness: float
    category: str
    materials: tuple[str, str]
    physics: dict[str, JointPhysics] = field(default_factory=dict)
    swept: SweptBox | None = None

    @property
    def visual(self) -> trimesh.Trimesh:
        return assemble(self.shape)


def check_dims(dims: Any) -> tuple[float, float, float]:
    """Validates requested dimensions (m)."""
    try:
        d = tuple(float(v) for v in dims)
    except (TypeError, ValueError):
        raise AssetError(f"dimensions must be 3 numbers (m), got {dims!r}") from None
    if len(d) != 3 or not all(np.isfinite(d)):
        raise AssetError(f"dimensions must be 3 finite numbers (m), got {dims!r}")
    if min(d) < MIN_DIM or max(d) > MAX_DIM:
        raise AssetError(
            f"dimensions {d} m are out of range: each must be within {MIN_DIM}..{MAX_DIM} m"
        )
    return (d[0], d[1], d[2])


def _shade(rgba: tuple[float, ...], rng: np.random.Generator, amount: float = 0.06) -> tuple:
    hue, light, sat = colorsys.rgb_to_hls(*rgba[:3])
    light2 = float(np.clip(light + rng.uniform(-amount, amount), 0.03, 0.97))
    r, g, b = colorsys.hls_to_rgb(hue, light2, sat)
    return (r, g, b, rgba[3] if len(rgba) > 3 else 1.0)


def generate(spec: AssetSpec) -> Generated:
    """Builds a procedural asset.

    Raises:
        AssetError: unknown category or invalid dimensions.
    """
    cat: Category | None = CATEGORIES.get(spec.category)
    if cat is None:
        raise AssetError(
            f"unknown procedural category {spec.category!r}: see python -m factory.assets --list"
        )
    rng = np.random.default_rng(spec.seed)
    if spec.dims is None:
        dims = tuple(float(v) * float(rng.uniform(0.92, 1.08)) for v in cat.dims)
    else:
        dims = check_dims(spec.dims)
    mats = spec.materials or cat.materials
    m0, m1 = material(mats[0]), material(mats[1])
    if spec.colors is not None:
        cols = (tuple(spec.colors[0]), tuple(spec.colors[1]))
    elif cat.colors is not None:
        cols = (_shade(cat.colors[0], rng), _shade(cat.colors[1], rng))
    else:
        cols = (_shade(m0.rgba, rng), _shade(m1.rgba, rng))
    shape = cat.template(np.array(dims, dtype=float), (mats[0], mats[1]), cols, rng)  # type: ignore[arg-type]
    if spec.rig != "joints":
        fuse(shape)
    # exact size: scale the assembled parts onto the requested box (templates are built to it;
    # this removes rounding from revolved or segmented parts)
    visual = assemble(shape)
    lo, hi = visual.bounds
    ext = hi - lo
    scale = np.array(dims) / np.maximum(ext, 1e-12)
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    tf = np.diag([*scale, 1.0])
    tf[:3, 3] = -centre * scale
    for p in shape.parts:
        p.visual.apply_transform(tf)
        for c in p.collision:
            c.apply_transform(tf)

    def _x(v: float) -> float:
        return float((v - centre[0]) * scale[0])

    def _y(v: float) -> float:
        return float((v - centre[1]) * scale[1])

    def _z(v: float) -> float:
        return float((v - centre[2]) * scale[2])

    shape.supports = [
        replace(
            s,
            z=_z(s.z),
            rect=(_x(s.rect[0]), _y(s.rect[1]), _x(s.rect[2]), _y(s.rect[3])),
            clearance=s.clearance * float(scale[2]),
        )
        for s in shape.supports
    ]
    shape.containers = [
        replace(
            c,
            lo=(_x(c.lo[0]), _y(c.lo[1]), _z(c.lo[2])),
            hi=(_x(c.hi[0]), _y(c.hi[1]), _z(c.hi[2])),
        )
        for c in shape.containers
    ]
    physics = _scale_joints(shape, tf, scale, cat)
    mass = cat.fill * sum(p.volume * material(p.material).density * p.fill for p in shape.parts)
    return Generated(
        shape=shape,
        dims=dims,  # type: ignore[arg-type]
        mass=float(mass),
        friction=m0.friction,
        metallic=m0.metallic,
        roughness=m0.roughness,
        category=spec.category,
        materials=(mats[0], mats[1]),
        physics=physics,
        swept=swept_box(shape) if shape.joints else None,
    )


def _scale_joints(
    shape: Shape, tf: np.ndarray, scale: np.ndarray, cat: Category
) -> dict[str, JointPhysics]:
    """Moves the shape's joints and handles by the final scale ``tf`` (anchors and centres as
    points, directions scaled and renormalised, slide travel and handle length by the scale
    along them), then applies the category's physics per role; returns it by joint name."""

    def point(v: Any) -> tuple[float, float, float]:
        p = tf @ np.array([*v, 1.0])
        return (float(p[0]), float(p[1]), float(p[2]))

    def direction(v: Any) -> tuple[tuple[float, float, float], float]:
        u = np.asarray(v, float) * scale
        n = float(np.linalg.norm(u))
        return (float(u[0] / n), float(u[1] / n), float(u[2] / n)), n

    physics = {}
    for k, j in enumerate(shape.joints):
        axis, stretch = direction(j.axis)
        rng = j.range if j.kind == "hinge" else (j.range[0] * stretch, j.range[1] * stretch)
        j = replace(j, anchor=point(j.anchor), axis=axis, range=rng)
        phys = cat.articulation[j.role]
        shape.joints[k] = applied(j, phys)
        physics[j.name] = phys
    for h in shape.handles:
        along, stretch = direction(h.along)
        normal, _ = direction(h.normal)
        h.center = list(point(h.center))
        h.along, h.normal = list(along), list(normal)
        h.length *= stretch
    return physics
