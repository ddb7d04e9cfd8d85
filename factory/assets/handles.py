"""Handles of moving fronts: ``bar``, ``knob``, ``pull`` and ``edge``, with exact convex
collision and the :class:`~factory.schema.asset.HandleMeta` they are described by.

:func:`handle` builds one in a local frame (x along the handle, -y out of the front, z
across) and turns it onto the front: ``center`` is the handle's centre on the front's surface
(object frame, m), ``normal`` points out of the front and ``along`` along the handle; the meta's
``center`` is the grip's centre. Its parts carry ``Part.handle = name`` and ``Part.link``, so
the asset builder finds the handle's collision pieces. :func:`front_bar` is the appliances'
bar on posts (drawn on the root body).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from factory.assets.errors import AssetError
from factory.assets.geometry import Part, Shape, cylinder
from factory.assets.primitives import moved, rounded_box
from factory.schema.asset import HANDLE_STYLES, HandleMeta

RGBA = tuple[float, float, float, float]
CHROME: RGBA = (0.8, 0.81, 0.83, 1.0)

BAR_CLEARANCE = 0.03
"""Free space (m) behind a bar's grip, for the fingers (the plan asks >= 25 mm)."""


def _frame(along: Sequence[float], normal: Sequence[float]) -> np.ndarray:
    """The rotation taking the local frame (x along, -y out of the front) onto ``along`` and
    ``normal``."""
    a = np.asarray(along, float)
    out = np.asarray(normal, float)
    if abs(np.linalg.norm(a) - 1) > 1e-6 or abs(np.linalg.norm(out) - 1) > 1e-6:
        raise AssetError(f"handle directions must be unit vectors, got {along} and {normal}")
    if abs(float(a @ out)) > 1e-6:
        raise AssetError(f"a handle's along {along} must be perpendicular to its normal {normal}")
    y = -out
    return np.column_stack([a, y, np.cross(a, y)])


def _bar(length: float, depth: float, mat: str, rgba: RGBA) -> tuple[list[Part], float, float]:
    t = float(np.clip(0.5 * (depth - BAR_CLEARANCE), 0.008, 0.016))
    clearance = depth - t
    parts = [rounded_box((length, t, t), (0, -(depth - t / 2), 0), mat, rgba, 0.45 * t, "grip", 1)]
    for k, x in enumerate((-0.4 * length, 0.4 * length)):
        parts.append(
            rounded_box(
                (0.6 * t, clearance, 0.6 * t),
                (x, -clearance / 2, 0),
                mat,
                rgba,
                0.25 * t,
                f"post_{k}",
                segments=1,
            )
        )
    return parts, t, clearance


def _knob(length: float, depth: float, mat: str, rgba: RGBA) -> tuple[list[Part], float, float]:
    r = 0.5 * length
    neck = 0.45 * depth
    turn = np.eye(4)
    turn[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # local z -> -y (out of the front)
    parts = [
        cylinder(0.4 * r, neck, 0.0, mat, rgba, sections=12, name="neck"),
        cylinder(0.8 * r, depth - neck, neck, mat, rgba, sections=16, name="cap", radius_top=r),
    ]
    return [moved(p, turn) for p in parts], depth - neck, neck


def _pull(length: float, depth: float, mat: str, rgba: RGBA) -> tuple[list[Part], float, float]:
    plate = min(0.006, 0.3 * depth)
    lip = float(np.clip(0.4 * depth, 0.006, 0.012))
    height = 3 * lip
    parts = [
        rounded_box((length, plate, height), (0, -plate / 2, 0), mat, rgba, 0.4 * plate, "plate"),
        rounded_box(
            (length, depth - plate, lip),
            (0, -plate - (depth - plate) / 2, height / 2 - lip / 2),
            mat,
            rgba,
            0.3 * lip,
            "lip",
            segments=1,
        ),
    ]
    return parts, lip, height - lip


def _edge(length: float, depth: float, mat: str, rgba: RGBA) -> tuple[list[Part], float, float]:
    return [], depth, 0.0


_STYLES: dict[str, Callable[[float, float, str, RGBA], tuple[list[Part], float, float]]] = {
    "bar": _bar,
    "knob": _knob,
    "pull": _pull,
    "edge": _edge,
}


def handle(
    style: str,
    name: str,
    center: Sequence[float],
    along: Sequence[float],
    normal: Sequence[float],
    length: float,
    depth: float,
    link: str = "",
    mat: str = "steel",
    rgba: RGBA = CHROME,
) -> tuple[list[Part], HandleMeta]:
    """One handle and its meta.

    Args:
        style: one of ``HANDLE_STYLES``: ``bar`` (a grip on two posts, ``depth`` proud of the
            front), ``knob`` (a neck and a cap, ``length`` across), ``pull`` (a plate with a
            lip to hook under) or ``edge`` (the front's own edge: no parts, ``depth`` is the
            panel's thickness).
        name: the handle's name (safe id).
        center: the centre of its footprint on the front (m, object frame); for an ``edge``,
            the middle of the edge.
        along: unit direction of its long axis.
        normal: unit direction out of the front.
        length: extent along ``along`` (m).
        depth: how far it stands out of the front (m).
        link: the link its parts go on.
        mat: material key; ``rgba`` its colour.

    Returns:
        its parts (object frame; convex collision, each part its own pieces) and its meta
        (``collision`` left empty: the asset builder fills the indices).

    Raises:
        AssetError: unknown style (naming the styles), bad directions or sizes.
    """
    if style not in _STYLES:
        raise AssetError(f"handle style {style!r} is not one of {list(HANDLE_STYLES)}")
    if not (length > 0 and depth > 0):
        raise AssetError(f"handle {name!r}: length and depth must be > 0 (m)")
    rot = _frame(along, normal)
    tf = np.eye(4)
    tf[:3, :3] = rot
    tf[:3, 3] = center
    parts, thickness, clearance = _STYLES[style](length, depth, mat, rgba)
    for p in parts:
        moved(p, tf)
        p.name = f"{name}_{p.name}"
        p.link = link
        p.handle = name
    grip = np.asarray(center, float) + np.asarray(normal, float) * (
        0.5 * depth if style == "knob" else depth - 0.5 * thickness
    )
    if style == "edge":
        grip = np.asarray(center, float)
    meta = HandleMeta(
        name=name,
        style=style,  # type: ignore[arg-type]
        center=[float(v) for v in grip],
        along=[float(v) for v in along],
        normal=[float(v) for v in normal],
        length=float(length),
        thickness=float(thickness if style != "knob" else 0.4 * length),  # the neck's diameter
        clearance=float(clearance),
    )
    return parts, meta


def front_bar(
    s: Shape,
    name: str,
    center: tuple[float, float, float],
    length: float,
    vertical: bool,
    y_face: float,
    depth: float,
    mat: str = "steel",
    rgba: RGBA = CHROME,
) -> None:
    """An appliance's bar handle ``length`` long on two posts, standing ``depth`` proud of
    the front at ``y_face`` (facing -y), added to ``s`` (root body, the appliances' look)."""
    t = min(0.018, 0.6 * depth)
    ext = (t, t, length) if vertical else (length, t, t)
    y = y_face - depth + t / 2
    s.add(rounded_box(ext, (center[0], y, center[2]), mat, rgba, 0.45 * t, name, segments=1))
    for k, off in enumerate((-0.4 * length, 0.4 * length)):
        px = center[0] + (0 if vertical else off)
        pz = center[2] + (off if vertical else 0)
        post = depth - t
        if post > 1e-3:
            s.add(
                rounded_box(
                    (0.6 * t, post, 0.6 * t),
                    (px, y_face - post / 2, pz),
                    mat,
                    rgba,
                    0.25 * t,
                    f"{name}_post_{k}",
                    segments=1,
                )
            )


__all__ = ["BAR_CLEARANCE", "CHROME", "front_bar", "handle"]
