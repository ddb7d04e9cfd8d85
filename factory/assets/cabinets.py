"""Articulated case furniture: a panel carcass with rows of drawers over hinged doors.

The carcass (root body) is an open-front :func:`~.geometry.frame_box`. A :class:`Layout`
says what fills its front: ``drawers`` stacked on top (each a tray link on a slide along -y,
on its own board), then a door compartment with one door (hinged on its ``hinge`` edge) or
two (hinged on the outer edges), ``shelves`` inside it, an optional hanging ``rail``, an
optional fixed control ``panel`` on the right (the appliances'), an optional fixed ``top``
strip over the doors (a washing machine's controls) and optional ``glazed`` doors. A door
hinged on its left edge turns about -z, one on its right edge about +z, so +q swings either
out to the front.
Handles (:mod:`.handles`) stand in front of the fronts within the requested depth. The
compartments' floors and shelves are supports and their volumes containers, each with the
link that carries it and the joint to open first. All in the object frame, closed (m, front
-y).

``base_cabinet`` is the layout of one drawer over one left-hinged door (the first layout this
module had; its shapes are unchanged by the generalisation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from factory.assets.articulation import JointSpec
from factory.assets.geometry import Container, Part, Shape, Support, box, cylinder, frame_box
from factory.assets.grammar import GrammarError
from factory.assets.handles import CHROME, handle
from factory.assets.primitives import moved
from factory.schema.asset import HANDLE_STYLES, HandleMeta

RGBA = tuple[float, float, float, float]

GAP = 0.003
"""Gap (m) between a front and the carcass or the next front."""

HANDLE_DEPTH = 0.042
"""How far (m) handles stand out of the fronts (a bar keeps >= 25 mm behind its grip)."""

KNOB = 0.035
"""A knob's cap diameter (m): the Panda's fingers (80 mm open) close around it."""

REACH = 1.1
"""The highest a door's handle goes (m): within the Panda's reach from the floor."""

HINGES = ("left", "right")

GLASS: RGBA = (0.55, 0.68, 0.72, 1.0)
"""A glazed door's pane (visual)."""


@dataclass(frozen=True)
class Layout:
    """What fills a carcass's front (see the module's docstring).

    Attributes:
        handles: the handle style of every front (one of ``HANDLE_STYLES``).
        drawer_share: the drawer rows' share of the height when there are doors below.
        drawers: stacked drawers on top (0..4; joints ``drawer`` or ``drawer_0`` (top) ...).
        doors: doors of the compartment below (0..2; joints ``door`` or ``door_left``,
            ``door_right``).
        hinge: the hinged edge of a single door (``left`` or ``right``).
        shelves: shelf boards in the door compartment (0..4; supports ``shelf_0`` ...).
        rail: a hanging rail under the shelves, which then sit in the top fifth.
        panel: the share of the width (0..0.4) of a fixed panel right of the doors.
        top: the share of the height (0..0.4) of a fixed strip over the doors (no drawers).
        glazed: a glass pane (visual) in each door's front.
        wall: the carcass's panel thickness (m; 0: 2 % of the larger of width and height,
            12..25 mm).
        front: the thickness of the fronts (m).
        handle_length: the longest bar or pull (m).
        floor_gap: free height (m) under the lowest front.
    """

    handles: str = "bar"
    drawer_share: float = 0.3
    drawers: int = 1
    doors: int = 1
    hinge: str = "left"
    shelves: int = 0
    rail: bool = False
    panel: float = 0.0
    top: float = 0.0
    glazed: bool = False
    wall: float = 0.0
    front: float = 0.018
    handle_length: float = 0.16
    floor_gap: float = 0.005

    def __post_init__(self) -> None:
        def count(name: str, v: Any, hi: int) -> None:
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= hi:
                raise GrammarError(f"{name}: expected a whole number within 0..{hi}, got {v!r}")

        if self.handles not in HANDLE_STYLES:
            raise GrammarError(
                f"handles: {self.handles!r} is not one of {', '.join(HANDLE_STYLES)}"
            )
        share = self.drawer_share
        if not isinstance(share, float | int) or not 0.15 <= share <= 0.5:
            raise GrammarError(f"drawer_share: expected a number within 0.15..0.5, got {share}")
        count("drawers", self.drawers, 4)
        count("doors", self.doors, 2)
        count("shelves", self.shelves, 4)
        if self.drawers + self.doors == 0:
            raise GrammarError("drawers: a cabinet needs at least one drawer or door")
        if self.hinge not in HINGES:
            raise GrammarError(f"hinge: {self.hinge!r} is not one of {', '.join(HINGES)}")
        if not isinstance(self.rail, bool):
            raise GrammarError(f"rail: expected true or false, got {self.rail!r}")
        if not isinstance(self.panel, float | int) or not 0.0 <= self.panel <= 0.4:
            raise GrammarError(f"panel: expected a number within 0..0.4, got {self.panel!r}")
        if not isinstance(self.top, float | int) or not 0.0 <= self.top <= 0.4:
            raise GrammarError(f"top: expected a number within 0..0.4, got {self.top!r}")
        if self.top and self.drawers:
            raise GrammarError("top: a fixed strip over the doors takes the drawers' place")
        if not isinstance(self.glazed, bool):
            raise GrammarError(f"glazed: expected true or false, got {self.glazed!r}")
        if (self.shelves or self.rail or self.panel or self.top or self.glazed) and not self.doors:
            raise GrammarError(
                "shelves: shelves, a rail, a panel, a top strip and glazing need a door compartment"
            )
        if self.handles == "edge" and (self.drawers > 1 or self.doors > 1 or self.panel):
            # an edge grip needs a free edge: a lower drawer's top and a door's edge facing
            # another front have only the gap between fronts
            raise GrammarError(
                "handles: 'edge' needs free edges (one drawer, one door and no panel)"
            )


def cabinet(
    handles: Any = "bar",
    drawer_share: float = 0.3,
    drawers: Any = 1,
    doors: Any = 1,
    hinge: Any = "left",
    shelves: Any = 0,
    rail: bool = False,
    glazed: bool = False,
) -> Any:
    """The ``cabinet`` template kind: drawers over doors (by default one drawer over one
    door hinged on its left edge).

    Args:
        handles: the handle style of every front (one of ``HANDLE_STYLES``).
        drawer_share: the drawer rows' share of the height (0.15..0.5) over doors.
        drawers: stacked drawers (0..4).
        doors: doors below them (0..2; two are hinged on the outer edges).
        hinge: the hinged edge of a single door (``left`` or ``right``).
        shelves: shelf boards behind the doors (0..4).
        rail: a hanging rail behind the doors (the shelves then sit above it).
        glazed: a glass pane in each door (a display cabinet's or a glazed bookcase's).

    Raises:
        GrammarError: a bad parameter (the catalogue reports it as its field's error).
    """
    layout = Layout(
        handles=handles,
        drawer_share=drawer_share,
        drawers=drawers,
        doors=doors,
        hinge=hinge,
        shelves=shelves,
        rail=rail,
        glazed=glazed,
    )

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        return build_cabinet(d, mats, cols, layout)

    return build


def build_cabinet(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], lay: Layout
) -> Shape:
    """The shape of ``lay`` in the extents ``d`` (carcass in ``mats[0]``/``cols[0]``, fronts
    in ``mats[1]``/``cols[1]``)."""
    w, ln, h = (float(v) for v in d)
    t = lay.wall or float(np.clip(0.02 * max(w, h), 0.012, 0.025))
    ft = lay.front
    style = lay.handles
    depth = HANDLE_DEPTH if style != "edge" else 0.0
    ln_c = ln - ft - depth
    dy = (ft + depth) / 2  # the carcass sits at the back
    parts, supports, _ = frame_box((w, ln_c, h), t, mats[0], cols[0], open_front=True)
    shift = np.eye(4)
    shift[1, 3] = dy
    s = Shape([moved(p, shift) for p in parts])
    y_c = -ln_c / 2 + dy  # the carcass's open front
    y_back = ln / 2 - t
    handle_parts: list[Part] = []
    handle_metas: list[HandleMeta] = []
    # the drawer rows fill [z_lo, h - t]; doors fill [t, z_div - t] under a divider board
    if lay.doors:
        if lay.drawers:
            z_div = h - lay.drawer_share * (h - t)  # top of the divider
        else:
            z_div = h - lay.top * (h - t) if lay.top else h
        z_lo = z_div
        if lay.drawers or lay.top:
            s.add(
                box(
                    (w - 2 * t, ln_c - t, t),
                    (0, dy - t / 2, z_div - t / 2),
                    mats[0],
                    cols[0],
                    "divider",
                )
            )
        _door_compartment(s, w, ln_c, h, t, ft, dy, y_c, y_back, z_div, mats, cols, lay)
    else:
        z_lo = t
    top = next(sp for sp in supports if sp.name.endswith("_top"))
    s.supports.append(Support(top.name, top.z, (-w / 2, -ln / 2, w / 2, ln / 2), top.clearance))

    # the drawers, top first, each on its own board: rows of height r between boards
    n = lay.drawers
    r = (h - t - z_lo - (n - 1) * t) / n if n else 0.0
    for k in range(n):
        top_k = h - t - k * (r + t)
        bot = top_k - r if k < n - 1 else z_lo
        hi_edge = h if k == 0 else top_k  # the front's top edge (less the gap)
        # ... and how far its bottom edge lies below the row (it covers the board below)
        below = t if lay.doors or k < n - 1 else bot - lay.floor_gap
        if k < n - 1:
            s.add(
                box(
                    (w - 2 * t, ln_c - t, t),
                    (0, dy - t / 2, bot - t / 2),
                    mats[0],
                    cols[0],
                    f"runner_{k}",
                )
            )
        name = "drawer" if n == 1 else f"drawer_{k}"
        _drawer(s, name, w, ln_c, t, ft, y_c, bot, top_k, below, hi_edge, mats, cols)
        if style != "edge":
            hp, hm = handle(
                style,
                f"{name}_handle",
                (0, y_c - ft, (bot + hi_edge) / 2),
                (1, 0, 0),
                (0, -1, 0),
                KNOB if style == "knob" else min(0.3 * w, lay.handle_length),
                depth,
                name,
            )
        else:
            hp, hm = handle(
                "edge",
                f"{name}_handle",
                (0, y_c - ft / 2, h - GAP),
                (1, 0, 0),
                (0, 0, 1),
                w - 2 * GAP,
                ft,
                name,
            )
        handle_parts += hp
        handle_metas.append(hm)

    # the doors: panels hinged on their outer edges
    if lay.doors:
        xa, xb = -w / 2, w / 2 - lay.panel * w  # the doors' span
        e = z_div - t if lay.drawers or lay.top else h  # the top edge of the doors' zone
        door_h = e - 2 * GAP - lay.floor_gap  # >= floor_gap above the floor
        z_door = GAP + door_h / 2 + lay.floor_gap
        if lay.doors == 1:
            doors = [("door", xa, xb, lay.hinge)]
        else:
            mid = (xa + xb) / 2
            doors = [("door_left", xa, mid, "left"), ("door_right", mid, xb, "right")]
        for name, x0, x1, side in doors:
            door: Part = box(
                ((x1 - x0) - 2 * GAP, ft, door_h),
                ((x0 + x1) / 2, y_c - ft / 2, z_door),
                mats[1],
                cols[1],
                name,
            )
            door.link = name
            s.add(door)
            if lay.glazed:
                dw = (x1 - x0) - 2 * GAP
                pane = box(
                    (dw - 2 * 0.06, 0.002, door_h - 2 * 0.08),
                    ((x0 + x1) / 2, y_c - ft - 0.001, z_door),
                    "glass",
                    GLASS,
                    f"{name}_glass",
                )
                pane.collision = []  # flush with the front: visual only
                pane.link = name
                s.add(pane)
            left = side == "left"
            anchor = (x0 + GAP if left else x1 - GAP, y_c - ft, 0.0)
            axis = (0.0, 0.0, -1.0 if left else 1.0)
            s.joints.append(JointSpec(name, "hinge", "door", name, anchor, axis, (0.0, 2.0)))
            if style != "edge":
                inset = 0.06 if lay.doors == 1 else 0.05
                hp, hm = handle(
                    style,
                    f"{name}_handle",
                    (x1 - inset if left else x0 + inset, y_c - ft, min(0.75 * door_h, REACH)),
                    (0, 0, 1),
                    (0, -1, 0),
                    KNOB if style == "knob" else min(0.3 * door_h, lay.handle_length),
                    depth,
                    name,
                )
            else:
                hp, hm = handle(
                    "edge",
                    f"{name}_handle",
                    (x1 - GAP if left else x0 + GAP, y_c - ft / 2, 0.5 * door_h),
                    (0, 0, 1),
                    (1, 0, 0) if left else (-1, 0, 0),
                    door_h,
                    ft,
                    name,
                )
            handle_parts += hp
            handle_metas.append(hm)
        if lay.panel:
            s.add(
                box(
                    ((w / 2 - xb) - 2 * GAP, ft, door_h),
                    ((xb + w / 2) / 2, y_c - ft / 2, z_door),
                    mats[1],
                    cols[1],
                    "panel",
                )
            )
        if lay.top:
            s.add(
                box(
                    (w - 2 * GAP, ft, h - e - 2 * GAP),
                    (0, y_c - ft / 2, (e + h) / 2),
                    mats[1],
                    cols[1],
                    "top_panel",
                )
            )

    # handles, in front of the fronts
    for p in handle_parts:
        s.add(p)
    s.handles += handle_metas
    return s


def _door_compartment(
    s: Shape,
    w: float,
    ln_c: float,
    h: float,
    t: float,
    ft: float,
    dy: float,
    y_c: float,
    y_back: float,
    z_div: float,
    mats: tuple[str, str],
    cols: tuple[RGBA, RGBA],
    lay: Layout,
) -> None:
    """The fixed inside of the door compartment (shelves, rail, the panel's partition) and
    its supports and containers, one set per door (reached through it)."""
    top = z_div - t if lay.drawers or lay.top else h - t  # the compartment's ceiling
    x_in = (-w / 2 + t, w / 2 - t)
    if lay.panel:
        xp = w / 2 - lay.panel * w  # the partition's right face
        s.add(
            box(
                (t, ln_c - t, top - t),
                (xp - t / 2, dy - t / 2, (top + t) / 2),
                mats[0],
                cols[0],
                "partition",
            )
        )
        x_in = (x_in[0], xp - t)
    # shelf boards (their tops), evenly spaced, or in the top fifth over a rail
    if lay.rail:
        tops = [t + (top - t) * (0.8 + 0.2 * b / lay.shelves) for b in range(lay.shelves)]
    else:
        tops = [t + (top - t) * (b + 1) / (lay.shelves + 1) + t / 2 for b in range(lay.shelves)]
    for b, zt in enumerate(tops):
        s.add(
            box(
                (x_in[1] - x_in[0], ln_c - t, t),
                ((x_in[0] + x_in[1]) / 2, dy - t / 2, zt - t / 2),
                mats[0],
                cols[0],
                f"shelf_{b}",
            )
        )
    ceiling = (tops[0] - t) if tops else top  # over the floor (a rail hangs below it)
    if lay.rail:
        r = 0.012
        rail = cylinder(r, x_in[1] - x_in[0], x_in[0], "steel", CHROME, sections=12, name="rail")
        turn = np.eye(4)
        turn[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]  # z -> x
        turn[:3, 3] = (0.0, (y_c + y_back) / 2, ceiling - 0.05 - r)
        rail = moved(rail, turn)
        s.add(rail)
        ceiling -= 0.05 + 2 * r
    levels = [(t, ceiling - t)]  # (level, clearance)
    levels += [
        (zt, (tops[b + 1] - t if b + 1 < len(tops) else top) - zt) for b, zt in enumerate(tops)
    ]
    names = ["case_floor", *(f"shelf_{b}" for b in range(len(tops)))]
    if lay.doors == 1:
        spans = [("", "door", x_in)]
    else:
        mid = (x_in[0] + x_in[1]) / 2
        spans = [
            ("_left", "door_left", (x_in[0], mid)),
            ("_right", "door_right", (mid, x_in[1])),
        ]
    for suffix, access, (x0, x1) in spans:
        inner = (x0, y_c, x1, y_back)
        for name, (z, clear) in zip(names, levels, strict=True):
            s.supports.append(Support(f"{name}{suffix}", z, inner, clear, access=access))
        s.containers.append(
            Container(f"case_interior{suffix}", (x0, y_c, t), (x1, y_back, top), access=access)
        )


def _drawer(
    s: Shape,
    name: str,
    w: float,
    ln_c: float,
    t: float,
    ft: float,
    y_c: float,
    bot: float,
    top: float,
    below: float,
    hi_edge: float,
    mats: tuple[str, str],
    cols: tuple[RGBA, RGBA],
) -> None:
    """A drawer (tray link on a slide, with its floor's support and interior) in the row
    ``bot..top`` behind a front from ``bot - below + GAP`` to ``hi_edge - GAP``."""
    x0, x1 = -w / 2 + t + GAP, w / 2 - t - GAP
    zb, zt = bot + GAP, top - GAP
    tray_l = 0.9 * (ln_c - t)
    wall = 0.012
    y0 = y_c  # back face of the drawer front
    side = zt - zb - 0.02
    y_mid = y0 + tray_l / 2
    m0, c0 = mats[0], cols[0]
    tray = [
        box((x1 - x0, tray_l, wall), (0, y_mid, zb + wall / 2), m0, c0),
        box((wall, tray_l, side), (x0 + wall / 2, y_mid, zb + side / 2), m0, c0),
        box((wall, tray_l, side), (x1 - wall / 2, y_mid, zb + side / 2), m0, c0),
        box((x1 - x0 - 2 * wall, wall, side), (0, y0 + tray_l - wall / 2, zb + side / 2), m0, c0),
        box(
            (w - 2 * GAP, ft, hi_edge - bot - 2 * GAP + below),
            (0, y_c - ft / 2, (bot - below + hi_edge) / 2),
            mats[1],
            cols[1],
        ),
    ]
    for p, part in zip(tray, ("bottom", "left", "right", "back", "front"), strict=True):
        p.name = f"{name}_{part}"
        p.link = name
        s.add(p)
    floor = (x0 + wall, y0, x1 - wall, y0 + tray_l - wall)
    s.supports.append(Support(f"{name}_floor", zb + wall, floor, zt - zb - wall, name, name))
    s.containers.append(
        Container(
            f"{name}_interior",
            (floor[0], floor[1], zb + wall),
            (floor[2], floor[3], zt - 0.02),
            name,
            name,
        )
    )
    s.joints.append(
        JointSpec(
            name,
            "slide",
            "drawer",
            name,
            (0.0, y_c, (zb + zt) / 2),
            (0.0, -1.0, 0.0),
            (0.0, tray_l),
        )
    )


__all__ = ["GAP", "HANDLE_DEPTH", "KNOB", "Layout", "build_cabinet", "cabinet"]
