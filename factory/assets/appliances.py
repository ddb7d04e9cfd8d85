"""Appliance templates: refrigerators, ovens (ranges), microwaves, dishwashers and washing
machines, each with its doors, handles, panels and windows.

Same contract as :mod:`.templates`: extents ``d = (width, length, height)`` (m), front at -y,
object frame. The body is a rounded box standing in for a hollow case (a low fill, as the
plain box was); doors and handles stand proud of its front within the requested depth and
have their own boxes; flush details (a window, a cooktop's burners, a drawer's line) are
visual. The top stays a support at the full height.

The articulated appliances (``hinged_fridge``, ``hinged_microwave``, ``hinged_washer``; built
with moving links under ``assets.articulated``) are :func:`.cabinets.build_cabinet` layouts:
a panel case whose door is a link on a vertical hinge, its interior floor and shelves
supports reached through it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import trimesh

from factory.assets.cabinets import Layout, build_cabinet
from factory.assets.geometry import Part, Shape, Support, cylinder
from factory.assets.handles import front_bar as _bar
from factory.assets.primitives import moved, ring, rounded_box

RGBA = tuple[float, float, float, float]
_DARK: RGBA = (0.06, 0.06, 0.07, 1.0)
_GLASS: RGBA = (0.1, 0.12, 0.14, 1.0)
_CHROME: RGBA = (0.8, 0.81, 0.83, 1.0)
_BODY_FILL = 0.08


def _facing_front(part: Part, at: tuple[float, float, float]) -> Part:
    """A part built along +z, turned to point along -y and moved to ``at``."""
    tf = trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0])
    tf[:3, 3] = at
    return moved(part, tf)


def _flat(part: Part) -> Part:
    part.collision = []
    return part


def _body(
    s: Shape,
    w: float,
    ln: float,
    h: float,
    front: float,
    mat: str,
    rgba: RGBA,
    top: float | None = None,
) -> float:
    """The case ``h`` high from ``y = -ln/2 + front`` to the back, its top a support at
    ``top`` (default ``h``); returns its front's y."""
    depth = ln - front
    s.add(
        rounded_box(
            (w, depth, h),
            (0.0, ln / 2 - depth / 2, h / 2),
            mat,
            rgba,
            radius=min(0.02, 0.05 * min(w, h)),
            name="body",
            fill=_BODY_FILL,
        )
    )
    s.supports.append(Support("top", top or h, (-w / 2, ln / 2 - depth, w / 2, ln / 2)))
    return ln / 2 - depth


def _door(
    s: Shape,
    name: str,
    x: tuple[float, float],
    z: tuple[float, float],
    y_front: float,
    t: float,
    mat: str,
    rgba: RGBA,
) -> None:
    s.add(
        rounded_box(
            (x[1] - x[0], t, z[1] - z[0]),
            ((x[0] + x[1]) / 2, y_front - t / 2, (z[0] + z[1]) / 2),
            mat,
            rgba,
            radius=min(0.4 * t, 0.01),
            name=name,
            fill=_BODY_FILL,
            segments=1,
        )
    )


def _knobs(s: Shape, n: int, x: tuple[float, float], z: float, y_face: float, r: float) -> None:
    for k in range(n):
        xk = x[0] + (x[1] - x[0]) * (k + 0.5) / n
        knob = cylinder(r, 0.6 * r, 0.0, "plastic", _DARK, sections=12, name=f"knob_{k}")
        s.add(_facing_front(knob, (xk, y_face, z)))


def refrigerator(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A tall case with a freezer door above or below the main door (or two side-by-side
    doors on wide ones), long vertical bar handles and a dark kick plate."""
    w, ln, h = d
    s = Shape()
    hd = float(np.clip(0.06 * ln, 0.035, 0.05))
    door_t = 0.3 * hd
    y_case = _body(s, w, ln, h, hd, mats[0], cols[0])
    kick = 0.06 * h
    gap = 0.004
    z0, z1 = kick, h - 0.01
    if w > 0.85 and rng.integers(2):
        xm = 0.1 * w
        doors = [
            ("door_0", (-w / 2, xm - gap / 2), (z0, z1)),
            ("door_1", (xm + gap / 2, w / 2), (z0, z1)),
        ]
        handles = [(xm - 0.04, True), (xm + 0.04, True)]
        hz = [0.55 * h, 0.55 * h]
        hl = [0.45 * h, 0.45 * h]
    else:
        split = z0 + (z1 - z0) * (0.68 if rng.integers(2) else 0.32)
        doors = [
            ("door_0", (-w / 2, w / 2), (z0, split - gap / 2)),
            ("door_1", (-w / 2, w / 2), (split + gap / 2, z1)),
        ]
        xh = w / 2 - 0.07 if rng.integers(2) else -w / 2 + 0.07
        handles = [(xh, True), (xh, True)]
        hz = [(z0 + split) / 2, (split + z1) / 2]
        hl = [min(0.6 * (split - z0), 0.7), min(0.6 * (z1 - split), 0.7)]
    for name, xr, zr in doors:
        _door(s, name, xr, zr, y_case, door_t, mats[0], cols[0])
    for k, ((xh, vertical), z, length) in enumerate(zip(handles, hz, hl, strict=True)):
        _bar(
            s,
            f"handle_{k}",
            (xh, 0.0, z),
            length,
            vertical,
            y_case - door_t,
            hd - door_t,
            mats[1] if mats[1] != "plastic" else "steel",
        )
    s.add(_kick_plate(w, y_case, kick))
    return s


def _kick_plate(w: float, y_case: float, kick: float) -> Part:
    """The dark plate closing the toe kick under a door of width ``w`` (m): ``kick`` high,
    just behind the case front at ``y_case``."""
    return _flat(
        rounded_box(
            (w - 0.04, 0.01, kick - 0.01),
            (0.0, y_case - 0.004, kick / 2),
            "plastic",
            _DARK,
            0.003,
            "kick_plate",
            segments=1,
        )
    )


def oven(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A range: a control panel with knobs, an oven door with a dark window and a bar handle,
    a drawer line below, and four burners on the cooktop."""
    w, ln, h = d
    s = Shape()
    hd = 0.045
    burner_t = 0.0025
    y_case = _body(s, w, ln, h - 0.6 * burner_t, hd, mats[0], cols[0], top=h)
    panel_h = 0.12 * h
    s.add(
        rounded_box(
            (w, 0.05, panel_h),
            (0.0, y_case + 0.025 - 0.012, h - panel_h / 2),
            "plastic",
            _DARK if rng.integers(2) else cols[0],
            0.008,
            "control_panel",
            segments=1,
        )
    )
    _knobs(
        s, 4 + int(rng.integers(2)), (-0.42 * w, 0.42 * w), h - panel_h / 2, y_case - 0.012, 0.018
    )
    drawer = 0.14 * h
    door_t = 0.02
    top = h - panel_h - 0.01
    _door(
        s,
        "door",
        (-w / 2 + 0.01, w / 2 - 0.01),
        (drawer + 0.005, top),
        y_case,
        door_t,
        mats[0],
        cols[0],
    )
    win = (0.7 * w, 0.5 * (top - drawer))
    s.add(
        _flat(
            rounded_box(
                (win[0], 0.004, win[1]),
                (0.0, y_case - door_t - 0.0015, drawer + 0.42 * (top - drawer)),
                "glass",
                _GLASS,
                0.0015,
                "window",
                segments=1,
            )
        )
    )
    _bar(s, "handle", (0.0, 0.0, top - 0.05), 0.75 * w, False, y_case - door_t, hd - door_t)
    _door(
        s,
        "drawer",
        (-w / 2 + 0.01, w / 2 - 0.01),
        (0.01, drawer - 0.005),
        y_case,
        door_t,
        mats[0],
        cols[0],
    )
    for k, (bx, by) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
        rb = (0.11 if k % 2 else 0.085) * min(w, 0.75)
        at = (bx * 0.22 * w, by * 0.2 * ln + 0.02)
        s.add(cylinder(rb, burner_t, h - burner_t, "plastic", _DARK, at, 20, f"burner_{k}"))
    return s


def microwave(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A case with a door on the left (a dark window in a frame, a vertical handle) and a
    control panel of buttons on the right."""
    w, ln, h = d
    s = Shape()
    hd = 0.03
    door_t = 0.012
    y_case = _body(s, w, ln, h, hd, mats[0], cols[0])
    split = 0.72 * w
    x0 = -w / 2 + 0.006
    _door(s, "door", (x0, -w / 2 + split), (0.015, h - 0.015), y_case, door_t, mats[0], cols[0])
    s.add(
        _flat(
            rounded_box(
                (0.72 * split, 0.004, 0.62 * h),
                (x0 + 0.45 * split, y_case - door_t - 0.0015, h / 2),
                "glass",
                _GLASS,
                0.0015,
                "window",
                segments=1,
            )
        )
    )
    _bar(
        s,
        "handle",
        (-w / 2 + split - 0.035, 0.0, h / 2),
        0.6 * h,
        True,
        y_case - door_t,
        hd - door_t,
    )
    px = (-w / 2 + split + 0.01, w / 2 - 0.01)
    s.add(
        _flat(
            rounded_box(
                (px[1] - px[0], 0.006, h - 0.04),
                ((px[0] + px[1]) / 2, y_case - 0.002, h / 2),
                "plastic",
                _DARK,
                0.002,
                "control_panel",
                segments=1,
            )
        )
    )
    bw = 0.22 * (px[1] - px[0])
    for k in range(6):
        bx = px[0] + (px[1] - px[0]) * (0.3 + 0.4 * (k % 2))
        bz = h * (0.7 - 0.12 * (k // 2))
        s.add(
            _flat(
                rounded_box(
                    (bw, 0.004, 0.06 * h),
                    (bx, y_case - 0.006, bz),
                    "steel",
                    _CHROME,
                    0.0015,
                    f"button_{k}",
                    segments=1,
                )
            )
        )
    return s


def dishwasher(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A full-height door with a control strip and a bar handle at its top, a kick plate."""
    w, ln, h = d
    s = Shape()
    hd = 0.04
    door_t = 0.015
    y_case = _body(s, w, ln, h, hd, mats[0], cols[0])
    kick = 0.1 * h
    _door(
        s,
        "door",
        (-w / 2 + 0.005, w / 2 - 0.005),
        (kick, h - 0.01),
        y_case,
        door_t,
        mats[0],
        cols[0],
    )
    strip = 0.1 * h
    s.add(
        _flat(
            rounded_box(
                (w - 0.03, 0.004, strip),
                (0.0, y_case - door_t - 0.0015, h - 0.01 - strip / 2 - 0.01),
                "plastic",
                _DARK,
                0.0015,
                "control_strip",
                segments=1,
            )
        )
    )
    _bar(
        s,
        "handle",
        (0.0, 0.0, h - 0.01 - strip - 0.04),
        0.7 * w,
        False,
        y_case - door_t,
        hd - door_t,
    )
    s.add(_kick_plate(w, y_case, kick))
    return s


def washing_machine(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A front loader: a round porthole door (a chrome ring around a dark glass), a control
    panel with a dial and a detergent drawer, and a service flap."""
    w, ln, h = d
    s = Shape()
    hd = 0.05
    y_case = _body(s, w, ln, h, hd, mats[0], cols[0])
    panel_h = 0.15 * h
    zc = 0.45 * h
    rr = min(0.36 * w, 0.3 * h)
    rim = ring(
        [(0.72 * rr, 0.0), (rr, 0.0), (rr, 0.6 * hd), (0.9 * rr, hd), (0.74 * rr, 0.8 * hd)],
        mats[1] if mats[1] != "plastic" else "steel",
        _CHROME,
        segments=12,
        name="door_ring",
        fill=0.05,
    )
    s.add(_facing_front(rim, (0.0, y_case, zc)))
    glass = cylinder(
        0.74 * rr, 0.6 * hd, 0.0, "glass", _GLASS, sections=24, name="door_glass", fill=0.3
    )
    s.add(_facing_front(glass, (0.0, y_case, zc)))
    s.add(
        _flat(
            rounded_box(
                (w - 0.03, 0.004, panel_h),
                (0.0, y_case - 0.0015, h - panel_h / 2 - 0.01),
                "plastic",
                _DARK if rng.integers(2) else cols[0],
                0.0015,
                "control_panel",
                segments=1,
            )
        )
    )
    s.add(
        rounded_box(
            (0.3 * w, 0.02, 0.7 * panel_h),
            (-w / 2 + 0.2 * w, y_case - 0.01, h - panel_h / 2 - 0.01),
            mats[0],
            cols[0],
            0.005,
            "drawer",
            segments=1,
        )
    )
    _knobs(s, 1, (0.2 * w, 0.4 * w), h - panel_h / 2 - 0.01, y_case - 0.004, 0.028)
    s.add(
        _flat(
            rounded_box(
                (0.16 * w, 0.004, 0.1 * h),
                (0.3 * w, y_case - 0.0015, 0.08 * h),
                mats[0],
                cols[0],
                0.0015,
                "service_flap",
                segments=1,
            )
        )
    )
    return s


# ---- articulated appliances (built on :func:`.cabinets.build_cabinet`; moving doors with
# their handles, interiors as supports). Their rigid namesakes above stay as they are.


def _front_of(s: Shape, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The bounds ``(lo, hi)`` of the front part called ``name``."""
    lo, hi = next(p for p in s.parts if p.name == name).visual.bounds
    return lo, hi


def hinged_fridge(handles: str = "bar", hinge: str = "right") -> Any:
    """The ``hinged_fridge`` template kind: an insulated case (40 mm walls) with one tall
    door hinged on its ``hinge`` edge (a long handle near the other edge) and three shelves
    inside, each a support reached through the door.

    Raises:
        GrammarError: a bad parameter.
    """
    layout = Layout(
        handles=handles,
        drawers=0,
        doors=1,
        hinge=hinge,
        shelves=3,
        wall=0.04,
        front=0.045,
        handle_length=0.4,
        floor_gap=0.03,
    )

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        return build_cabinet(d, mats, cols, layout)

    return build


def hinged_microwave(handles: str = "bar") -> Any:
    """The ``hinged_microwave`` template kind: a case with a door hinged on its left edge (a
    dark window, a handle near its right edge) beside a fixed control panel of buttons; the
    cavity's floor is a support reached through the door.

    Raises:
        GrammarError: a bad parameter.
    """
    layout = Layout(
        handles=handles,
        drawers=0,
        doors=1,
        hinge="left",
        panel=0.26,
        wall=0.012,
        front=0.022,
        handle_length=0.2,
    )

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        s = build_cabinet(d, mats, cols, layout)
        lo, hi = _front_of(s, "door")
        dw, dh = hi[0] - lo[0], hi[2] - lo[2]
        window = _flat(
            rounded_box(
                (0.62 * dw, 0.003, 0.62 * dh),
                (lo[0] + 0.42 * dw, lo[1] - 0.0015, (lo[2] + hi[2]) / 2),
                "glass",
                _GLASS,
                0.001,
                "door_window",
                segments=1,
            )
        )
        window.link = "door"
        s.add(window)
        plo, phi = _front_of(s, "panel")
        pw, ph = phi[0] - plo[0], phi[2] - plo[2]
        for k in range(6):
            s.add(
                _flat(
                    rounded_box(
                        (0.3 * pw, 0.003, 0.06 * ph),
                        (
                            plo[0] + pw * (0.3 + 0.4 * (k % 2)),
                            plo[1] - 0.0015,
                            plo[2] + ph * (0.7 - 0.12 * (k // 2)),
                        ),
                        "plastic",
                        _DARK,
                        0.001,
                        f"button_{k}",
                        segments=1,
                    )
                )
            )
        return s

    return build


def hinged_washer(handles: str = "bar", hinge: str = "left") -> Any:
    """The ``hinged_washer`` template kind: a front loader. A fixed control strip (a dial)
    over a door hinged on its ``hinge`` edge (a chrome porthole ring round a dark glass, a
    handle near the other edge); the drum's floor is a support reached through the door.

    Raises:
        GrammarError: a bad parameter.
    """
    layout = Layout(
        handles=handles,
        drawers=0,
        doors=1,
        hinge=hinge,
        top=0.18,
        wall=0.02,
        front=0.03,
        handle_length=0.14,
        floor_gap=0.04,
    )

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        s = build_cabinet(d, mats, cols, layout)
        lo, hi = _front_of(s, "door")
        dw, dh = hi[0] - lo[0], hi[2] - lo[2]
        rr = 0.36 * min(dw, dh)
        xc = (lo[0] + hi[0]) / 2 + (0.04 if layout.hinge == "right" else -0.04) * dw
        at = (xc, lo[1], (lo[2] + hi[2]) / 2)
        rim = ring(
            [(0.78 * rr, 0.0), (rr, 0.0), (rr, 0.004), (0.78 * rr, 0.004)],
            "steel",
            _CHROME,
            segments=24,
            name="door_ring",
        )
        glass = cylinder(0.78 * rr, 0.003, 0.0, "glass", _GLASS, sections=24, name="door_glass")
        for part in (rim, glass):
            part = _flat(_facing_front(part, at))
            part.link = "door"
            s.add(part)
        plo, phi = _front_of(s, "top_panel")
        dial = cylinder(0.03, 0.004, 0.0, "plastic", _DARK, sections=16, name="dial")
        s.add(_flat(_facing_front(dial, (phi[0] - 0.12, plo[1], (plo[2] + phi[2]) / 2))))
        s.add(
            _flat(
                rounded_box(
                    (0.3 * (phi[0] - plo[0]), 0.003, 0.5 * (phi[2] - plo[2])),
                    (plo[0] + 0.2 * (phi[0] - plo[0]), plo[1] - 0.0015, (plo[2] + phi[2]) / 2),
                    "plastic",
                    _DARK,
                    0.001,
                    "detergent_flap",
                    segments=1,
                )
            )
        )
        return s

    return build
