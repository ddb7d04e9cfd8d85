"""Shape templates: parametric builders that categories share.

Each template takes the requested extents ``d = (width, length, height)`` (m; the result's
bounding box matches them), two materials and two colours (primary, secondary), and a random
generator for style details (leg shape, number of boards, proportions), and returns a
:class:`~.geometry.Shape` in the object frame (z up, centred in x and y, bottom at z = 0; the
front faces -y).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from factory.assets.geometry import (
    Container,
    Shape,
    Support,
    box,
    cylinder,
    ellipsoid,
    frame_box,
    shell,
)

RGBA = tuple[float, float, float, float]
Template = Callable[[np.ndarray, tuple[str, str], tuple[RGBA, RGBA], np.random.Generator], Shape]


def _legs(
    shape: Shape,
    w: float,
    ln: float,
    h: float,
    t: float,
    mat: str,
    rgba: RGBA,
    round_legs: bool,
    inset: float = 0.0,
) -> None:
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
        x = sx * (w / 2 - t / 2 - inset)
        y = sy * (ln / 2 - t / 2 - inset)
        if round_legs:
            shape.add(cylinder(t / 2, h, 0.0, mat, rgba, (x, y), 12, f"leg_{k}"))
        else:
            shape.add(box((t, t, h), (x, y, h / 2), mat, rgba, f"leg_{k}"))


def table(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A top on four legs (dining/coffee/side tables, desks)."""
    w, ln, h = d
    s = Shape()
    top = float(np.clip(0.04 * h + 0.01, 0.02, 0.06))
    leg = float(np.clip(0.06 * min(w, ln), 0.03, 0.08))
    s.add(box((w, ln, top), (0, 0, h - top / 2), mats[0], cols[0], "top"))
    _legs(s, w, ln, h - top, leg, mats[1], cols[1], bool(rng.integers(2)), inset=0.02 * min(w, ln))
    s.supports.append(Support("top", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return s


def desk(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A top on a drawer pedestal and two legs."""
    w, ln, h = d
    s = Shape()
    top = 0.03
    s.add(box((w, ln, top), (0, 0, h - top / 2), mats[0], cols[0], "top"))
    pw = min(0.4, 0.35 * w)
    side = 1 if rng.integers(2) else -1
    s.add(
        box(
            (pw, ln * 0.9, h - top),
            (side * (w / 2 - pw / 2), 0, (h - top) / 2),
            mats[0],
            cols[1],
            "pedestal",
        )
    )
    for k, y in enumerate((-ln / 2 + 0.03, ln / 2 - 0.03)):
        s.add(
            box(
                (0.04, 0.04, h - top),
                (-side * (w / 2 - 0.02), y * 0.95, (h - top) / 2),
                mats[1],
                cols[1],
                f"leg_{k}",
            )
        )
    s.supports.append(Support("top", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return s


def chair(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Seat on four legs with a backrest (at +y)."""
    w, ln, h = d
    s = Shape()
    seat_h = float(np.clip(0.5 * h, 0.3, 0.5))
    seat_t = 0.04
    s.add(box((w, ln, seat_t), (0, 0, seat_h - seat_t / 2), mats[0], cols[0], "seat"))
    _legs(s, w, ln, seat_h - seat_t, 0.035, mats[1], cols[1], bool(rng.integers(2)))
    back_t = 0.04
    s.add(
        box(
            (w, back_t, h - seat_h),
            (0, ln / 2 - back_t / 2, seat_h + (h - seat_h) / 2),
            mats[0],
            cols[0],
            "back",
        )
    )
    s.supports.append(Support("seat", seat_h, (-w / 2, -ln / 2, w / 2, ln / 2 - back_t)))
    return s


def stool(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A round or square seat on legs (stools, bar stools, benches)."""
    w, ln, h = d
    s = Shape()
    t = 0.04
    if rng.integers(2) and abs(w - ln) < 1e-6:
        s.add(cylinder(w / 2, t, h - t, mats[0], cols[0], name="seat", sections=20))
        s.add(cylinder(0.025, h - t, 0.0, mats[1], cols[1], name="post"))
        s.add(cylinder(0.45 * w, 0.02, 0.0, mats[1], cols[1], name="foot"))
    else:
        s.add(box((w, ln, t), (0, 0, h - t / 2), mats[0], cols[0], "seat"))
        _legs(s, w, ln, h - t, 0.035, mats[1], cols[1], bool(rng.integers(2)))
    s.supports.append(Support("seat", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return s


def sofa(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Upholstered base, back (at +y) and arms: sofas, armchairs, loveseats."""
    w, ln, h = d
    s = Shape()
    seat_h = 0.45 * h
    arm = float(np.clip(0.12 * w, 0.08, 0.2))
    back = float(np.clip(0.22 * ln, 0.12, 0.25))
    fill = 0.12
    s.add(
        box(
            (w - 2 * arm, ln - back, seat_h),
            (0, -back / 2, seat_h / 2),
            mats[0],
            cols[0],
            "base",
            fill,
        )
    )
    s.add(box((w, back, h), (0, ln / 2 - back / 2, h / 2), mats[0], cols[0], "back", fill))
    arm_h = seat_h + float(rng.uniform(0.1, 0.2)) * h
    for k, sx in enumerate((-1, 1)):
        s.add(
            box(
                (arm, ln - back, arm_h),
                (sx * (w / 2 - arm / 2), -back / 2, arm_h / 2),
                mats[0],
                cols[1],
                f"arm_{k}",
                fill,
            )
        )
    s.supports.append(Support("seat", seat_h, (-w / 2 + arm, -ln / 2, w / 2 - arm, ln / 2 - back)))
    return s


def bed(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Frame, mattress and a headboard at +y."""
    w, ln, h = d
    s = Shape()
    frame_h = 0.25 * h
    mat_h = 0.22 * h
    head_t = 0.06
    s.add(
        box(
            (w, ln - head_t, frame_h),
            (0, -head_t / 2, frame_h / 2),
            mats[1],
            cols[1],
            "frame",
            0.06,
        )
    )
    s.add(
        box(
            (w * 0.97, (ln - head_t) * 0.98, mat_h),
            (0, -head_t / 2, frame_h + mat_h / 2),
            "foam",
            cols[0],
            "mattress",
            1.0,
        )
    )
    s.add(box((w, head_t, h), (0, ln / 2 - head_t / 2, h / 2), mats[1], cols[1], "headboard", 0.5))
    top = frame_h + mat_h
    s.supports.append(Support("mattress", top, (-w * 0.48, -ln / 2, w * 0.48, ln / 2 - head_t)))
    return s


def case(boards_range: tuple[int, int], open_front: bool, open_top: bool = False) -> Template:
    """A panel case: shelves and bookcases (open front, boards), cabinets, appliances."""

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        t = float(np.clip(0.02 * max(w, h), 0.012, 0.03))
        boards = int(rng.integers(boards_range[0], boards_range[1] + 1))
        parts, supports, containers = frame_box(
            (w, ln, h), t, mats[0], cols[0], open_front, open_top, boards
        )
        s = Shape(parts, supports, containers)
        return s

    return build


def appliance(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A closed box body with a front panel line and a handle (fridges, ovens, washers)."""
    w, ln, h = d
    s = Shape()
    hd = min(0.03, 0.1 * ln)
    s.add(box((w, ln - hd, h), (0, hd / 2, h / 2), mats[0], cols[0], "body", 0.08))
    hh = min(0.6 * h, 0.4)
    s.add(
        box(
            (0.02, hd, hh),
            (w / 2 - 0.08 * w, -ln / 2 + hd / 2, h * 0.6),
            mats[1],
            cols[1],
            "handle",
        )
    )
    s.supports.append(Support("top", h, (-w / 2, -ln / 2 + hd, w / 2, ln / 2)))
    return s


def block(fill: float = 1.0) -> Template:
    """A plain box (books, boxes, rugs, panels, devices)."""

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        s = Shape()
        s.add(box((w, ln, h), (0, 0, h / 2), mats[0], cols[0], "body", fill))
        s.supports.append(Support("top", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
        return s

    return build


def book(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Covers around a block of pages."""
    w, ln, h = d
    s = Shape()
    c = min(0.003, 0.1 * h)
    s.add(box((w, ln, c), (0, 0, c / 2), "cardboard", cols[0], "cover_bottom"))
    s.add(box((w, ln, c), (0, 0, h - c / 2), "cardboard", cols[0], "cover_top"))
    s.add(box((w - 0.006, ln - 0.004, h - 2 * c), (0.003, 0, h / 2), "paper", cols[1], "pages"))
    s.add(box((0.006, ln, h - 2 * c), (-w / 2 + 0.003, 0, h / 2), "cardboard", cols[0], "spine"))
    s.supports.append(Support("top", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return s


def panel(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A thin framed panel for walls (paintings, mirrors, boards, screens): faces -y."""
    w, ln, h = d
    s = Shape()
    f = min(0.04, 0.1 * min(w, h))
    s.add(box((w, ln * 0.6, h), (0, ln * 0.2, h / 2), mats[1], cols[1], "canvas"))
    for k, (ext, c) in enumerate(
        (
            ((w, ln, f), (0, 0, f / 2)),
            ((w, ln, f), (0, 0, h - f / 2)),
            ((f, ln, h - 2 * f), (-w / 2 + f / 2, 0, h / 2)),
            ((f, ln, h - 2 * f), (w / 2 - f / 2, 0, h / 2)),
        )
    ):
        s.add(box(ext, c, mats[0], cols[0], f"frame_{k}"))
    return s


def screen(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A display on a stand (TVs, monitors)."""
    w, ln, h = d
    s = Shape()
    stand_h = 0.18 * h
    s.add(box((0.4 * w, ln, 0.02), (0, 0, 0.01), mats[1], cols[1], "foot"))
    s.add(box((0.06, 0.04, stand_h), (0, 0, stand_h / 2 + 0.01), mats[1], cols[1], "neck"))
    s.add(
        box(
            (w, min(ln, 0.05), h - stand_h),
            (0, 0, stand_h + (h - stand_h) / 2),
            mats[0],
            cols[0],
            "display",
        )
    )
    return s


def laptop(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Base and an opened lid leaning back (at +y)."""
    w, ln, h = d
    s = Shape()
    base_t = min(0.02, 0.2 * h)
    s.add(box((w, ln * 0.9, base_t), (0, -ln * 0.05, base_t / 2), mats[0], cols[0], "base"))
    s.add(
        box(
            (w, ln * 0.1, h - base_t),
            (0, ln * 0.45, base_t + (h - base_t) / 2),
            mats[0],
            cols[1],
            "lid",
        )
    )
    return s


def vessel(r_ratio: float, wall: float, handle: bool = False, lid: bool = False) -> Template:
    """Hollow open containers: mugs, cups, bowls, vases, bins, buckets, pots, glasses.

    ``r_ratio`` is the base radius over the rim radius (1: straight, < 1: flaring).
    """

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        s = Shape()
        hw = 0.0
        if handle:
            hw = min(0.25 * w, 0.03)
        body_w = w - hw
        r_top = min(body_w, ln) / 2
        r_bot = r_top * r_ratio
        wall_t = max(0.002, wall * r_top)
        cx = -hw / 2
        bottom = min(max(0.008, 0.08 * h), 0.3 * h)
        part = shell(r_bot, r_top, h, wall_t, bottom, mats[0], cols[0], xy=(cx, 0.0), name="vessel")
        s.add(part)
        if handle:
            hx = cx + r_top + hw / 2
            t = min(0.012, hw / 2)
            s.add(box((hw, t, t), (hx - t / 2, 0, 0.25 * h), mats[0], cols[0], "handle_low"))
            s.add(box((hw, t, t), (hx - t / 2, 0, 0.75 * h), mats[0], cols[0], "handle_high"))
            s.add(
                box(
                    (t, t, 0.5 * h + t),
                    (cx + r_top + hw - t / 2, 0, 0.5 * h),
                    mats[0],
                    cols[0],
                    "handle_grip",
                )
            )
        inner = r_top - wall_t
        s.containers.append(
            Container(
                "interior",
                (cx - inner * 0.7, -inner * 0.7, bottom),
                (cx + inner * 0.7, inner * 0.7, h),
            )
        )
        s.supports.append(
            Support(
                "inside", bottom, (cx - r_bot * 0.6, -r_bot * 0.6, cx + r_bot * 0.6, r_bot * 0.6)
            )
        )
        return s

    return build


def plate(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A shallow dish: a disc with a flaring rim."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    s.add(
        shell(0.7 * r, r, h, 0.006, min(0.006, 0.4 * h), mats[0], cols[0], segments=16, name="dish")
    )
    s.supports.append(Support("dish", min(0.006, 0.4 * h), (-0.6 * r, -0.6 * r, 0.6 * r, 0.6 * r)))
    return s


def bottle(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A body, a tapering shoulder, a neck and a cap (bottles, jars with ``neck`` short)."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    body_h = float(rng.uniform(0.55, 0.65)) * h
    neck_r = 0.35 * r
    s.add(cylinder(r, body_h, 0.0, mats[0], cols[0], name="body"))
    sh = 0.15 * h
    s.add(cylinder(r, sh, body_h, mats[0], cols[0], name="shoulder", radius_top=neck_r))
    s.add(cylinder(neck_r, h - body_h - sh - 0.02 * h, body_h + sh, mats[0], cols[0], name="neck"))
    s.add(cylinder(neck_r * 1.1, 0.02 * h, h - 0.02 * h, mats[1], cols[1], name="cap"))
    return s


def can(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A solid cylinder with a lid band (cans, jars, candles, cylinders of all kinds)."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    s.add(cylinder(r, 0.9 * h, 0.0, mats[0], cols[0], name="body"))
    s.add(cylinder(r * 0.97, 0.1 * h, 0.9 * h, mats[1], cols[1], name="lid"))
    s.supports.append(Support("top", h, (-0.7 * r, -0.7 * r, 0.7 * r, 0.7 * r)))
    return s


def fruit(elong: float = 1.0) -> Template:
    """Round produce (apples, oranges, lemons, tomatoes, eggs): an ellipsoid with a stem."""

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        s = Shape()
        stem = 0.06 * h if elong <= 1.0 else 0.0
        s.add(
            ellipsoid(
                (w / 2, ln / 2, (h - stem) / 2), (0, 0, (h - stem) / 2), mats[0], cols[0], "flesh"
            )
        )
        if stem:
            s.add(
                cylinder(
                    0.05 * w,
                    stem + 0.02 * h,
                    h - stem - 0.02 * h,
                    "plant",
                    (0.35, 0.25, 0.12, 1),
                    name="stem",
                    sections=8,
                )
            )
        return s

    return build


def banana(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A curved chain of convex segments (length along x)."""
    w, ln, h = d
    s = Shape()
    n = 5
    seg_w = w / n
    sag = h - ln * 0.8
    for k in range(n):
        x = -w / 2 + seg_w * (k + 0.5)
        u = (x / (w / 2)) ** 2
        z = sag * u
        s.add(
            ellipsoid(
                (seg_w * 0.95, ln / 2, ln * 0.42),
                (x, 0, z + ln * 0.42),
                mats[0],
                cols[0],
                f"segment_{k}",
            )
        )
    return s


def lamp(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A base, a pole and a shade (table and floor lamps)."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    base_h = 0.05 * h
    shade_h = float(rng.uniform(0.25, 0.35)) * h
    s.add(cylinder(0.6 * r, base_h, 0.0, mats[1], cols[1], name="base"))
    s.add(
        cylinder(
            max(0.01, 0.06 * r),
            h - base_h - shade_h,
            base_h,
            mats[1],
            cols[1],
            name="pole",
            sections=8,
        )
    )
    s.add(
        cylinder(
            r, shade_h, h - shade_h, "fabric", cols[0], name="shade", radius_top=0.7 * r, fill=0.05
        )
    )
    return s


def plant(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A pot with soil and a leafy crown."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    pot_h = float(rng.uniform(0.3, 0.4)) * h
    s.add(cylinder(0.7 * r, pot_h, 0.0, mats[0], cols[0], name="pot", radius_top=0.8 * r))
    crown = h - pot_h
    s.add(ellipsoid((r, r, crown / 2), (0, 0, pot_h + crown / 2), "plant", cols[1], "leaves", 0.15))
    return s


def toilet(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A pedestal, a bowl and a cistern at +y."""
    w, ln, h = d
    s = Shape()
    seat_h = 0.5 * h
    tank_l = 0.22 * ln
    s.add(
        box(
            (0.5 * w, 0.5 * ln, seat_h * 0.8),
            (0, -0.05 * ln, seat_h * 0.4),
            mats[0],
            cols[0],
            "pedestal",
            0.3,
        )
    )
    s.add(
        shell(
            0.35 * w,
            0.5 * min(w, ln - tank_l),
            0.2 * seat_h,
            0.01,
            0.01,
            mats[0],
            cols[0],
            z0=seat_h * 0.8,
            xy=(0.0, -tank_l / 2),
            name="bowl",
        )
    )
    s.add(
        box(
            (w, tank_l, h - seat_h * 0.8),
            (0, ln / 2 - tank_l / 2, seat_h * 0.8 + (h - seat_h * 0.8) / 2),
            mats[0],
            cols[0],
            "cistern",
            0.3,
        )
    )
    return s


def basin(depth_ratio: float) -> Template:
    """A box with a rectangular hollow (sinks, bathtubs, planters, toy boxes)."""

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        s = Shape()
        t = float(np.clip(0.05 * min(w, ln), 0.01, 0.06))
        depth = depth_ratio * h
        s.add(box((w, ln, h - depth), (0, 0, (h - depth) / 2), mats[0], cols[0], "base", 0.5))
        z0 = h - depth
        for k, (ext, c) in enumerate(
            (
                ((w, t, depth), (0, -ln / 2 + t / 2, z0 + depth / 2)),
                ((w, t, depth), (0, ln / 2 - t / 2, z0 + depth / 2)),
                ((t, ln - 2 * t, depth), (-w / 2 + t / 2, 0, z0 + depth / 2)),
                ((t, ln - 2 * t, depth), (w / 2 - t / 2, 0, z0 + depth / 2)),
            )
        ):
            s.add(box(ext, c, mats[0], cols[0], f"wall_{k}"))
        s.containers.append(
            Container("interior", (-w / 2 + t, -ln / 2 + t, z0), (w / 2 - t, ln / 2 - t, h))
        )
        s.supports.append(Support("interior", z0, (-w / 2 + t, -ln / 2 + t, w / 2 - t, ln / 2 - t)))
        return s

    return build


def dumbbell(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """Two weights on a bar (length along x)."""
    w, ln, h = d
    r = min(ln, h) / 2
    s = Shape()
    plate_w = 0.25 * w
    for k, sx in enumerate((-1, 1)):
        p = cylinder(r, plate_w, -plate_w / 2, mats[0], cols[0], name=f"weight_{k}")
        for m in (p.visual, *p.collision):
            m.apply_transform(_rot_y_to_x())
            m.apply_translation([sx * (w / 2 - plate_w / 2), 0, r])
        s.add(p)
    bar = cylinder(
        0.25 * r, w - 2 * plate_w, -(w - 2 * plate_w) / 2, mats[1], cols[1], name="bar", sections=10
    )
    for m in (bar.visual, *bar.collision):
        m.apply_transform(_rot_y_to_x())
        m.apply_translation([0, 0, r])
    s.add(bar)
    return s


def _rot_y_to_x() -> np.ndarray:
    import trimesh

    return trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0])


def ball(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A sphere (balls, ornaments); hollow balls use a low fill."""
    w, ln, h = d
    s = Shape()
    s.add(ellipsoid((w / 2, ln / 2, h / 2), (0, 0, h / 2), mats[0], cols[0], "ball", 0.1))
    return s


def teddy(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A sitting toy bear: body, head and ears of ellipsoids."""
    w, ln, h = d
    s = Shape()
    bh = 0.58 * h
    s.add(ellipsoid((w * 0.4, ln / 2, bh / 2), (0, 0, bh / 2), mats[0], cols[0], "body", 0.3))
    hr = 0.19 * h
    s.add(
        ellipsoid(
            (hr, min(hr, ln / 2), hr), (0, 0, h - 0.1 * h - hr), mats[0], cols[0], "head", 0.3
        )
    )
    for k, sx in enumerate((-1, 1)):
        s.add(
            ellipsoid(
                (0.06 * h, 0.03 * h, 0.05 * h),
                (sx * hr * 0.8, 0, h - 0.05 * h),
                mats[0],
                cols[1],
                f"ear_{k}",
                0.3,
            )
        )
    for k, sx in enumerate((-1, 1)):
        s.add(
            ellipsoid(
                (0.1 * w, 0.1 * w, 0.1 * h),
                (sx * w * 0.4, -ln * 0.2, 0.1 * h),
                mats[0],
                cols[0],
                f"paw_{k}",
                0.3,
            )
        )
    return s


def rack(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A pole on a round foot with hooks (coat racks, floor lamps without shade)."""
    w, ln, h = d
    r = min(w, ln) / 2
    s = Shape()
    s.add(cylinder(r, 0.03, 0.0, mats[0], cols[0], name="foot"))
    s.add(cylinder(0.02, h - 0.03, 0.03, mats[0], cols[0], name="pole", sections=10))
    for k in range(4):
        a = k * math.pi / 2
        s.add(
            box(
                (r * 0.8, 0.02, 0.02),
                (math.cos(a) * r * 0.4, math.sin(a) * r * 0.4, h - 0.1),
                mats[1],
                cols[1],
                f"hook_{k}",
                yaw=a,
            )
        )
    return s


def piano(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """An upright piano: body at +y and a keyboard shelf in front."""
    w, ln, h = d
    s = Shape()
    body_l = 0.55 * ln
    s.add(box((w, body_l, h), (0, ln / 2 - body_l / 2, h / 2), mats[0], cols[0], "body", 0.4))
    s.add(
        box(
            (w, ln - body_l, 0.08),
            (0, -ln / 2 + (ln - body_l) / 2, 0.72),
            mats[0],
            cols[0],
            "keybed",
        )
    )
    s.add(
        box(
            (w * 0.9, (ln - body_l) * 0.7, 0.02),
            (0, -ln / 2 + (ln - body_l) * 0.45, 0.77),
            "plastic",
            cols[1],
            "keys",
        )
    )
    for k, sx in enumerate((-1, 1)):
        s.add(
            box(
                (0.05, 0.05, 0.68),
                (sx * (w / 2 - 0.05), -ln / 2 + 0.025, 0.34),
                mats[0],
                cols[0],
                f"leg_{k}",
            )
        )
    return s
