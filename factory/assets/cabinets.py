"""Articulated case furniture: a panel carcass with a drawer on top and a hinged door below.

The carcass (root body) is an open-front :func:`~.geometry.frame_box` with a divider board;
the drawer is a tray link on a slide along -y, the door a panel link hinged on its left
edge about -z (so +q swings it out to the front). Handles (:mod:`.handles`) stand in front
of the fronts within the requested depth. All in the object frame, closed (m, front -y).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from factory.assets.articulation import JointSpec
from factory.assets.geometry import Container, Part, Shape, Support, box, frame_box
from factory.assets.grammar import GrammarError
from factory.assets.handles import handle
from factory.assets.primitives import moved
from factory.schema.asset import HANDLE_STYLES

RGBA = tuple[float, float, float, float]

GAP = 0.003
"""Gap (m) between a front and the carcass or the next front."""

HANDLE_DEPTH = 0.042
"""How far (m) handles stand out of the fronts (a bar keeps >= 25 mm behind its grip)."""


def cabinet(handles: Any = "bar", drawer_share: float = 0.3) -> Any:
    """The ``cabinet`` template kind: a drawer over a door.

    Args:
        handles: the handle style of both fronts (one of ``HANDLE_STYLES``).
        drawer_share: the drawer row's share of the height (0.15..0.5).

    Raises:
        GrammarError: a bad parameter (the catalogue reports it as its field's error).
    """
    if handles not in HANDLE_STYLES:
        raise GrammarError(f"handles: {handles!r} is not one of {', '.join(HANDLE_STYLES)}")
    if not isinstance(drawer_share, float | int) or not 0.15 <= drawer_share <= 0.5:
        raise GrammarError(f"drawer_share: expected a number within 0.15..0.5, got {drawer_share}")

    def build(
        d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
    ) -> Shape:
        return _build(d, mats, cols, str(handles), float(drawer_share))

    return build


def _build(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], style: str, share: float
) -> Shape:
    w, ln, h = (float(v) for v in d)
    t = float(np.clip(0.02 * max(w, h), 0.012, 0.025))
    ft = 0.018  # front thickness
    depth = HANDLE_DEPTH if style != "edge" else 0.0
    ln_c = ln - ft - depth
    dy = (ft + depth) / 2  # the carcass sits at the back
    parts, supports, _ = frame_box((w, ln_c, h), t, mats[0], cols[0], open_front=True)
    shift = np.eye(4)
    shift[1, 3] = dy
    s = Shape([moved(p, shift) for p in parts])
    y_c = -ln_c / 2 + dy  # the carcass's open front
    y_back = ln / 2 - t
    z_div = h - share * (h - t)  # top of the divider board
    s.add(
        box((w - 2 * t, ln_c - t, t), (0, dy - t / 2, z_div - t / 2), mats[0], cols[0], "divider")
    )
    # door compartment: reached through the door
    inner = (-w / 2 + t, y_c, w / 2 - t, y_back)
    s.supports.append(Support("case_floor", t, inner, z_div - t - t, access="door"))
    s.containers.append(
        Container("case_interior", (inner[0], y_c, t), (inner[2], y_back, z_div - t), access="door")
    )
    top = next(sp for sp in supports if sp.name.endswith("_top"))
    s.supports.append(Support(top.name, top.z, (-w / 2, -ln / 2, w / 2, ln / 2), top.clearance))

    # the drawer: a tray behind its front
    x0, x1 = -w / 2 + t + GAP, w / 2 - t - GAP
    zb, zt = z_div + GAP, h - t - GAP
    tray_l = 0.9 * (ln_c - t)
    wall = 0.012
    y0 = y_c  # back face of the drawer front
    tray = [
        box(
            (x1 - x0, tray_l, wall),
            (0, y0 + tray_l / 2, zb + wall / 2),
            mats[0],
            cols[0],
            "drawer_bottom",
        ),
        box(
            (wall, tray_l, zt - zb - 0.02),
            (x0 + wall / 2, y0 + tray_l / 2, zb + (zt - zb - 0.02) / 2),
            mats[0],
            cols[0],
            "drawer_left",
        ),
        box(
            (wall, tray_l, zt - zb - 0.02),
            (x1 - wall / 2, y0 + tray_l / 2, zb + (zt - zb - 0.02) / 2),
            mats[0],
            cols[0],
            "drawer_right",
        ),
        box(
            (x1 - x0 - 2 * wall, wall, zt - zb - 0.02),
            (0, y0 + tray_l - wall / 2, zb + (zt - zb - 0.02) / 2),
            mats[0],
            cols[0],
            "drawer_back",
        ),
        box(
            (w - 2 * GAP, ft, h - z_div - 2 * GAP + t),
            (0, y_c - ft / 2, (z_div - t + h) / 2),
            mats[1],
            cols[1],
            "drawer_front",
        ),
    ]
    for p in tray:
        p.link = "drawer"
        s.add(p)
    floor = (x0 + wall, y0, x1 - wall, y0 + tray_l - wall)
    s.supports.append(Support("drawer_floor", zb + wall, floor, zt - zb - wall, "drawer", "drawer"))
    s.containers.append(
        Container(
            "drawer_interior",
            (floor[0], floor[1], zb + wall),
            (floor[2], floor[3], zt - 0.02),
            "drawer",
            "drawer",
        )
    )
    s.joints.append(
        JointSpec(
            "drawer",
            "slide",
            "drawer",
            "drawer",
            (0.0, y_c, (zb + zt) / 2),
            (0.0, -1.0, 0.0),
            (0.0, tray_l),
        )
    )

    # the door: a panel hinged on its left edge
    door_h = z_div - t - 2 * GAP - 0.005  # >= 5 mm above the floor
    door: Part = box(
        (w - 2 * GAP, ft, door_h),
        (0, y_c - ft / 2, GAP + door_h / 2 + 0.005),
        mats[1],
        cols[1],
        "door",
    )
    door.link = "door"
    s.add(door)
    anchor = (-w / 2 + GAP, y_c - ft, 0.0)
    s.joints.append(
        JointSpec("door", "hinge", "door", "door", anchor, (0.0, 0.0, -1.0), (0.0, 2.0))
    )

    # handles, in front of the fronts
    if style != "edge":
        hp, hm = handle(
            style,
            "drawer_handle",
            (0, y_c - ft, (z_div + h) / 2),
            (1, 0, 0),
            (0, -1, 0),
            min(0.3 * w, 0.16),
            depth,
            "drawer",
        )
        dp, dm = handle(
            style,
            "door_handle",
            (w / 2 - 0.06, y_c - ft, 0.75 * door_h),
            (0, 0, 1),
            (0, -1, 0),
            min(0.3 * door_h, 0.16),
            depth,
            "door",
        )
    else:
        hp, hm = handle(
            "edge",
            "drawer_handle",
            (0, y_c - ft / 2, h - GAP),
            (1, 0, 0),
            (0, 0, 1),
            w - 2 * GAP,
            ft,
            "drawer",
        )
        dp, dm = handle(
            "edge",
            "door_handle",
            (w / 2 - GAP, y_c - ft / 2, 0.5 * door_h),
            (0, 0, 1),
            (1, 0, 0),
            door_h,
            ft,
            "door",
        )
    for p in (*hp, *dp):
        s.add(p)
    s.handles += [hm, dm]
    return s
