"""Upholstered templates: sofas and armchairs with puffy seat and back cushions, beds with a
mattress, a duvet and pillows, and loose cushions.

Same contract as :mod:`.templates`: extents ``d = (width, length, height)`` (m), front at -y,
object frame. The collision boxes cover nearly the volume of the plain boxes these shapes had
(short legs lift a sofa's frame; its back cushions stop 4 cm below the back's top; a bed's
pillows are new boxes on the mattress), and the top of a seat's cushion boxes is the seat's
support height, as before; the cushions' crowns and rounded edges are visual."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from factory.assets.geometry import Part, Shape, Support, cylinder
from factory.assets.primitives import moved, rounded_box

RGBA = tuple[float, float, float, float]
_LEG = (0.22, 0.15, 0.09, 1.0)


def _back_cushion(
    width: float,
    thick: float,
    height: float,
    center: tuple[float, float, float],
    mat: str,
    rgba: RGBA,
    name: str,
    fill: float,
) -> Part:
    """A cushion standing up, its crown facing -y (a back cushion)."""
    part = rounded_box(
        (width, height, thick),
        (0.0, 0.0, 0.0),
        mat,
        rgba,
        radius=0.3 * thick,
        name=name,
        fill=fill,
        bulge=0.12 * thick,
        flat=2,
        segments=1,
    )
    tf = trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0])
    tf[:3, 3] = center
    return moved(part, tf)


def sofa(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A frame on short legs, puffy seat cushions, back cushions against a back frame (at +y)
    and rounded arms: sofas, armchairs, loveseats. The seat's support is the cushions' top."""
    w, ln, h = d
    s = Shape()
    seat_h = 0.45 * h
    arm = float(np.clip(0.12 * w, 0.08, 0.2))
    back = float(np.clip(0.22 * ln, 0.12, 0.25))
    back_f = 0.4 * back
    fill = 0.14  # the plain boxes' 0.12, for the air now between the legs and cushions
    leg_h = float(np.clip(0.07 * h, 0.03, 0.07)) if rng.integers(3) else 0.0
    cush = float(np.clip(0.35 * seat_h, 0.07, 0.15))
    z_base = seat_h - cush
    inner = w - 2 * arm
    n = max(1, min(3, round(inner / 0.62)))
    mat, col, trim = mats[0], cols[0], cols[1]
    base_y = -back_f / 2
    s.add(
        rounded_box(
            (inner, ln - back_f, z_base - leg_h),
            (0, base_y, leg_h + (z_base - leg_h) / 2),
            mat,
            col,
            radius=0.02,
            name="base",
            fill=fill,
            segments=1,
        )
    )
    cw = inner / n
    depth = ln - back
    for k in range(n):
        x = -inner / 2 + cw * (k + 0.5)
        s.add(
            rounded_box(
                (cw, depth, cush),
                (x, -ln / 2 + depth / 2, z_base + cush / 2),
                mat,
                col,
                radius=0.35 * cush,
                name=f"seat_cushion_{k}",
                fill=fill,
                bulge=0.12 * cush,
                flat=2,
                segments=1,
            )
        )
        s.add(
            _back_cushion(
                cw,
                back - back_f,
                h - 0.04 - z_base,
                (x, ln / 2 - back_f - (back - back_f) / 2, z_base + (h - 0.04 - z_base) / 2),
                mat,
                col,
                f"back_cushion_{k}",
                fill,
            )
        )
    s.add(
        rounded_box(
            (w, back_f, h - leg_h),
            (0, ln / 2 - back_f / 2, leg_h + (h - leg_h) / 2),
            mat,
            trim,
            radius=min(0.45 * back_f, 0.04),
            name="back",
            fill=fill,
            segments=1,
        )
    )
    arm_h = seat_h + float(rng.uniform(0.1, 0.2)) * h
    for k, sx in enumerate((-1, 1)):
        s.add(
            rounded_box(
                (arm, ln - back_f, arm_h - leg_h),
                (sx * (w / 2 - arm / 2), -back_f / 2, leg_h + (arm_h - leg_h) / 2),
                mat,
                trim,
                radius=min(0.4 * arm, 0.06),
                name=f"arm_{k}",
                fill=fill,
                segments=1,
            )
        )
    if leg_h:
        for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
            x = sx * (w / 2 - 0.05)
            y = sy * (ln / 2 - 0.05)
            s.add(
                cylinder(0.02, leg_h, 0.0, "wood", _LEG, (x, y), 10, f"leg_{k}", radius_top=0.025)
            )
    s.supports.append(Support("seat", seat_h, (-inner / 2, -ln / 2, inner / 2, ln / 2 - back)))
    return s


def bed(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A rounded frame, a mattress under a duvet with a folded edge, pillows and a headboard
    at +y. The mattress's collision is its box (top at the support height); the duvet lies
    inside it and the pillows have their own boxes (the support stops short of them)."""
    w, ln, h = d
    s = Shape()
    frame_h = 0.25 * h
    mat_h = 0.22 * h
    head_t = 0.06
    body = ln - head_t
    top = frame_h + mat_h
    s.add(
        rounded_box(
            (w, body, frame_h),
            (0, -head_t / 2, frame_h / 2),
            mats[1],
            cols[1],
            radius=min(0.02, 0.2 * frame_h),
            name="frame",
            fill=0.06,
            segments=1,
        )
    )
    mw, ml = w * 0.97, body * 0.98
    duvet_t = float(np.clip(0.2 * mat_h, 0.025, 0.05))
    mattress = rounded_box(
        (mw * 0.985, ml, mat_h - duvet_t),
        (0, -head_t / 2, frame_h + (mat_h - duvet_t) / 2),
        "foam",
        (0.95, 0.95, 0.93, 1.0),
        radius=0.3 * (mat_h - duvet_t),
        name="mattress",
        segments=1,
        collide=False,
    )
    mattress.collision = [
        trimesh.creation.box(extents=(mw, ml, mat_h)).apply_translation(
            (0, -head_t / 2, frame_h + mat_h / 2)
        )
    ]
    s.add(mattress)
    cover = float(rng.uniform(0.6, 0.75)) * ml
    hang = 0.6 * mat_h
    y0 = -head_t / 2 - ml / 2
    s.add(
        rounded_box(
            (mw, cover, hang + duvet_t),
            (0, y0 + cover / 2, top - (hang + duvet_t) / 2),
            mats[0],
            cols[0],
            radius=0.6 * duvet_t + 0.01,
            name="duvet",
            bulge=0.3 * duvet_t,
            flat=2,
            collide=False,
        )
    )
    fold = 1.6 * duvet_t
    s.add(
        rounded_box(
            (mw, 0.12, fold),
            (0, y0 + cover - 0.06, top - fold / 2),
            mats[0],
            cols[0],
            radius=0.45 * fold,
            name="duvet_fold",
            collide=False,
        )
    )
    n = 2 if w > 1.2 else 1
    pw = min(0.7, (mw - 0.06) / n - 0.04)
    pl = float(np.clip(0.2 * body, 0.25, 0.4))
    ph = float(np.clip(0.14 * h, 0.08, 0.14))
    py = ln / 2 - head_t - 0.03 - pl / 2
    for k in range(n):
        x = 0.0 if n == 1 else (k - 0.5) * (pw + 0.04)
        s.add(
            rounded_box(
                (pw, pl, ph),
                (x, py, top + ph / 2),
                "fabric",
                (0.97, 0.97, 0.95, 1.0),
                radius=0.4 * ph,
                name=f"pillow_{k}",
                fill=0.1,
                bulge=0.12 * ph,
                flat=2,
                segments=1,
            )
        )
    s.add(
        rounded_box(
            (w, head_t, h),
            (0, ln / 2 - head_t / 2, h / 2),
            mats[1],
            cols[1],
            radius=0.4 * head_t,
            name="headboard",
            fill=0.5,
            segments=1,
        )
    )
    s.supports.append(Support("mattress", top, (-w * 0.48, -ln / 2, w * 0.48, py - pl / 2 - 0.02)))
    return s


def pillow(
    d: np.ndarray, mats: tuple[str, str], cols: tuple[RGBA, RGBA], rng: np.random.Generator
) -> Shape:
    """A loose cushion or pillow: a crowned, rounded pad (its box is its collision)."""
    w, ln, h = d
    s = Shape()
    s.add(
        rounded_box(
            (w, ln, h),
            (0, 0, h / 2),
            mats[0],
            cols[0],
            radius=0.4 * h,
            name="cushion",
            fill=0.1,
            bulge=0.1 * h,
            flat=2,
        )
    )
    s.supports.append(Support("top", h, (-w / 2, -ln / 2, w / 2, ln / 2)))
    return s
