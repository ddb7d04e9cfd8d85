"""Templates for fixtures and decor that boxes and cylinders drew weakly: toilets (pedestal,
bowl, seat, lid, cistern), wall clocks (rim, dial, marks, hands), lamps (base, stem, open
shade), potted plants (pot, soil, leaves) and curtains (rod and pleated panels).

Same contract as :mod:`.templates`: extents ``d = (width, length, height)`` (m), front at -y,
object frame. Visual details that lie inside another part's collision (a clock's hands, a
plant's stem and leaves inside its crown) have no collision of their own; every piece of
collision is a convex hull of at most 64 vertices.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from factory.assets.geometry import Part, Shape, box, cylinder, ellipsoid, shell
from factory.assets.primitives import moved, pleated, revolved, ring, rounded_box

RGBA = tuple[float, float, float, float]
_WHITE: RGBA = (0.97, 0.97, 0.96, 1.0)
_DARK: RGBA = (0.07, 0.07, 0.08, 1.0)
_CHROME: RGBA = (0.82, 0.83, 0.85, 1.0)


def _scale_about(part: Part, sx: float, sy: float, about: tuple[float, float]) -> Part:
    """Scales a part in x and y about the vertical line through ``about`` (an oval from a
    round part; revolved UVs are measured on the final mesh, hulls stay convex)."""
    tf = np.diag([sx, sy, 1.0, 1.0])
    tf[0, 3] = about[0] * (1 - sx)
    tf[1, 3] = about[1] * (1 - sy)
    part.visual.apply_transform(tf)
    for c in part.collision:
        c.apply_transform(tf)
    return part


def toilet(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """An oval pedestal and bowl, a seat ring and a closed lid, and a cistern with a lid and
    a flush button at +y."""
    w, ln, h = d
    s = Shape()
    mat, col = mats[0], cols[0]
    tank_l = 0.22 * ln
    bowl_l = ln - tank_l
    yb = -ln / 2 + bowl_l / 2
    r = w / 2
    sy = (bowl_l / 2) / r
    seat_t = 0.02
    rim = 0.5 * h - seat_t - 0.012
    bowl_h = 0.35 * rim
    z_b = rim - bowl_h
    ped = revolved(
        [(0.55 * r, 0.0), (0.5 * r, 0.03), (0.42 * r, 0.45 * z_b), (0.74 * r, z_b)],
        mat,
        col,
        xy=(0.0, yb),
        sections=24,
        name="pedestal",
        fill=0.3,
    )
    s.add(_scale_about(ped, 1.0, sy * 0.9, (0.0, yb)))
    bowl = shell(
        0.74 * r, 0.98 * r, bowl_h, 0.02, 0.02, mat, col, z0=z_b, xy=(0.0, yb), name="bowl"
    )
    s.add(_scale_about(bowl, 1.0, sy, (0.0, yb)))
    seat = ring(
        [(0.6 * r, 0.0), (r, 0.0), (r, 0.6 * seat_t), (0.95 * r, seat_t), (0.64 * r, seat_t)],
        "plastic",
        _WHITE,
        z0=rim,
        xy=(0.0, yb),
        segments=8,
        name="seat",
    )
    s.add(_scale_about(seat, 1.0, sy, (0.0, yb)))
    lid = revolved(
        [(0.97 * r, 0.0), (0.97 * r, 0.004), (0.9 * r, 0.012)],
        "plastic",
        _WHITE,
        z0=rim + seat_t,
        xy=(0.0, yb),
        name="lid",
        collision="hull",
    )
    s.add(_scale_about(lid, 1.0, sy, (0.0, yb)))
    tz0 = rim - 0.04
    ty = ln / 2 - tank_l / 2
    s.add(
        rounded_box(
            (0.45 * w, 0.9 * tank_l, tz0),
            (0.0, ty, tz0 / 2),
            mat,
            col,
            radius=0.03,
            name="trap",
            fill=0.3,
        )
    )
    th = h - 0.022 - tz0
    s.add(
        rounded_box((0.9 * w, tank_l, th), (0.0, ty, tz0 + th / 2), mat, col, 0.025, "cistern", 0.3)
    )
    s.add(
        rounded_box(
            (0.94 * w, tank_l, 0.02), (0.0, ty, h - 0.014), mat, col, 0.008, "cistern_lid", 1.0
        )
    )
    s.add(cylinder(0.02, 0.006, h - 0.006, "steel", _CHROME, (0.0, ty), 16, "flush_button"))
    return s


def clock(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A round wall clock facing -y: a rim, a dial with twelve marks, hour and minute hands
    (set to a random time) and a centre cap; its back is against the wall (+y)."""
    w, depth, h = d
    s = Shape()
    r = min(w, h) / 2
    parts: list[Part] = [
        cylinder(0.93 * r, 0.5 * depth, 0.0, mats[0], cols[0], sections=24, name="body"),
        cylinder(
            0.9 * r, 0.08 * depth, 0.5 * depth, "paper", (0.95, 0.94, 0.9, 1.0), (0, 0), 24, "dial"
        ),
        ring(
            [
                (0.88 * r, 0.0),
                (r, 0.0),
                (r, 0.85 * depth),
                (0.96 * r, depth),
                (0.91 * r, depth),
                (0.88 * r, 0.8 * depth),
            ],
            mats[0],
            cols[0],
            segments=6,
            name="rim",
        ),
    ]
    z_mark = 0.58 * depth
    marks = []
    for k in range(12):
        a = 2 * math.pi * k / 12
        big = k % 3 == 0
        length, width = (0.16 * r, 0.045 * r) if big else (0.09 * r, 0.025 * r)
        rad = 0.78 * r - length / 2 + 0.04 * r
        m = box(
            (width, length, 0.02 * depth),
            (rad * math.sin(a), rad * math.cos(a), z_mark + 0.01 * depth),
            "plastic",
            _DARK,
            yaw=-a,
        )
        marks.append(m.visual)
    mark_mesh = trimesh.util.concatenate(marks)
    assert isinstance(mark_mesh, trimesh.Trimesh)
    parts.append(Part(mark_mesh, [], "plastic", _DARK, name="marks"))
    hour = float(rng.uniform(0, 12))
    for name, angle, length, width, z in (
        ("hour_hand", 2 * math.pi * hour / 12, 0.5 * r, 0.06 * r, 0.62 * depth),
        ("minute_hand", 2 * math.pi * (hour % 1), 0.78 * r, 0.04 * r, 0.67 * depth),
    ):
        c = 0.5 * length - 0.1 * r
        hand = box(
            (width, length, 0.03 * depth),
            (c * math.sin(angle), c * math.cos(angle), z),
            "plastic",
            _DARK,
            name,
            yaw=-angle,
        )
        hand.collision = []
        parts.append(hand)
    cap = cylinder(0.06 * r, 0.1 * depth, 0.6 * depth, "plastic", _DARK, (0, 0), 12, "cap")
    cap.collision = []
    parts.append(cap)
    tf = trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0])
    tf[:3, 3] = [0.0, depth / 2, h / 2]
    for p in parts:
        s.add(moved(p, tf))
    return s


def lamp(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A lamp: a weighted disc foot and a stem, or (table lamps) a bulbous ceramic body; an
    open, thin-walled shade (a truncated cone) over the stem's end. The shade's collision is
    the solid cone, as before."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    shade_h = float(rng.uniform(0.25, 0.35)) * h
    r_top = float(rng.uniform(0.6, 0.8)) * r
    z_shade = h - shade_h
    stem_top = z_shade + 0.45 * shade_h
    stem_r = max(0.008, 0.05 * r)
    if h < 1.0 and rng.integers(2):
        body_h = float(rng.uniform(0.45, 0.6)) * z_shade
        s.add(
            revolved(
                [
                    (0.32 * r, 0.0),
                    (0.36 * r, 0.04 * body_h),
                    (0.55 * r, 0.4 * body_h),
                    (0.48 * r, 0.75 * body_h),
                    (0.22 * r, 0.93 * body_h),
                    (0.16 * r, body_h),
                ],
                mats[1],
                cols[1],
                sections=16,
                name="body",
                fill=0.4,
            )
        )
        z_stem = body_h
    else:
        foot = max(0.015, 0.035 * h)
        s.add(
            revolved(
                [(0.6 * r, 0.0), (0.6 * r, 0.4 * foot), (0.5 * r, foot), (0.12 * r, 1.3 * foot)],
                mats[1],
                cols[1],
                sections=16,
                name="foot",
            )
        )
        z_stem = 1.3 * foot
    s.add(cylinder(stem_r, stem_top - z_stem, z_stem, mats[1], cols[1], name="stem", sections=10))
    wall = max(0.003, 0.015 * r)
    shade = ring(
        [(r - wall, 0.0), (r, 0.0), (r_top, shade_h), (r_top - wall, shade_h)],
        "fabric",
        cols[0],
        z0=z_shade,
        segments=6,
        name="shade",
        fill=0.05,
    )
    shade.collision = cylinder(r, shade_h, z_shade, "fabric", cols[0], radius_top=r_top).collision
    s.add(shade)
    return s


def _leaf(length: float, width: float, thick: float, droop: float) -> trimesh.Trimesh:
    """A closed, lens-shaped leaf along +x from the origin: a four-point outline (stalk end,
    two widest points, tip) around a raised midrib, its tip drooping by ``droop`` (m)."""
    v = np.array(
        [
            [0.0, 0.0, 0.0],
            [0.4 * length, 0.5 * width, 0.0],
            [length, 0.0, 0.0],
            [0.4 * length, -0.5 * width, 0.0],
            [0.4 * length, 0.0, thick],
            [0.4 * length, 0.0, -thick],
        ]
    )
    v[:, 2] -= droop * (v[:, 0] / length) ** 2
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces += [(4, j, i), (5, i, j)]
    return trimesh.Trimesh(v, np.array(faces), process=False)


def _placed_leaf(
    leaf: trimesh.Trimesh, pitch: float, yaw: float, at: tuple[float, float, float]
) -> trimesh.Trimesh:
    m = leaf.copy()
    m.apply_transform(trimesh.transformations.rotation_matrix(-pitch, [0, 1, 0]))
    m.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
    m.apply_translation(at)
    return m


def plant(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A flared pot with a lip and soil, and leaves: a rosette of leaves rising from the soil
    (broad or sword-like), or a stem with a crown of leaves (tall plants). The crown's
    collision is the ellipsoid it fills, as before."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    pot_h = float(rng.uniform(0.3, 0.4)) * h
    soil = 0.92 * pot_h
    s.add(
        revolved(
            [(0.56 * r, 0.0), (0.6 * r, 0.03 * pot_h), (0.74 * r, soil)],
            mats[0],
            cols[0],
            sections=16,
            name="pot",
            collision="hull",
        )
    )
    lip = ring(
        [(0.66 * r, 0.0), (0.8 * r, 0.0), (0.8 * r, pot_h - soil), (0.7 * r, pot_h - soil)],
        mats[0],
        cols[0],
        z0=soil,
        segments=6,
        name="lip",
    )
    lip.collision = []
    s.add(lip)
    dirt = cylinder(
        0.69 * r, 0.4 * (pot_h - soil), soil, "soil", (0.25, 0.18, 0.11, 1.0), sections=12
    )
    dirt.collision = []
    dirt.name = "soil"
    s.add(dirt)
    crown = h - pot_h
    leaves = []
    if h > 0.6 and rng.integers(3):  # a stem and a crown
        stem_top = pot_h + 0.55 * crown
        trunk = cylinder(
            max(0.008, 0.04 * r),
            stem_top - soil,
            soil,
            "plant",
            cols[1],  # the leaves' look: one draw for the stem and the crown
            name="stem",
            sections=8,
        )
        trunk.collision = []
        s.add(trunk)
        cz, cr, ch = pot_h + 0.58 * crown, 0.9 * r, 0.38 * crown
        for _ in range(int(rng.integers(50, 64))):
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            rad = rng.uniform(0.35, 1.0)
            at = (u[0] * cr * rad, u[1] * cr * rad, cz + u[2] * ch * rad)
            size = float(rng.uniform(0.42, 0.58)) * r
            leaf = _leaf(size, 0.45 * size, 0.06 * size, 0.15 * size)
            yaw = math.atan2(at[1], at[0]) + rng.uniform(-0.6, 0.6)
            leaves.append(_placed_leaf(leaf, float(rng.uniform(-0.3, 0.7)), yaw, at))
    else:  # a rosette from the soil
        sword = bool(rng.integers(2))
        n = int(rng.integers(9, 15))
        for k in range(n):
            pitch = float(rng.uniform(1.05, 1.4) if sword else rng.uniform(0.55, 1.2))
            reach = (h - soil) * float(rng.uniform(0.75, 1.0)) / math.sin(pitch)
            reach = min(reach, 0.95 * r / max(math.cos(pitch), 1e-3))
            width = (0.12 if sword else 0.32) * reach
            leaf = _leaf(reach, width, 0.04 * width, (0.03 if sword else 0.15) * reach)
            yaw = 2 * math.pi * (k + rng.uniform(-0.2, 0.2)) / n
            base = (0.1 * r * math.cos(yaw), 0.1 * r * math.sin(yaw), soil)
            leaves.append(_placed_leaf(leaf, pitch, yaw, base))
    foliage = trimesh.util.concatenate(leaves)
    assert isinstance(foliage, trimesh.Trimesh)
    crown_hull = ellipsoid((r, r, crown / 2), (0, 0, pot_h + crown / 2), "plant", cols[1])
    s.add(Part(foliage, crown_hull.collision, "plant", cols[1], 0.15, "leaves"))
    return s


def curtain(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A rod on two brackets with finials and one or two pleated panels hanging from it to
    the floor, drawn open by a random amount (width along x; the wall is at +y)."""
    w, ln, h = d
    s = Shape()
    rod_r = float(np.clip(0.12 * ln, 0.008, 0.016))
    fin = 1.8 * rod_r
    z_rod = h - fin
    rod = cylinder(rod_r, w - 2 * fin, -(w - 2 * fin) / 2, mats[1], cols[1], name="rod")
    rot = trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0])
    rot[:3, 3] = [0.0, 0.0, z_rod]
    s.add(moved(rod, rot))
    for k, sx in enumerate((-1, 1)):
        s.add(
            ellipsoid(
                (fin, fin, fin), (sx * (w / 2 - fin), 0.0, z_rod), mats[1], cols[1], f"finial_{k}"
            )
        )
        s.add(
            box(
                (0.012, ln / 2, 0.02),
                (sx * (w / 2 - 3 * fin), ln / 4, z_rod),
                mats[1],
                cols[1],
                f"bracket_{k}",
            )
        )
    drop = z_rod - rod_r
    panels = 2 if rng.integers(4) else 1
    for k in range(panels):
        pw = float(rng.uniform(0.26, 0.45) if panels == 2 else rng.uniform(0.45, 0.85)) * w
        sx = -1 if (k == 0) else 1
        x = sx * (w / 2 - 2 * fin - pw / 2)
        folds = max(3, round(pw / 0.11))
        s.add(
            pleated(
                pw,
                0.8 * ln,
                drop,
                min(0.008, 0.1 * ln),
                folds,
                (x, 0.0, drop / 2),
                mats[0],
                cols[0],
                f"panel_{k}",
                0.08,
                gather=float(rng.uniform(0.85, 0.95)),
            )
        )
    return s
