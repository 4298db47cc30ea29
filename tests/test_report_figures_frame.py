"""The report figures' own layout (report/figures_frame.py), light ticks
(report/figures_ticks.py) and PNG writer (report/figures_png.py).

* ``fit`` keeps every text inside the canvas and wastes no margin: the
  outermost text of each side ends within the pad of the canvas's edge,
  for long and rotated tick labels, offset texts, a legend beside the axes,
  a colour bar, shared axes, unequal columns and axes of equal aspect;
* the light ticks draw the very pixels of matplotlib's own ticks;
* the PNG decodes (Pillow) to the pixels it was given, with its dpi.
"""

from __future__ import annotations

import base64
import io
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import pytest

from strip_aerotri.report import figures, figures_ticks
from strip_aerotri.report.figures_frame import PAD_PT, fixed_title
from strip_aerotri.report.figures_png import png_bytes

from _figures import outside_canvas

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 96


def _reach(fig: Figure) -> np.ndarray:
    """How far inside the canvas the outermost drawn text, tick, legend or
    colour bar ends on each side (left, bottom, right, top) [pixels]."""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    artists = [*fig.texts, *fig.legends]
    for ax in fig.axes:
        artists += [ax, *ax.get_default_bbox_extra_artists()]
    boxes = []
    for artist in artists:
        if not artist.get_visible():
            continue
        extent = artist.get_tightbbox(renderer)
        if extent is not None and extent.width > 0 and extent.height > 0:
            boxes.append(extent.extents)
    union = np.array(boxes)
    box = fig.bbox
    return np.array(
        [
            union[:, 0].min() - box.x0,
            union[:, 1].min() - box.y0,
            box.x1 - union[:, 2].max(),
            box.y1 - union[:, 3].max(),
        ]
    )


def _draw(fig: Figure, **kwargs) -> str:
    png = figures._fitted_png(fig, **kwargs)
    fig.canvas.draw()  # drawn once more: to measure it as drawn
    return png


def _long_labels() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    ax.plot([4_650_000.0, 4_659_000.0], [123_456_789.0, 123_756_789.0])
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    fixed_title(ax, "Long tick labels")
    return fig, {}


def _offsets() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.plot([1000.0001, 1000.0005], [5e-7, 9e-7], "o")
    ax.set_xlabel("x with an offset")
    ax.set_ylabel("y in scientific notation")
    fixed_title(ax, "Offset texts")
    return fig, {}


def _rotated_beside() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure
    from matplotlib.ticker import FixedFormatter, FixedLocator

    fig = Figure(figsize=(9, 3.5))
    ax = fig.subplots()
    ax.plot(np.arange(40.0), np.sin(np.arange(40.0)), label="a series with a long name")
    ax.xaxis.set_major_locator(FixedLocator(np.arange(0.0, 40.0, 4.0)))
    ax.xaxis.set_major_formatter(FixedFormatter([f"DSC_{k:05d}.JPG" for k in range(10)]))
    ax.tick_params(axis="x", labelrotation=45)
    ax.grid(True, lw=0.3)
    ax.set_xlabel("photo")
    beside = ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig, {"beside": beside}


def _colorbar() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5))
    ax = fig.subplots()
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 1000, (50, 2))
    sc = ax.scatter(xy[:, 0], xy[:, 1], c=rng.normal(0, 0.05, 50), cmap="RdBu_r")
    ax.set_aspect("equal", adjustable="datalim")
    for k, (x, y) in enumerate(xy[:5]):
        ax.annotate(f"GCP-{k:04d}", (x, y), textcoords="offset points", xytext=(5, -10))
    bar = fig.colorbar(sc, cax=fig.add_axes((0.9, 0.1, 0.02, 0.8)))
    bar.set_label("height residual dH [m] (given − adjusted)")
    fixed_title(ax, "A colour bar and names")
    return fig, {"colorbar": bar}


def _panels() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 7))
    axes = fig.subplots(3, 1, sharex=True)
    for k, ax in enumerate(axes):
        ax.plot(np.linspace(0, 25_000, 50), np.cos(np.arange(50.0)) * 10.0**-k)
        ax.set_ylabel(f"panel {k} [m]")
        ax.grid(True, lw=0.3)
    axes[-1].set_xlabel("along the strip [m]")
    fixed_title(axes[0], "Three panels, one x axis")
    return fig, {}


def _columns() -> tuple[Figure, dict]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 3.8))
    ax, hx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.3, 1]})
    ax.plot(np.arange(100.0), np.arange(100.0) ** 2)
    ax.set_ylabel("µm at image scale")
    fixed_title(ax, "Left panel")
    hx.stairs(np.arange(10.0) * 500, np.linspace(-10, 10, 11), fill=True)
    fixed_title(hx, "All 82826 y-parallaxes; ±3 RMS dashed", fontsize=10)
    hx.set_xlabel("µm")
    return fig, {}


def _side_titles() -> tuple[Figure, dict]:
    """Titles at the left and right of their axes (not matplotlib's
    ``ax.title``), the only texts above the axes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.5))
    left, right = fig.subplots(1, 2)
    left.plot([0.0, 1.0], [0.0, 1.0])
    fixed_title(left, "A title at the left, large", loc="left", fontsize=14)
    right.plot([0.0, 1.0], [1.0, 0.0])
    fixed_title(right, "and one at the right", loc="right", fontsize=14)
    return fig, {}


FIGURES: dict[str, Callable[[], tuple[Figure, dict]]] = {
    "titles left and right": _side_titles,
    "long tick labels": _long_labels,
    "offset texts": _offsets,
    "rotated labels, legend beside": _rotated_beside,
    "colour bar, names, equal aspect": _colorbar,
    "three shared panels": _panels,
    "unequal columns": _columns,
}


@pytest.mark.parametrize("name", list(FIGURES), ids=list(FIGURES))
def test_fit_keeps_every_text_inside_without_waste(name):
    fig, kwargs = FIGURES[name]()
    _draw(fig, **kwargs)
    assert outside_canvas(fig) == []
    pad = PAD_PT * DPI / 72.0
    reach = _reach(fig)
    # the pad is kept on every side, and not much more on any side but
    # where a text of the other panel or an annotation sets the margin
    assert np.all(reach >= pad - 1.5), reach
    assert np.all(reach <= pad + 12.0), reach


def test_fit_places_the_axis_labels_where_matplotlib_would():
    """The labels pinned by fit sit where matplotlib's automatic placement
    (beyond the tick labels, by the label pad) puts them."""
    fig, kwargs = _long_labels()
    _draw(fig, **kwargs)
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    pinned = [
        ax.xaxis.label.get_window_extent(renderer),
        ax.yaxis.label.get_window_extent(renderer),
    ]
    labels = [t for t in ax.texts if t.get_text()]
    ticks_bottom = min(
        t.get_window_extent(renderer).y0 for t in labels if t.get_position()[1] == 0
    )
    ticks_left = min(t.get_window_extent(renderer).x0 for t in labels if t.get_position()[0] == 0)
    px = DPI / 72.0
    assert pinned[0].y1 == pytest.approx(ticks_bottom - ax.xaxis.labelpad * px, abs=1.0)
    assert pinned[1].x1 == pytest.approx(ticks_left - ax.yaxis.labelpad * px, abs=1.0)


@pytest.mark.parametrize("name", list(FIGURES), ids=list(FIGURES))
def test_light_ticks_draw_matplotlibs_pixels(name, monkeypatch):
    """The same figure with matplotlib's own ticks (draw_light a no-op) and
    with the light ones: identical pixels."""
    fig, kwargs = FIGURES[name]()
    light = figures._fitted_png(fig, **kwargs)
    # drawn by draw_light, but for axes with an offset text (their own ticks)
    assert (fig.axes[0].get_xticks().size > 0) == (name == "offset texts")
    monkeypatch.setattr(figures_ticks, "draw_light", lambda *args: False)
    fig, kwargs = FIGURES[name]()
    own = figures._fitted_png(fig, **kwargs)
    assert fig.axes[0].get_xticks().size > 0  # matplotlib's ticks this time
    a, b = (_pixels(p) for p in (light, own))
    assert a.shape == b.shape
    assert np.array_equal(a, b)


def _pixels(b64: str) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(base64.b64decode(b64))).convert("RGBA"))


@pytest.mark.parametrize("alpha", [255, 128])
def test_png_decodes_to_its_pixels(alpha):
    from PIL import Image

    rng = np.random.default_rng(3)
    rgba = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)
    rgba[:, :, 3] = 255
    rgba[5, 7, 3] = alpha
    data = png_bytes(rgba, 96)
    image = Image.open(io.BytesIO(data))
    image.load()
    assert image.mode == ("RGB" if alpha == 255 else "RGBA")
    assert image.size == (53, 37)
    assert image.info["dpi"] == pytest.approx((96.0, 96.0), abs=0.02)
    decoded = np.asarray(image.convert("RGBA"))
    assert np.array_equal(decoded, rgba)


def test_png_refuses_what_is_not_an_rgba_image():
    with pytest.raises(ValueError, match="Expected an"):
        png_bytes(np.zeros((4, 4, 3), dtype=np.uint8), 96)
    with pytest.raises(ValueError, match="Expected an"):
        png_bytes(np.zeros((4, 4, 4), dtype=np.float64), 96)


def _best_legend() -> tuple[Figure, dict]:
    """Data in three corners: matplotlib's "best" place is the fourth."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    x = np.linspace(0.0, 1.0, 400)
    ax.plot(x, np.where(x < 0.5, 1.0, 0.9 - x), label="a line through three corners")
    ax.scatter(x[::20], 1.0 - x[::20] ** 3, label="markers", s=8)
    ax.grid(True, lw=0.3)
    fixed_title(ax, "A legend at the best place")
    return fig, {"best": ax.legend(loc="best")}


def test_a_best_legend_is_fixed_where_matplotlib_puts_it(monkeypatch):
    """Found once by fit (before the light ticks, which would count as the
    axes' data) and fixed: the pixels of matplotlib's own search at each draw."""
    from strip_aerotri.report import figures_frame

    fig, kwargs = _best_legend()
    settled = _pixels(figures._fitted_png(fig, **kwargs))
    if hasattr(kwargs["best"], "set_loc"):  # matplotlib 3.8 on: fixed by fit
        assert isinstance(kwargs["best"]._loc, tuple)
    else:  # before: searched at the draw, and the axes keep matplotlib's ticks
        assert fig.axes[0].get_xticks().size > 0
    monkeypatch.setattr(figures_frame, "_settle", lambda *args: False)
    monkeypatch.setattr(figures_ticks, "draw_light", lambda *args: False)
    fig, kwargs = _best_legend()
    searched = _pixels(figures._fitted_png(fig, **kwargs))
    assert np.array_equal(settled, searched)


@pytest.mark.parametrize("name", [n for n in FIGURES if n != "offset texts"])
def test_pinned_labels_land_where_matplotlib_puts_them(name, monkeypatch):
    """The axis labels pinned by fit (so that the draw does not measure the
    tick labels again) and matplotlib's own placement at the draw, with
    its own ticks: identical pixels.  (With an offset text fit lifts the
    title over it, which matplotlib does at the draw otherwise.)"""
    from strip_aerotri.report import figures_frame

    fig, kwargs = FIGURES[name]()
    pinned = _pixels(figures._fitted_png(fig, **kwargs))
    monkeypatch.setattr(figures_frame, "_pin", lambda *args: None)
    monkeypatch.setattr(figures_ticks, "draw_light", lambda *args: False)
    fig, kwargs = FIGURES[name]()
    placed = _pixels(figures._fitted_png(fig, **kwargs))
    assert np.array_equal(pinned, placed)


def test_the_warm_up_takes_the_path_of_a_best_legend(monkeypatch):
    """The small figure drawn ahead (``html.prepare_drawing``) fixes its
    legend at matplotlib's "best" place, as three of the page's figures do,
    rather than measuring it as a legend beside the axes."""
    from strip_aerotri.report import figures_frame, html

    settled, measured = [], []
    settle, measure = figures_frame._settle, figures_frame._measure

    def counted_settle(legend, renderer):  # type: ignore[no-untyped-def]
        settled.append(legend)
        return settle(legend, renderer)

    def counted_measure(fig, grid, renderer, beside, *args):  # type: ignore[no-untyped-def]
        measured.append(beside)
        return measure(fig, grid, renderer, beside, *args)

    monkeypatch.setattr(figures_frame, "_settle", counted_settle)
    monkeypatch.setattr(figures_frame, "_measure", counted_measure)
    html.prepare_drawing()
    assert len(settled) == 1 and settled[0].get_texts()[0].get_text() == "a"
    assert measured and all(beside is None for beside in measured)
