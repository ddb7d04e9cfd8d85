"""The part grammar: a category's shape as a short list of primitive parts (catalogue data).

A ``parts`` template (``template: {kind: parts, parts: [...]}`` in the catalogue data) places
primitives in *slots*: boxes ``[x0, y0, z0, x1, y1, z1]`` given as fractions (0..1) of the
requested extents (x across, y front (0) to back (1), z up), so one entry fits every size.
Each part is one mapping with exactly one shape key:

* ``box: slot`` a solid box (``round``: rounded edges, radius as a fraction of its smallest
  side);
* ``cyl: slot`` a cylinder along ``axis`` (``z``, ``x`` or ``y``; diameter the smaller cross
  side of the slot), a frustum with ``taper`` (top radius / bottom radius);
* ``sphere: slot`` an ellipsoid filling the slot;
* ``revolve: slot`` a solid of revolution along ``axis`` from ``profile``, a list of
  ``[r, t]`` pairs: radius as a fraction of the slot's half cross side, position along the axis
  as a fraction of the slot (not decreasing, 0 to 1);
* ``shell: slot`` a hollow open-topped vessel (``taper``: bottom radius / rim radius, ``wall``:
  wall thickness as a fraction of the rim radius); it adds an interior;
* ``tray: slot`` an open-topped rectangular box (``wall``: fraction of its smaller side); it adds
  an interior;
* ``prism: slot`` a convex ``polygon`` (``[u, v]`` fractions of the slot's two cross axes)
  extruded along ``axis``;
* ``bar: [x0, y0, z0, x1, y1, z1]`` a round bar between two points, ``t`` thick (m).

Common keys: ``mat`` (0: primary material and colour, 1: secondary, or a material name),
``fill`` (solid fraction for mass), ``mirror`` (``x``, ``y`` or ``xy``: also the copies
mirrored about the centre planes), ``repeat`` (``[n, dx, dy, dz]``: n copies, each shifted by
fractions), ``support`` (true: the part's top is a support surface) and ``name``.

Every primitive is watertight and convex or made of exact convex pieces (a shell's wall
segments, a revolve's bands) of at most :data:`.geometry.MAX_HULL_VERTICES` vertices, so the
physical contract of the other templates holds: exact extents (the generator scales the parts
onto the requested box), convex collision, mass from material, volume and ``fill``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

from factory.assets.geometry import Container, Part, Shape, Support, box, cylinder, ellipsoid
from factory.assets.geometry import shell as shell_part
from factory.assets.physics import MATERIALS, material
from factory.assets.primitives import revolved, rounded_box

RGBA = tuple[float, float, float, float]
Template = Callable[[np.ndarray, tuple[str, str], tuple[RGBA, RGBA], np.random.Generator], Shape]

SHAPES = ("box", "cyl", "sphere", "revolve", "shell", "tray", "prism", "bar")
"""The shape keys of a part."""

OPTIONS: dict[str, tuple[str, ...]] = {
    "box": ("round",),
    "cyl": ("axis", "taper"),
    "sphere": (),
    "revolve": ("axis", "profile"),
    "shell": ("taper", "wall"),
    "tray": ("wall",),
    "prism": ("axis", "polygon"),
    "bar": ("t",),
}
"""The shape-specific keys each shape accepts (besides :data:`COMMON`)."""

COMMON = ("mat", "fill", "mirror", "repeat", "support", "name")
AXES = ("x", "y", "z")
MIRRORS = ("x", "y", "xy")


class GrammarError(ValueError):
    """A part description is invalid; the message names the field (``parts[2].box``)."""


@dataclass(frozen=True)
class PartSpec:
    """One validated part: its shape, slot (fractions) and options."""

    shape: str
    slot: tuple[float, float, float, float, float, float]
    mat: int | str = 0
    fill: float = 1.0
    name: str = ""
    support: bool = False
    axis: str = "z"
    taper: float = 1.0
    round: float = 0.0
    wall: float = 0.08
    t: float = 0.02
    profile: tuple[tuple[float, float], ...] = ()
    polygon: tuple[tuple[float, float], ...] = ()


def _numbers(value: Any, n: int | None, field: str) -> tuple[float, ...]:
    ok = isinstance(value, Sequence) and not isinstance(value, str)
    if ok:
        ok = all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    if not ok or (n is not None and len(value) != n):
        want = f"{n} numbers" if n is not None else "numbers"
        raise GrammarError(f"{field}: expected a list of {want}, got {value!r}")
    return tuple(float(v) for v in value)


def _pairs(value: Any, field: str, lo: int) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) < lo:
        raise GrammarError(f"{field}: expected a list of at least {lo} [a, b] pairs, got {value!r}")
    out = [_numbers(p, 2, f"{field}[{i}]") for i, p in enumerate(value)]
    return tuple((a, b) for a, b in out)


def _number(value: Any, field: str, lo: float, hi: float) -> float:
    if not isinstance(value, int | float) or isinstance(value, bool) or not lo <= value <= hi:
        raise GrammarError(f"{field}: expected a number in {lo}..{hi}, got {value!r}")
    return float(value)


def _choice(value: Any, field: str, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise GrammarError(f"{field}: {value!r} is not one of {', '.join(choices)}")
    return str(value)


def _convex(poly: tuple[tuple[float, float], ...]) -> bool:
    p = np.asarray(poly, float)
    e = np.roll(p, -1, axis=0) - p
    cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    return bool(np.all(cross > 1e-12) or np.all(cross < -1e-12))


def parse_part(raw: Any, field: str) -> list[PartSpec]:
    """Validates one part mapping and expands its ``mirror`` and ``repeat`` copies.

    Raises:
        GrammarError: naming the field (``parts[2].taper``) and the valid choices.
    """
    if not isinstance(raw, Mapping):
        raise GrammarError(f"{field}: expected a mapping with one of {', '.join(SHAPES)}")
    shapes = [k for k in raw if k in SHAPES]
    if len(shapes) != 1:
        raise GrammarError(f"{field}: needs exactly one shape key of {', '.join(SHAPES)}")
    shape = shapes[0]
    allowed = (shape, *OPTIONS[shape], *COMMON)
    for key in raw:
        if key not in allowed:
            raise GrammarError(
                f"{field}.{key}: unknown key for a {shape}; valid keys: {', '.join(allowed)}"
            )
    slot = _numbers(raw[shape], 6, f"{field}.{shape}")
    if any(not -0.5 <= v <= 1.5 for v in slot):
        raise GrammarError(f"{field}.{shape}: fractions must lie within -0.5..1.5, got {slot}")
    if shape != "bar" and any(slot[i + 3] <= slot[i] for i in range(3)):
        raise GrammarError(f"{field}.{shape}: each upper bound must exceed its lower, got {slot}")
    kw: dict[str, Any] = {}
    mat = raw.get("mat", 0)
    if mat not in (0, 1) and mat not in MATERIALS:
        raise GrammarError(
            f"{field}.mat: {mat!r} is not 0, 1 or a material ({', '.join(MATERIALS)})"
        )
    kw["mat"] = mat
    if "fill" in raw:
        kw["fill"] = _number(raw["fill"], f"{field}.fill", 0.001, 10.0)
    if "name" in raw:
        if not isinstance(raw["name"], str) or not raw["name"]:
            raise GrammarError(f"{field}.name: expected a non-empty string")
        kw["name"] = raw["name"]
    if "support" in raw:
        if not isinstance(raw["support"], bool):
            raise GrammarError(f"{field}.support: expected true or false")
        kw["support"] = raw["support"]
    if "axis" in raw:
        kw["axis"] = _choice(raw["axis"], f"{field}.axis", AXES)
    if "taper" in raw:
        kw["taper"] = _number(raw["taper"], f"{field}.taper", 0.05, 20.0)
    if "round" in raw:
        kw["round"] = _number(raw["round"], f"{field}.round", 0.0, 0.45)
    if "wall" in raw:
        kw["wall"] = _number(raw["wall"], f"{field}.wall", 0.005, 0.45)
    if "t" in raw:
        kw["t"] = _number(raw["t"], f"{field}.t", 0.001, 0.5)
    if shape == "revolve":
        if "profile" not in raw:
            raise GrammarError(f"{field}.profile: a revolve needs a profile of [r, t] pairs")
        prof = _pairs(raw["profile"], f"{field}.profile", 2)
        ts = [t for _, t in prof]
        if any(r <= 0 or r > 1.0 for r, _ in prof) or ts[0] != 0 or ts[-1] != 1:
            raise GrammarError(
                f"{field}.profile: radii must be in (0, 1] and positions run from 0 to 1"
            )
        if any(b < a for a, b in itertools.pairwise(ts)):
            raise GrammarError(f"{field}.profile: positions must not decrease")
        kw["profile"] = prof
    if shape == "prism":
        if "polygon" not in raw:
            raise GrammarError(f"{field}.polygon: a prism needs a convex polygon of [u, v] points")
        poly = _pairs(raw["polygon"], f"{field}.polygon", 3)
        if len(poly) > 32 or not _convex(poly):
            raise GrammarError(f"{field}.polygon: must be convex with 3..32 points")
        kw["polygon"] = poly
    base = PartSpec(shape, slot, **kw)  # type: ignore[arg-type]
    copies = [base]
    if "mirror" in raw:
        how = _choice(raw["mirror"], f"{field}.mirror", MIRRORS)
        for axis in how:
            copies += [_mirrored(c, "xy".index(axis), shape == "bar") for c in copies]
    if "repeat" in raw:
        rep = _numbers(raw["repeat"], 4, f"{field}.repeat")
        n = int(rep[0])
        if n != rep[0] or not 1 <= n <= 40:
            raise GrammarError(f"{field}.repeat: the count must be a whole number in 1..40")
        d = rep[1:] * 2
        copies = [
            PartSpec(
                **{**c.__dict__, "slot": tuple(s + k * v for s, v in zip(c.slot, d, strict=True))}
            )
            for c in copies
            for k in range(n)
        ]
    return copies


def _mirrored(p: PartSpec, i: int, points: bool) -> PartSpec:
    s = list(p.slot)
    if points:
        s[i], s[i + 3] = 1 - s[i], 1 - s[i + 3]
    else:
        s[i], s[i + 3] = 1 - s[i + 3], 1 - s[i]
    return PartSpec(**{**p.__dict__, "slot": tuple(s)})


def parse(parts: Any, containers: Any = ()) -> tuple[list[PartSpec], list[tuple[float, ...]]]:
    """Validates a ``parts`` template's parameters.

    Raises:
        GrammarError: naming the field and the valid choices.
    """
    if not isinstance(parts, Sequence) or isinstance(parts, str) or not parts:
        raise GrammarError("parts: expected a non-empty list of parts")
    specs = [s for i, raw in enumerate(parts) for s in parse_part(raw, f"parts[{i}]")]
    if not isinstance(containers, Sequence) or isinstance(containers, str):
        raise GrammarError("containers: expected a list of slots")
    boxes = [_numbers(c, 6, f"containers[{i}]") for i, c in enumerate(containers)]
    return specs, boxes


def parts(parts: Any, containers: Any = ()) -> Template:
    """The ``parts`` template: builds the validated parts to the requested extents.

    Args:
        parts: the part mappings (see the module docstring).
        containers: extra interior slots ``[x0, y0, z0, x1, y1, z1]`` (fractions).

    Raises:
        GrammarError: an invalid part (raised here, when the catalogue is loaded).
    """
    specs, boxes = parse(parts, containers)

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        s = Shape()
        for k, spec in enumerate(specs):
            _add(s, spec, d, mats, cols, f"{spec.name or spec.shape}_{k}")
        for lo_hi in boxes:
            lo, hi = _point(lo_hi[:3], d), _point(lo_hi[3:], d)
            s.containers.append(Container("interior", lo, hi))
        return s

    return build


def _point(f: Sequence[float], d: np.ndarray) -> tuple[float, float, float]:
    return ((f[0] - 0.5) * d[0], (f[1] - 0.5) * d[1], f[2] * d[2])


def _look(spec: PartSpec, mats: tuple[str, str], cols: tuple[RGBA, RGBA]) -> tuple[str, RGBA]:
    if isinstance(spec.mat, str):
        return spec.mat, material(spec.mat).rgba
    return mats[spec.mat], cols[spec.mat]


def _axis_frame(axis: str) -> np.ndarray:
    """The rotation taking a part built along z onto ``axis``."""
    if axis == "x":
        return trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0])
    if axis == "y":
        return trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0])
    return np.eye(4)


def _place(part: Part, matrix: np.ndarray) -> Part:
    part.visual.apply_transform(matrix)
    for c in part.collision:
        c.apply_transform(matrix)
    return part


def _add(
    s: Shape,
    spec: PartSpec,
    d: np.ndarray,
    mats: tuple[str, str],
    cols: tuple[RGBA, RGBA],
    name: str,
) -> None:
    mat, rgba = _look(spec, mats, cols)
    lo = np.array(_point(spec.slot[:3], d))
    hi = np.array(_point(spec.slot[3:], d))
    if spec.shape == "bar":
        s.add(_bar(lo, hi, spec.t, mat, rgba, name, spec.fill))
        return
    ext = hi - lo
    centre = (lo + hi) / 2
    if spec.shape == "box":
        if spec.round > 0:
            r = spec.round * float(ext.min())
            part = rounded_box(tuple(ext), tuple(centre), mat, rgba, r, name, spec.fill, segments=1)
        else:
            part = box(tuple(ext), tuple(centre), mat, rgba, name, spec.fill)
        s.add(part)
    elif spec.shape == "sphere":
        s.add(ellipsoid(tuple(ext / 2), tuple(centre), mat, rgba, name, spec.fill))
    elif spec.shape in ("cyl", "revolve"):
        i = AXES.index(spec.axis)
        length = float(ext[i])
        radius = float(min(ext[j] for j in range(3) if j != i)) / 2
        if spec.shape == "cyl":
            top = radius * spec.taper if spec.taper <= 1 else radius
            bot = radius if spec.taper <= 1 else radius / spec.taper
            part = cylinder(
                bot, length, -length / 2, mat, rgba, (0.0, 0.0), 20, name, spec.fill, top
            )
        else:
            prof = [(r * radius, t * length - length / 2) for r, t in spec.profile]
            part = revolved(prof, mat, rgba, sections=20, name=name, fill=spec.fill)
        tf = _axis_frame(spec.axis)
        tf[:3, 3] = centre
        s.add(_place(part, tf))
    elif spec.shape == "shell":
        r_top = float(min(ext[0], ext[1])) / 2
        r_bot = r_top * spec.taper
        if r_bot > r_top:
            r_top, r_bot = r_top / spec.taper, r_top
        wall = spec.wall * min(r_top, r_bot) * 2
        bottom = min(max(wall, 0.06 * float(ext[2])), 0.3 * float(ext[2]))
        s.add(
            shell_part(
                r_bot,
                r_top,
                float(ext[2]),
                wall,
                bottom,
                mat,
                rgba,
                float(lo[2]),
                12,
                name,
                (float(centre[0]), float(centre[1])),
            )
        )
        inner = 0.7 * (min(r_top, r_bot) - wall)
        cx, cy = float(centre[0]), float(centre[1])
        s.containers.append(
            Container(
                "interior",
                (cx - inner, cy - inner, float(lo[2]) + bottom),
                (cx + inner, cy + inner, float(hi[2])),
            )
        )
        s.supports.append(
            Support(
                "inside", float(lo[2]) + bottom, (cx - inner, cy - inner, cx + inner, cy + inner)
            )
        )
        return
    elif spec.shape == "tray":
        _tray(s, lo, hi, spec, mat, rgba, name)
        return
    elif spec.shape == "prism":
        s.add(_prism(lo, hi, spec, mat, rgba, name))
    if spec.support:
        s.supports.append(Support(name, float(hi[2]), (lo[0], lo[1], hi[0], hi[1])))


def _bar(
    a: np.ndarray, b: np.ndarray, t: float, mat: str, rgba: RGBA, name: str, fill: float
) -> Part:
    v = b - a
    length = float(np.linalg.norm(v))
    if length < 1e-9:
        raise GrammarError(f"{name}: a bar needs two different end points")
    part = cylinder(t / 2, length, -length / 2, mat, rgba, (0.0, 0.0), 12, name, fill)
    tf = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], v / length)
    tf[:3, 3] = (a + b) / 2
    return _place(part, tf)


def _tray(
    s: Shape, lo: np.ndarray, hi: np.ndarray, spec: PartSpec, mat: str, rgba: RGBA, name: str
) -> None:
    ext = hi - lo
    c = (lo + hi) / 2
    t = spec.wall * float(min(ext[0], ext[1]))
    floor = min(t, 0.3 * float(ext[2]))
    wall_h = float(ext[2]) - floor
    zc = float(lo[2]) + floor + wall_h / 2
    s.add(
        box(
            (ext[0], ext[1], floor),
            (c[0], c[1], lo[2] + floor / 2),
            mat,
            rgba,
            f"{name}_floor",
            spec.fill,
        )
    )
    for k, sy in enumerate((-1, 1)):
        y = c[1] + sy * (ext[1] / 2 - t / 2)
        s.add(box((ext[0], t, wall_h), (c[0], y, zc), mat, rgba, f"{name}_wall_{k}", spec.fill))
    for k, sx in enumerate((-1, 1)):
        x = c[0] + sx * (ext[0] / 2 - t / 2)
        s.add(
            box(
                (t, ext[1] - 2 * t, wall_h), (x, c[1], zc), mat, rgba, f"{name}_side_{k}", spec.fill
            )
        )
    inner_lo = (lo[0] + t, lo[1] + t, lo[2] + floor)
    inner_hi = (hi[0] - t, hi[1] - t, hi[2])
    s.containers.append(Container("interior", inner_lo, inner_hi))
    s.supports.append(
        Support(
            f"{name}_floor", lo[2] + floor, (inner_lo[0], inner_lo[1], inner_hi[0], inner_hi[1])
        )
    )


def _prism(lo: np.ndarray, hi: np.ndarray, spec: PartSpec, mat: str, rgba: RGBA, name: str) -> Part:
    i = AXES.index(spec.axis)
    u, v = (j for j in range(3) if j != i)
    poly = np.asarray(spec.polygon, float)
    pts = np.column_stack(
        [lo[u] + poly[:, 0] * (hi[u] - lo[u]), lo[v] + poly[:, 1] * (hi[v] - lo[v])]
    )
    n = len(pts)
    tris = np.array([(0, k, k + 1) for k in range(1, n - 1)])
    mesh = trimesh.creation.extrude_triangulation(pts, tris, float(hi[i] - lo[i]))
    verts = np.asarray(mesh.vertices, float)
    out = np.zeros_like(verts)
    out[:, u], out[:, v], out[:, i] = verts[:, 0], verts[:, 1], verts[:, 2] + lo[i]
    mesh = trimesh.Trimesh(out, mesh.faces, process=True)
    if mesh.volume < 0:
        mesh.invert()
    return Part(mesh, [mesh.convex_hull], mat, rgba, spec.fill, name)
