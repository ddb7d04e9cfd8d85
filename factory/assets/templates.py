"""Shape templates: parametric builders that categories share.

Each template takes the requested extents ``d = (width, length, height)`` (m; the result's
bounding box matches them), two materials and two colours (primary, secondary), and a random
generator for style details (leg shape, number of boards, proportions), and returns a
:class:`~.geometry.Shape` in the object frame (z up, centred in x and y, bottom at z = 0; the
front faces -y).

Furniture with rounded edges (table tops, cases) uses :func:`.primitives.rounded_box`; the
upholstered templates live in :mod:`.upholstery`, fixtures and decor (toilet, clock, lamp,
plant, curtain) in :mod:`.fixtures` and appliances in :mod:`.appliances`, re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import trimesh

from factory.assets.appliances import dishwasher as dishwasher
from factory.assets.appliances import microwave as microwave
from factory.assets.appliances import oven as oven
from factory.assets.appliances import refrigerator as refrigerator
from factory.assets.appliances import washing_machine as washing_machine
from factory.assets.fixtures import clock as clock
from factory.assets.fixtures import curtain as curtain
from factory.assets.fixtures import lamp as lamp
from factory.assets.fixtures import plant as plant
from factory.assets.fixtures import toilet as toilet
from factory.assets.geometry import (
    Container,
    Part,
    Shape,
    Support,
    box,
    cylinder,
    ellipsoid,
    frame_box,
    shell,
)
from factory.assets.primitives import rounded_box
from factory.assets.upholstery import bed as bed
from factory.assets.upholstery import pillow as pillow
from factory.assets.upholstery import sofa as sofa

RGBA = tuple[float, float, float, float]
Template = Callable[[np.ndarray, tuple[str, str], tuple[RGBA, RGBA], np.random.Generator], Shape]
_PULL: RGBA = (0.72, 0.72, 0.74, 1.0)


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
    radius = min(0.45 * top, 0.02) if rng.integers(4) else 0.15 * top  # rounded or crisp
    s.add(
        rounded_box((w, ln, top), (0, 0, h - top / 2), mats[0], cols[0], radius, "top", segments=1)
    )
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
    s.add(
        rounded_box((w, ln, top), (0, 0, h - top / 2), mats[0], cols[0], 0.012, "top", segments=1)
    )
    pw = min(0.4, 0.35 * w)
    side = 1 if rng.integers(2) else -1
    s.add(
        rounded_box(
            (pw, ln * 0.9, h - top),
            (side * (w / 2 - pw / 2), 0, (h - top) / 2),
            mats[0],
            cols[1],
            0.008,
            "pedestal",
            segments=1,
        )
    )
    for k in range(3):  # drawer fronts and their pulls on the pedestal's front
        zc = (h - top) * (0.83 - 0.3 * k)
        dx = side * (w / 2 - pw / 2)
        front = rounded_box(
            (pw - 0.02, 0.006, 0.26 * (h - top)),
            (dx, -ln * 0.45 - 0.003, zc),
            mats[0],
            cols[1],
            0.002,
            f"drawer_{k}",
            segments=1,
        )
        s.add(front)
        s.add(box((0.1, 0.012, 0.012), (dx, -ln * 0.45 - 0.012, zc), "steel", _PULL, f"pull_{k}"))
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


def case(boards: tuple[int, int], open_front: bool, open_top: bool = False) -> Template:
    """A panel case with softened (bevelled) edges: shelves and bookcases (open front,
    boards), cabinets, wardrobes and dressers (closed front: doors or drawers with handles,
    standing proud of the case within the requested depth)."""

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        w, ln, h = d
        t = float(np.clip(0.02 * max(w, h), 0.012, 0.03))
        n_boards = int(rng.integers(boards[0], boards[1] + 1))
        hd = 0.0 if open_front else float(min(0.03, 0.08 * ln))
        parts, supports, containers = frame_box(
            (w, ln - hd, h), t, mats[0], cols[0], open_front, open_top, n_boards
        )
        s = Shape([_bevelled(p, 0.3 * t, hd / 2) for p in parts])  # top and sides rounded
        s.supports = [
            Support(sp.name, sp.z, _shift_rect(sp.rect, hd / 2), sp.clearance) for sp in supports
        ]
        s.containers = [
            Container(
                c.name, (c.lo[0], c.lo[1] + hd / 2, c.lo[2]), (c.hi[0], c.hi[1] + hd / 2, c.hi[2])
            )
            for c in containers
        ]
        if not open_front:
            _fronts(s, w, ln, h, hd, mats[0], cols[0], rng)
        return s

    return build


def _shift_rect(
    rect: tuple[float, float, float, float], dy: float
) -> tuple[float, float, float, float]:
    return (rect[0], rect[1] + dy, rect[2], rect[3] + dy)


def _bevelled(p: Part, radius: float, dy: float = 0.0) -> Part:
    """The case panel ``p`` (an axis-aligned box) moved by ``dy`` along y; the outline's
    panels (top and sides) become rounded boxes of the same bounds, the others (back,
    bottom, boards, a closed front behind its doors) stay boxes: fewer triangles to draw."""
    if not p.name.endswith(("_top", "_left", "_right")):
        shift = trimesh.transformations.translation_matrix((0.0, dy, 0.0))
        p.visual.apply_transform(shift)
        for c in p.collision:
            c.apply_transform(shift)
        return p
    lo, hi = p.visual.bounds
    ext = hi - lo
    c = (lo + hi) / 2
    return rounded_box(
        (float(ext[0]), float(ext[1]), float(ext[2])),
        (float(c[0]), float(c[1]) + dy, float(c[2])),
        p.material,
        p.rgba,
        radius,
        p.name,
        p.fill,
        segments=1,
    )


def _fronts(
    s: Shape,
    w: float,
    ln: float,
    h: float,
    hd: float,
    mat: str,
    rgba: RGBA,
    rng: np.random.Generator,
) -> None:
    """Doors or drawer fronts over a closed case's front (y = -ln/2 + hd), with pulls in
    front of them. The fronts share one collision slab; the pulls are visual."""
    y_case = -ln / 2 + hd
    ft = 0.4 * hd
    gap = 0.003
    drawers = h <= 1.2 * w and bool(rng.integers(2))
    rows = int(np.clip(round(h / 0.22), 2, 5)) if drawers else 1
    cols_n = (2 if w > 1.0 else 1) if drawers else (2 if w > 0.6 else 1)
    cw = (w - gap) / cols_n
    rh = (h - gap) / rows
    pd = hd - ft
    for i in range(cols_n):
        for j in range(rows):
            x0 = -w / 2 + gap + i * cw
            z0 = gap + j * rh
            front = box(
                (cw - gap, ft, rh - gap),
                (x0 + (cw - gap) / 2, y_case - ft / 2, z0 + (rh - gap) / 2),
                mat,
                rgba,
                f"front_{i}_{j}",
                0.5,
            )
            front.collision = []
            if i == 0 and j == 0:
                slab = trimesh.creation.box(extents=(w, ft, h))
                front.collision = [slab.apply_translation((0.0, y_case - ft / 2, h / 2))]
            s.add(front)
            if drawers:
                ext = (min(0.3 * cw, 0.16), pd, 0.012)
                at = (x0 + (cw - gap) / 2, y_case - ft - pd / 2, z0 + 0.6 * (rh - gap))
            else:
                edge = 0.12 if (cols_n == 2 and i == 1) else 0.88
                ext = (0.012, pd, min(0.3 * h, 0.25))
                at = (x0 + (cw - gap) * edge, y_case - ft - pd / 2, min(0.5 * h, 1.0))
            pull = box(ext, at, "steel", _PULL, f"pull_{i}_{j}")
            pull.collision = []
            s.add(pull)


def appliance(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A closed, rounded body with a handle (arcade machines; the kitchen and laundry
    appliances have their own templates in :mod:`.appliances`)."""
    w, ln, h = d
    s = Shape()
    hd = min(0.03, 0.1 * ln)
    s.add(rounded_box((w, ln - hd, h), (0, hd / 2, h / 2), mats[0], cols[0], 0.02, "body", 0.08))
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
