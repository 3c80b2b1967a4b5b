"""Small SVG charts for the evaluation report, written as text: no plotting library, no script, no network.

Each function returns one ``<svg>`` element to inline in an HTML page; every label is escaped
(:func:`html.escape`), since names and reasons come from a results file. Colours are CSS classes
(``ok``, ``fail``, ``a``, ``b``) that the page's style sheet defines. Values that are NaN or
infinite are left out of a chart (the page says how many).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Series", "interval_chart", "line_chart", "nice_ticks", "strip_chart", "tick_label"]

#: A line chart draws at most this many points per line (longer episodes are thinned evenly).
MAX_POINTS_PER_LINE = 300

#: Row labels (run names) longer than this are cut, with an ellipsis.
MAX_LABEL_CHARS = 32

_MARGIN_LEFT, _MARGIN_RIGHT, _MARGIN_TOP, _MARGIN_BOTTOM = 64, 16, 12, 40


@dataclass(frozen=True)
class Series:
    """One line of a line chart, or one row of a strip chart: its label, values and CSS class."""

    label: str
    values: Sequence[float]
    css_class: str = ""


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _num(value: float) -> str:
    """A coordinate: one decimal, no ``-0.0``."""
    text = f"{value:.1f}"
    return "0.0" if text == "-0.0" else text


def tick_label(value: float) -> str:
    """An axis label: at most 4 significant digits."""
    if value == 0:
        return "0"
    return f"{value:.4g}"


def nice_ticks(low: float, high: float, count: int = 5) -> list[float]:
    """About ``count`` round tick values (1, 2 or 5 times a power of ten apart) covering ``[low, high]``."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return [0.0, 1.0]
    if high < low:
        low, high = high, low
    if high == low:
        pad = abs(low) * 0.1 or 1.0
        low, high = low - pad, high + pad
    raw = (high - low) / max(1, count)
    # Values near the float limits (an env's 1e308, or 5e-324 apart): no round steps, just the ends.
    if not math.isfinite(raw) or raw < 1e-300:
        return [low, 0.0, high] if low < 0.0 < high else [low, high]
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw)
    first = math.floor(low / step) * step
    ticks: list[float] = []
    value = first
    while value <= high + step * 0.5 and len(ticks) < 4 * count + 2:
        ticks.append(round(value, 12))
        value += step
    if ticks[-1] < high:
        ticks.append(round(ticks[-1] + step, 12))
    return ticks


class _Axes:
    """Maps data coordinates into a ``width`` x ``height`` drawing with margins for the axes."""

    def __init__(self, width: int, height: int, x_ticks: list[float], y_ticks: list[float],
                 left: int = _MARGIN_LEFT) -> None:
        self.width, self.height = width, height
        self.x_ticks, self.y_ticks = x_ticks, y_ticks
        self.x0, self.x1 = x_ticks[0], x_ticks[-1]
        self.y0, self.y1 = y_ticks[0], y_ticks[-1]
        self.left, self.right = left, width - _MARGIN_RIGHT
        self.top, self.bottom = _MARGIN_TOP, height - _MARGIN_BOTTOM

    @staticmethod
    def _fraction(value: float, start: float, end: float) -> float:
        # Halved first, so that neither difference overflows for values near the float limit.
        span = end / 2 - start / 2
        return (value / 2 - start / 2) / span if span else 0.0

    def x(self, value: float) -> float:
        return self.left + self._fraction(value, self.x0, self.x1) * (self.right - self.left)

    def y(self, value: float) -> float:
        return self.bottom - self._fraction(value, self.y0, self.y1) * (self.bottom - self.top)

    def frame(self, x_label: str, y_label: str, *, y_grid: bool = True) -> list[str]:
        parts = [f'<line class="axis" x1="{self.left}" y1="{self.bottom}" x2="{self.right}" y2="{self.bottom}"/>']
        for tick in self.x_ticks:
            x = _num(self.x(tick))
            parts.append(f'<line class="tick" x1="{x}" y1="{self.bottom}" x2="{x}" y2="{self.bottom + 4}"/>'
                         f'<text class="xt" x="{x}" y="{self.bottom + 16}">{_e(tick_label(tick))}</text>')
        if y_grid:
            parts.append(f'<line class="axis" x1="{self.left}" y1="{self.top}" x2="{self.left}" '
                         f'y2="{self.bottom}"/>')
            for tick in self.y_ticks:
                y = _num(self.y(tick))
                parts.append(f'<line class="grid" x1="{self.left}" y1="{y}" x2="{self.right}" y2="{y}"/>'
                             f'<text class="yt" x="{self.left - 6}" y="{y}">{_e(tick_label(tick))}</text>')
        parts.append(f'<text class="xl" x="{_num((self.left + self.right) / 2)}" y="{self.height - 6}">'
                     f'{_e(x_label)}</text>')
        if y_label:
            parts.append(f'<text class="yl" transform="translate(14 {_num((self.top + self.bottom) / 2)}) '
                         f'rotate(-90)">{_e(y_label)}</text>')
        return parts


def _row_labels(labels: Sequence[str]) -> tuple[list[str], int]:
    """Row labels cut to :data:`MAX_LABEL_CHARS`, and the left margin that fits the longest."""
    cut = [label if len(label) <= MAX_LABEL_CHARS else label[: MAX_LABEL_CHARS - 1] + "\u2026" for label in labels]
    return cut, max(_MARGIN_LEFT, 16 + round(6.5 * max((len(c) for c in cut), default=0)))


def _svg(width: int, height: int, label: str, parts: list[str]) -> str:
    return (f'<svg class="chart" xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
            f'viewBox="0 0 {width} {height}" role="img" aria-label="{_e(label)}">{"".join(parts)}</svg>')


def _thin(values: Sequence[float]) -> list[tuple[int, float]]:
    """(index, value) pairs of ``values``, at most :data:`MAX_POINTS_PER_LINE`, the last one kept."""
    n = len(values)
    picks: Sequence[int] = range(n)
    if n > MAX_POINTS_PER_LINE:
        picks = sorted({round(i * (n - 1) / (MAX_POINTS_PER_LINE - 1)) for i in range(MAX_POINTS_PER_LINE)})
    return [(i, values[i]) for i in picks if math.isfinite(values[i])]


def _finite(values: Sequence[float]) -> list[float]:
    return [v for v in values if math.isfinite(v)]


def line_chart(series: Sequence[Series], *, x_label: str, y_label: str, label: str,
               width: int = 640, height: int = 280, x_include: Sequence[float] = (),
               y_include: Sequence[float] = ()) -> str:
    """One line per series, x = the value's index (a step), y = the value; a note when there is nothing to draw.

    The axes cover ``x_include`` / ``y_include`` too (so that two charts side by side share their scales).
    """
    thinned = [(s, _thin(s.values)) for s in series]
    ys = [v for _, points in thinned for _, v in points]
    xs: list[float] = [i for _, points in thinned for i, _ in points]
    if not ys:
        return _svg(width, 60, label, ['<text class="empty" x="8" y="32">no values to plot</text>'])
    xs += _finite(x_include)
    ys += _finite(y_include)
    axes = _Axes(width, height, nice_ticks(0, max(xs) or 1), nice_ticks(min(ys), max(ys)))
    parts = axes.frame(x_label, y_label)
    for s, points in thinned:
        if not points:
            continue
        coords = " ".join(f"{_num(axes.x(i))},{_num(axes.y(v))}" for i, v in points)
        shape = (f'<polyline class="line {_e(s.css_class)}" points="{coords}"><title>{_e(s.label)}</title>'
                 "</polyline>")
        if len(points) == 1:
            i, v = points[0]
            shape = (f'<circle class="dot {_e(s.css_class)}" cx="{_num(axes.x(i))}" cy="{_num(axes.y(v))}" r="3">'
                     f"<title>{_e(s.label)}</title></circle>")
        parts.append(shape)
    return _svg(width, height, label, parts)


def strip_chart(rows: Sequence[Series], *, x_label: str, label: str, width: int = 640,
                value_labels: Sequence[Sequence[str]] | None = None, x_include: Sequence[float] = ()) -> str:
    """One row per series with a dot per value along x and a bar at the median; ``value_labels`` title the dots.

    The x axis covers ``x_include`` too.
    """
    row_height = 34
    height = _MARGIN_TOP + _MARGIN_BOTTOM + row_height * max(1, len(rows))
    values = [v for row in rows for v in row.values if math.isfinite(v)]
    if not values:
        return _svg(width, 60, label, ['<text class="empty" x="8" y="32">no values to plot</text>'])
    names, left = _row_labels([row.label for row in rows])
    span = values + _finite(x_include)
    axes = _Axes(width, height, nice_ticks(min(0.0, *span), max(span)), [0.0, 1.0], left)
    parts = axes.frame(x_label, "", y_grid=False)
    for r, row in enumerate(rows):
        centre = _MARGIN_TOP + row_height * r + row_height / 2
        parts.append(f'<text class="rl" x="{left - 6}" y="{_num(centre)}">{_e(names[r])}</text>')
        finite = sorted(v for v in row.values if math.isfinite(v))
        for j, value in enumerate(row.values):
            if not math.isfinite(value):
                continue
            # A fixed jitter (no randomness: the same results draw the same page).
            offset = ((j * 7) % 11 - 5) * 1.6
            title = value_labels[r][j] if value_labels is not None else tick_label(value)
            parts.append(f'<circle class="dot {_e(row.css_class)}" cx="{_num(axes.x(value))}" '
                         f'cy="{_num(centre + offset)}" r="3.5"><title>{_e(title)}</title></circle>')
        if finite:
            n = len(finite)
            median = finite[n // 2] if n % 2 else (finite[n // 2 - 1] + finite[n // 2]) / 2
            x = _num(axes.x(median))
            parts.append(f'<line class="median" x1="{x}" y1="{_num(centre - 12)}" x2="{x}" '
                         f'y2="{_num(centre + 12)}"><title>median {_e(tick_label(median))}</title></line>')
    return _svg(width, height, label, parts)


def interval_chart(rows: Sequence[tuple[str, float, float, float, str]], *, label: str,
                   width: int = 640) -> str:
    """Success rates on a 0-100 % axis: per row ``(label, rate, low, high, css_class)``, a dot and its interval."""
    row_height = 34
    height = _MARGIN_TOP + _MARGIN_BOTTOM + row_height * max(1, len(rows))
    names, left = _row_labels([row[0] for row in rows])
    axes = _Axes(width, height, [0, 20, 40, 60, 80, 100], [0.0, 1.0], left)
    parts = axes.frame("success rate (%) with its 95 % interval", "", y_grid=False)
    for tick in axes.x_ticks[1:-1]:
        x = _num(axes.x(tick))
        parts.append(f'<line class="grid" x1="{x}" y1="{_MARGIN_TOP}" x2="{x}" y2="{axes.bottom}"/>')
    for r, (name, rate, low, high, css) in enumerate(rows):
        centre = _num(_MARGIN_TOP + row_height * r + row_height / 2)
        title = _e(f"{name}: {rate * 100:.1f} % ({low * 100:.1f}-{high * 100:.1f} %)")
        parts.append(f'<text class="rl" x="{left - 6}" y="{centre}">{_e(names[r])}</text>'
                     f'<line class="ci {_e(css)}" x1="{_num(axes.x(low * 100))}" y1="{centre}" '
                     f'x2="{_num(axes.x(high * 100))}" y2="{centre}"><title>{title}</title></line>'
                     f'<circle class="dot {_e(css)}" cx="{_num(axes.x(rate * 100))}" cy="{centre}" r="5">'
                     f"<title>{title}</title></circle>")
    return _svg(width, height, label, parts)
