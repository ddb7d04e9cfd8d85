"""Inline SVG charts (no plotting library, no script): line charts with optional error bars.

The SVG is text inside the page, so it needs no file, scales with the page and prints sharply.
Every label is escaped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from html import escape

COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf")


@dataclass
class Series:
    """One line: points ``(xs[i], ys[i])`` and, optionally, an interval ``[lo[i], hi[i]]``."""

    label: str
    xs: list[float]
    ys: list[float]
    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """About ``n`` round tick values covering ``[lo, hi]`` (steps of 1, 2 or 5 x 10^k)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return []
    if hi <= lo:
        hi = lo + (abs(lo) or 1.0)
    raw = (hi - lo) / max(1, n)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    start = math.floor(lo / step) * step
    ticks = []
    k = 0
    while start + k * step <= hi + step * 1e-9:
        ticks.append(round(start + k * step, 12))
        k += 1
    return ticks


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.0e}"
    return f"{v:g}"


def line_chart(
    series: list[Series],
    *,
    title: str,
    x_label: str,
    y_label: str,
    log_y: bool = False,
    log_x: bool = False,
    y_range: tuple[float, float] | None = None,
    width: int = 640,
    height: int = 280,
    markers: bool = False,
) -> str:
    """An SVG line chart.

    Args:
        series: the lines (points with non-finite values, or non-positive ones on a log axis,
            are left out).
        title: the chart's accessible name (``<title>``); x_label, y_label: axis labels.
        log_y: logarithmic y axis (base 10).
        log_x: logarithmic x axis (base 2, ticks at powers of two; x <= 0 is left out).
        y_range: fixed y limits (data units); default: the data's.
        width, height: size of the drawing (px; it scales down with the page).
        markers: draw a dot at every point (for few points).

    Returns:
        an ``<svg>`` element, or an empty string if no point is drawable.
    """

    def ok(y: float) -> bool:
        return math.isfinite(y) and (y > 0 or not log_y)

    def okx(x: float) -> bool:
        return math.isfinite(x) and (x > 0 or not log_x)

    gx = math.log2 if log_x else (lambda v: v)
    pts = [(gx(x), y) for s in series for x, y in zip(s.xs, s.ys, strict=False) if okx(x) and ok(y)]
    bars = [v for s in series for v in (*s.lo, *s.hi) if ok(v)]
    if not pts:
        return ""
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts] + bars
    x0, x1 = min(xs), max(xs)
    if x1 == x0:
        x0, x1 = x0 - 1, x1 + 1
    tf = math.log10 if log_y else (lambda v: v)
    if y_range is not None:
        y0, y1 = tf(y_range[0]), tf(y_range[1])
    else:
        y0, y1 = tf(min(ys)), tf(max(ys))
        pad = (y1 - y0) * 0.05 or 0.5
        y0, y1 = y0 - pad, y1 + pad
    left, right, top, bottom = 64, 16, 28 if len(series) > 1 else 12, 44
    pw, ph = width - left - right, height - top - bottom

    def sx(x: float) -> float:
        return left + (gx(x) - x0) / (x1 - x0) * pw

    def sy(y: float) -> float:
        return top + (1 - (tf(y) - y0) / (y1 - y0)) * ph

    out = [
        f'<svg class="chart" viewBox="0 0 {width} {height}" width="{width}" height="{height}" '
        f'role="img" xmlns="http://www.w3.org/2000/svg"><title>{escape(title)}</title>',
        f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="#fff" stroke="#bbb"/>',
    ]
    if log_y:
        yt = [10.0**k for k in range(math.floor(y0), math.ceil(y1) + 1)]
        if len(yt) <= 2:
            yt = [m * t for t in yt for m in (1, 2, 5)]
    else:
        yt = nice_ticks(y0, y1)
    for t in yt:
        if not (y0 - 1e-9 <= tf(t) <= y1 + 1e-9):
            continue
        y = sy(t)
        out.append(
            f'<line x1="{left}" x2="{left + pw}" y1="{y:.1f}" y2="{y:.1f}" stroke="#eee"/>'
            f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end" class="tick">{_fmt(t)}</text>'
        )
    xt = [float(k) for k in range(math.ceil(x0), math.floor(x1) + 1)] if log_x else []
    for t in xt or nice_ticks(x0, x1, 6):
        if not x0 - 1e-9 <= t <= x1 + 1e-9:
            continue
        x = left + (t - x0) / (x1 - x0) * pw
        t = 2.0**t if log_x else t
        out.append(
            f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top + ph}" y2="{top + ph + 4}" stroke="#888"/>'
            f'<text x="{x:.1f}" y="{top + ph + 17}" text-anchor="middle" class="tick">'
            f"{_fmt(t)}</text>"
        )
    out.append(
        f'<text x="{left + pw / 2:.1f}" y="{height - 6}" text-anchor="middle" class="axis">'
        f"{escape(x_label)}</text>"
        f'<text transform="translate(14 {top + ph / 2:.1f}) rotate(-90)" text-anchor="middle" '
        f'class="axis">{escape(y_label)}</text>'
    )
    for i, s in enumerate(series):
        color = COLORS[i % len(COLORS)]
        line = [
            f"{sx(x):.1f},{sy(y):.1f}" for x, y in zip(s.xs, s.ys, strict=False) if okx(x) and ok(y)
        ]
        if len(line) > 1:
            out.append(
                f'<polyline fill="none" stroke="{color}" stroke-width="1.8" '
                f'points="{" ".join(line)}"/>'
            )
        for x, lo, hi in zip(s.xs, s.lo, s.hi, strict=False):
            if okx(x) and ok(lo) and ok(hi):
                out.append(
                    f'<line x1="{sx(x):.1f}" x2="{sx(x):.1f}" y1="{sy(lo):.1f}" '
                    f'y2="{sy(hi):.1f}" stroke="{color}" stroke-width="1.2"/>'
                )
        if markers or len(line) == 1:
            out.extend(
                f'<circle cx="{p.split(",")[0]}" cy="{p.split(",")[1]}" r="3" fill="{color}"/>'
                for p in line
            )
        if len(series) > 1:
            lx = left + 8 + i * 150
            out.append(
                f'<rect x="{lx}" y="8" width="12" height="4" fill="{color}"/>'
                f'<text x="{lx + 16}" y="14" class="tick">{escape(s.label)}</text>'
            )
    out.append("</svg>")
    return "".join(out)


SVG_STYLE = (
    "<style>text{font-family:system-ui,sans-serif;fill:#333}.tick{font-size:11px}"
    ".axis{font-size:12px}</style>"
)
"""The text styles the page gives its charts, for an SVG file of its own."""


def standalone_svg(svg: str) -> str:
    """An SVG of :func:`line_chart` as a file of its own (an XML declaration and the text
    styles the report's page gives it inline)."""
    head, sep, rest = svg.partition(">")
    return f'<?xml version="1.0" encoding="UTF-8"?>\n{head}{sep}{SVG_STYLE}{rest}\n'
