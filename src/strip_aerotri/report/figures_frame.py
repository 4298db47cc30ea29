"""Axes placed once from the sizes of their labels: the report's figures
without a layout engine.

A layout engine (matplotlib's constrained or tight layout) measures every
axes with its ticks and labels through their artists, twice, before the
draw lays them out again: about half of a figure's drawing time.  Here the
ticks are fixed first (each axis's own locator, run at the axes' place), the
texts they and the labels carry are measured as a Text lays them out (the
font's sizes cached for the draw that follows), and the subplot parameters
are set from these sizes; a second pass at the new place confirms them (the
ticks a locator picks depend a little on the axes' length).  The ticks stay
fixed, so the draw writes the very labels that were measured; the axis
labels and titles are pinned where the draw would put them (the same
pixels, tests/test_report_figures_frame.py), so that it does not measure
every tick label again to find the place.

What it places: a grid of subplots (``Figure.subplots``, width ratios
allowed, shared axes too) with x ticks at the bottom and y ticks on the
left or right; titles; axis labels; offset texts; annotations of points
inside the axes; a legend beside the axes (``beside``); one colour bar right
of a single axes (``colorbar``: its axes, created by ``fig.add_axes``).
Legends inside the axes need no room.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.axis import Axis
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.colorbar import Colorbar
    from matplotlib.figure import Figure
    from matplotlib.legend import Legend
    from matplotlib.text import Text
    from matplotlib.ticker import Locator
    from matplotlib.transforms import Bbox

    from .._typing import FloatArray

__all__ = ["fit", "fixed_title"]

#: Blank between the canvas's edge and the outermost text, and between panels [points].
PAD_PT = 5.0

#: A colour bar's gap to its axes, as a fraction of the axes' width, its
#: height as a fraction of the axes' height and its length over its width
#: (matplotlib's ``pad``, ``shrink`` and ``aspect`` of ``Figure.colorbar``).
COLORBAR_PAD, COLORBAR_SHRINK, COLORBAR_ASPECT = 0.02, 0.8, 20.0

#: The share of the figure's width (height) that the left and right (bottom
#: and top) margins may take together.
MAX_MARGINS = 0.8

#: Passes at most: the second one normally confirms the first.
_PASSES = 4


@dataclass
class _Found:
    """Axes' details met while measuring them, used once they are placed."""

    #: each labelled axis and the depth of its ticks and tick labels [pixels]
    stacks: list[tuple[Axis, float]] = field(default_factory=list)
    #: each axis, its ticks in view (data coordinates) and their labels
    ticks: list[tuple[Axis, FloatArray, list[str]]] = field(default_factory=list)
    #: the sizes of the labels measured so far (all passes): :func:`_label_sizes`
    sizes: dict[tuple[str, int, float], tuple[float, float]] = field(default_factory=dict)


@dataclass
class _Frame:
    """Blank around the grid of axes [pixels]: the margins (left, bottom,
    right, top) and the gaps between columns and between rows."""

    margins: FloatArray  # (4,)
    gaps: FloatArray  # (2,)
    #: what was found on the way: the depth of each labelled axis's ticks
    #: and tick labels [pixels], each axis's ticks in view
    found: _Found | None = None

    def close_to(self, other: _Frame, tolerance_px: float = 2.0) -> bool:
        return bool(
            np.all(np.abs(self.margins - other.margins) <= tolerance_px)
            and np.all(np.abs(self.gaps - other.gaps) <= tolerance_px)
        )


def fit(
    fig: Figure,
    *,
    beside: Legend | None = None,
    colorbar: Colorbar | None = None,
    best: Legend | None = None,
) -> None:
    """Set ``fig``'s subplot parameters so that every label, tick label,
    title, the legend ``beside`` the axes and the ``colorbar`` are inside
    its canvas, with :data:`PAD_PT` to spare, and fix the axes' ticks
    (drawn by :func:`.figures_ticks.draw_light`).

    ``best``: a legend at matplotlib's "best" place inside its axes, found
    once here and fixed there (the draw would search for it two or three
    times over every vertex of the axes' data).

    ``fig`` must have its Agg canvas and its final dpi: the sizes are
    measured in its pixels.
    """
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # an Agg canvas
    # the subplots; not the colour bar, nor axes placed otherwise (insets)
    grid = [
        ax
        for ax in fig.axes
        if ax.get_subplotspec() is not None and (colorbar is None or ax is not colorbar.ax)
    ]
    locators: dict[int, Locator] = {}  # each ticker's own locator, by id
    sizes: dict[tuple[str, int, float], tuple[float, float]] = {}  # labels measured
    frame = _Frame(np.array([0.7, 0.5, 0.25, 0.35]) * fig.dpi, np.array([0.7, 0.4]) * fig.dpi)
    for attempt in range(_PASSES):
        _place(fig, grid, frame, colorbar)
        if attempt < _PASSES - 1:  # the last pass keeps the ticks measured before
            _fix_ticks(fig.axes, locators)
        needed = _measure(fig, grid, renderer, beside, colorbar, sizes)
        if needed.close_to(frame):
            break
        frame = needed
    assert needed.found is not None  # set by _measure
    _pin(needed.found.stacks, renderer)
    own_ticks = {id(colorbar.ax)} if colorbar is not None else set()
    # a best legend before the light ticks, which it would count as data
    if best is not None and not _settle(best, renderer) and best.axes is not None:
        own_ticks.add(id(best.axes))  # not fixed: its axes keep matplotlib's ticks
    from .figures_ticks import draw_light

    for axis, locs, labels in needed.found.ticks:
        if id(axis.axes) not in own_ticks:
            draw_light(axis, locs, labels)


def fixed_title(ax: Axes, text: str, **kwargs: Any) -> None:
    """``ax.set_title`` for a figure placed by :func:`fit`: at a fixed place
    (matplotlib moves a title at each draw to clear what is above the axes;
    :func:`fit` lifts it over a y axis's offset text itself)."""
    ax.set_title(text, y=1.0, **kwargs)


def _pin(stacks: list[tuple[Axis, float]], renderer: RendererAgg) -> None:
    """Axis labels where the draw would put them, beyond their axis's ticks
    and tick labels (``stacks``: their depth in pixels), fixed there: the
    draw then does not measure every tick label again to find the place.
    A title lifted over its y axis's offset text."""
    for axis, depth in stacks:
        box = axis.axes.bbox
        px = _points(axis.axes)
        beyond = depth + axis.labelpad * px
        if _horizontal(axis):
            low = axis.get_label_position() == "bottom"
            axis.set_label_coords(0.5, -beyond / box.height if low else 1.0 + beyond / box.height)
        else:
            low = str(axis.get_label_position()) == "left"
            axis.set_label_coords(-beyond / box.width if low else 1.0 + beyond / box.width, 0.5)
    for ax in {id(axis.axes): axis.axes for axis, _ in stacks}.values():
        offset = ax.yaxis.get_offset_text()
        if ax.get_title() and offset.get_visible() and offset.get_text():
            lift = _label_sizes([offset.get_text()], offset, renderer)[0, 1] + 3.0 * _points(ax)
            ax.title.set_y(1.0 + lift / ax.bbox.height)


def _settle(legend: Legend, renderer: RendererAgg) -> bool:
    """Fix ``legend`` where its location puts it now (its lower left corner
    in axes fraction); False where matplotlib has no ``Legend.set_loc``
    (before 3.8)."""
    ax = legend.axes
    set_loc = getattr(legend, "set_loc", None)
    if ax is None or set_loc is None:
        return False
    extent, box = legend.get_window_extent(renderer), ax.bbox
    set_loc(((extent.x0 - box.x0) / box.width, (extent.y0 - box.y0) / box.height))
    return True


def _horizontal(axis: Axis) -> bool:
    """Whether ``axis`` is its axes' x axis."""
    return axis is axis.axes.xaxis


def _points(ax: Axes) -> float:
    """Pixels per point in ``ax``'s figure."""
    fig = ax.get_figure()
    return float(fig.dpi) / 72.0 if fig is not None else 1.0


def _geometry(grid: list[Axes]) -> tuple[int, int]:
    spec = grid[0].get_subplotspec()
    if spec is None:
        raise ValueError("fit() places the subplots of a grid (Figure.subplots)")
    rows, cols = spec.get_gridspec().get_geometry()
    return int(rows), int(cols)


def _place(fig: Figure, grid: list[Axes], frame: _Frame, colorbar: Colorbar | None) -> None:
    """Subplot parameters from ``frame`` (pixels); the colour bar beside its axes."""
    width, height = fig.bbox.width, fig.bbox.height
    rows, cols = _geometry(grid)
    # margins of more than MAX_MARGINS of the figure shrink alike (the axes
    # keep the rest): what does not fit then is cut, as by a layout engine
    size = np.array([width, height] * 2)
    across = frame.margins[:2] + frame.margins[2:]
    shrink = np.minimum(1.0, MAX_MARGINS * size[:2] / np.maximum(across, 1e-9))
    left, bottom, right, top = frame.margins * np.tile(shrink, 2)
    inner_w = width - left - right
    inner_h = height - bottom - top
    gap_w = min(float(frame.gaps[0]), 0.5 * inner_w / max(cols - 1, 1))
    gap_h = min(float(frame.gaps[1]), 0.5 * inner_h / max(rows - 1, 1))
    axes_w = (inner_w - (cols - 1) * gap_w) / cols
    axes_h = (inner_h - (rows - 1) * gap_h) / rows
    fig.subplots_adjust(
        left=left / width,
        bottom=bottom / height,
        right=1.0 - right / width,
        top=1.0 - top / height,
        wspace=gap_w / axes_w,
        hspace=gap_h / axes_h,
    )
    if colorbar is not None:
        box = grid[0].get_position()
        bar_h = COLORBAR_SHRINK * box.height
        bar_w = bar_h * height / width / COLORBAR_ASPECT
        colorbar.ax.set_position(
            (box.x1 + COLORBAR_PAD * box.width, box.y0 + 0.5 * (box.height - bar_h), bar_w, bar_h)
        )


def _fix_ticks(axes: list[Axes], locators: dict[int, Locator]) -> None:
    """Each axis's ticks where its own locator puts them now, fixed (the
    limits of an axes of fixed aspect set first, as the draw sets them)."""
    from matplotlib.ticker import FixedLocator

    done: set[int] = set()
    for ax in axes:
        ax.apply_aspect()
        for axis in (ax.xaxis, ax.yaxis):
            key = id(axis.major)  # shared axes share it
            if key in done:
                continue
            done.add(key)
            own = locators.setdefault(key, axis.get_major_locator())
            axis.set_major_locator(own)
            axis.set_major_locator(FixedLocator(np.asarray(axis.get_majorticklocs()).tolist()))


def _largest(values: FloatArray) -> float:
    """The largest of ``values``, 0 for none."""
    return float(np.max(np.asarray(values, dtype=np.float64), initial=0.0))


def _measure(
    fig: Figure,
    grid: list[Axes],
    renderer: RendererAgg,
    beside: Legend | None,
    colorbar: Colorbar | None,
    sizes: dict[tuple[str, int, float], tuple[float, float]],
) -> _Frame:
    """The blank each side of the grid and between its cells needs
    (``sizes``: the labels measured in earlier passes)."""
    rows, cols = _geometry(grid)
    # needs[k]: pixels beyond axes k's box on the left, bottom, right, top
    found = _Found(sizes=sizes)
    needs = np.array([_needs(ax, renderer, found) for ax in grid]).reshape(len(grid), 4)
    spans = [ax.get_subplotspec() for ax in grid]
    col0 = np.array([s.colspan.start for s in spans if s is not None])
    col1 = np.array([s.colspan.stop - 1 for s in spans if s is not None])
    row0 = np.array([s.rowspan.start for s in spans if s is not None])
    row1 = np.array([s.rowspan.stop - 1 for s in spans if s is not None])
    margins = np.array(
        [
            _largest(needs[col0 == 0, 0]),
            _largest(needs[row1 == rows - 1, 1]),
            _largest(needs[col1 == cols - 1, 2]),
            _largest(needs[row0 == 0, 3]),
        ]
    )
    if beside is not None and beside.axes is not None:
        margins = np.maximum(margins, _beyond(beside.get_window_extent(renderer), beside.axes))
    if colorbar is not None:
        reach = colorbar.ax.bbox.x1 - grid[0].bbox.x1
        margins[2] = max(margins[2], reach + _needs(colorbar.ax, renderer, found)[2])
    between_cols = [
        _largest(needs[col1 == k, 2]) + _largest(needs[col0 == k + 1, 0]) for k in range(cols - 1)
    ]
    between_rows = [
        _largest(needs[row1 == k, 1]) + _largest(needs[row0 == k + 1, 3]) for k in range(rows - 1)
    ]
    pad = PAD_PT * fig.dpi / 72.0
    gaps = np.array([max(between_cols, default=0.0), max(between_rows, default=0.0)])
    return _Frame(np.maximum(margins, 0.0) + pad, np.maximum(gaps, 0.0) + pad, found)


def _beyond(extent: Bbox, ax: Axes) -> FloatArray:
    """How far ``extent`` (pixels) reaches beyond ``ax``'s box: left, bottom, right, top."""
    box = ax.bbox
    return np.array(
        [box.x0 - extent.x0, box.y0 - extent.y0, extent.x1 - box.x1, extent.y1 - box.y1]
    )


def _needs(ax: Axes, renderer: RendererAgg, found: _Found) -> FloatArray:
    """Pixels beyond ``ax``'s box that its ticks, tick labels, axis labels,
    offset texts, title and annotations take: left, bottom, right, top
    (``found``: gets the axes' ticks and the depth of labelled axes' ticks)."""
    px = _points(ax)
    need = np.maximum(
        _axis_needs(ax.xaxis, renderer, px, found), _axis_needs(ax.yaxis, renderer, px, found)
    )
    for side in (getattr(ax, "_left_title", None), getattr(ax, "_right_title", None)):
        if side is not None and side.get_visible() and side.get_text():
            need = np.maximum(need, _beyond(side.get_window_extent(renderer), ax))
    title = ax.title
    if title.get_visible() and title.get_text():
        need = np.maximum(need, _beyond(title.get_window_extent(renderer), ax))
        offset = ax.yaxis.get_offset_text()
        if offset.get_visible() and offset.get_text():  # the title goes above it
            need[3] += _label_sizes([offset.get_text()], offset, renderer)[0, 1] + 3.0 * px
    for text in ax.texts:
        if text.get_visible() and text.get_text() and _anchored_inside(text, ax):
            need = np.maximum(need, _beyond(text.get_window_extent(renderer), ax))
    return need


def _anchored_inside(text: Text, ax: Axes) -> bool:
    """Whether a text is drawn: an annotation of a point in data coordinates
    only when the point is inside the axes (matplotlib's default)."""
    xy = getattr(text, "xy", None)
    if xy is None or getattr(text, "xycoords", None) != "data":
        return True
    x, y = ax.transData.transform(np.asarray(xy, dtype=np.float64))
    box = ax.bbox
    return bool(box.x0 <= x <= box.x1 and box.y0 <= y <= box.y1)


def _axis_needs(axis: Axis, renderer: RendererAgg, px: float, found: _Found) -> FloatArray:
    """Pixels beyond the axes' box taken by ``axis`` (``px``: pixels per
    point): its tick marks and labels, offset text and label (left,
    bottom, right, top); its ticks and, if it has a label, the depth of
    its ticks and tick labels are added to ``found``."""
    need = np.zeros(4)
    if not axis.get_visible():
        return need
    horizontal = _horizontal(axis)
    tick = axis.get_major_ticks(1)[0]
    low = bool(tick.tick1line.get_visible() or tick.label1.get_visible())
    side = (1 if horizontal else 0) if low else (3 if horizontal else 2)
    labelled = tick.label1 if low else tick.label2
    locs, pixels, labels = _tick_labels(axis)
    found.ticks.append((axis, locs, labels))
    across = tick.get_tick_padding() * px if len(labels) else 0.0  # tick marks outside
    if labelled.get_visible() and labels:
        sizes = _label_sizes(labels, labelled, renderer, found.sizes)
        pad = float(tick.get_pad())  # type: ignore[func-returns-value,arg-type]  # stub: None; points
        across += pad * px + _largest(sizes[:, 1 if horizontal else 0])
        # the labels of the end ticks reach past the axes' ends
        lo, hi = _along_span(axis, pixels, sizes[:, 0 if horizontal else 1], labelled)
        need[[0, 2] if horizontal else [1, 3]] = lo, hi
    stack = across
    label = axis.label
    if label.get_visible() and label.get_text():
        extent = label.get_window_extent(renderer)
        stack += axis.labelpad * px + (extent.height if horizontal else extent.width)
        found.stacks.append((axis, across))
    offset = axis.get_offset_text()
    if horizontal and offset.get_visible() and offset.get_text():  # under the tick labels
        below = _label_sizes([offset.get_text()], offset, renderer)[0, 1]
        stack = max(stack, across + 3.0 * px + below)
    need[side] = max(need[side], stack)
    return need


def _tick_labels(axis: Axis) -> tuple[FloatArray, FloatArray, list[str]]:
    """The ticks of ``axis`` in view: data coordinates, pixels along the
    axis and labels, as the draw makes them (every tick formatted, those
    in view kept)."""
    ax = axis.axes
    locs = np.asarray(axis.get_majorticklocs(), dtype=np.float64)
    if locs.size == 0:
        return locs, locs, []
    labels = axis.get_major_formatter().format_ticks(locs.tolist())
    lo, hi = sorted(axis.get_view_interval())
    tolerance = 1e-10 * max(abs(hi - lo), 1e-300)
    keep = (locs >= lo - tolerance) & (locs <= hi + tolerance)
    horizontal = _horizontal(axis)
    other = np.full(int(keep.sum()), ax.get_ylim()[0] if horizontal else ax.get_xlim()[0])
    points = np.column_stack([locs[keep], other] if horizontal else [other, locs[keep]])
    pixels = np.asarray(ax.transData.transform(points), dtype=np.float64)[
        :, 0 if horizontal else 1
    ]
    return locs[keep], pixels, [s for s, k in zip(labels, keep, strict=True) if k]


def _along_span(
    axis: Axis, pixels: FloatArray, sizes: FloatArray, like: Text
) -> tuple[float, float]:
    """How far tick labels (``sizes`` along the axis, at ``pixels``) reach
    beyond the axes' two ends: x labels as aligned, y labels centred."""
    box = axis.axes.bbox
    if _horizontal(axis):
        start, end = box.x0, box.x1
        share = {"left": 0.0, "right": 1.0}.get(like.get_horizontalalignment(), 0.5)
    else:
        start, end, share = box.y0, box.y1, 0.5
    return (
        _largest(start - (pixels - share * sizes)),
        _largest(pixels + (1.0 - share) * sizes - end),
    )


def _label_sizes(
    labels: list[str],
    like: Text,
    renderer: RendererAgg,
    known: dict[tuple[str, int, float], tuple[float, float]] | None = None,
) -> FloatArray:
    """(n, 2) width and height [pixels] of the boxes of ``labels`` drawn as
    ``like`` (its font, rotation and line spacing): each measured as a Text
    lays it out (the text's own sizes from the cache the draw reads), or
    taken from ``known`` (by text, font and rotation), which gets them."""
    from matplotlib.text import Text

    known = {} if known is None else known
    font, turn = hash(like.get_fontproperties()), float(like.get_rotation())
    keys = [(text, font, turn) for text in labels]
    missing = [key for key in keys if key not in known]
    if missing:
        probe = Text()
        probe.update_from(like)
        fig = like.get_figure()
        if fig is not None:
            probe.set_figure(fig)
        for key in missing:
            probe.set_text(key[0])
            extent = probe.get_window_extent(renderer)
            known[key] = (float(extent.width), float(extent.height))
    return np.array([known[key] for key in keys], dtype=np.float64).reshape(len(keys), 2)
