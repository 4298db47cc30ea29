"""The figures of report.html (report/figures.py, report/block.py): nothing
drawn outside the canvas (titles, labels, legends, colour bars, keys) at any
strip length, residual arrows above the point markers, a scale arrow in the
plan figures of residuals.

The figures are caught as they are turned into PNG (``figures._png``) and
drawn again at the report's 96 dpi to measure every artist.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import pytest

from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.report import figures

from _figures import outside_canvas

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@pytest.fixture
def caught(monkeypatch) -> list[Figure]:
    """Every figure the report makes, in order (all drawn in this process)."""
    from strip_aerotri.report.aside import FORK_ENV

    monkeypatch.setenv(FORK_ENV, "0")
    made: list[Figure] = []
    real = figures._png

    def catch(fig: Figure) -> str:
        made.append(fig)
        return real(fig)

    monkeypatch.setattr(figures, "_png", catch)
    return made


def _strip_result(n_photos: int, **kwargs):
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(n_photos, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        return triangulate(sim.observations, sim.control, sim.crs)


STRIPS = {
    "3 photos": (3, {"seed": 2}),
    "8 photos, geographic": (8, {"seed": 1, "crs": "EPSG:4326"}),
    "14 photos": (14, {"seed": 1, "control": "every_k_models", "control_every": 2}),
    "45 photos": (45, {"seed": 3, "control": "every_k_models", "control_every": 3}),
    "corridor, 30 photos": (30, {"preset": "corridor", "seed": 1}),
}


@pytest.mark.parametrize("case", list(STRIPS), ids=list(STRIPS))
def test_strip_figures_are_inside_their_canvas(caught, case):
    from strip_aerotri.report.html import build_html
    from strip_aerotri.report.record import build_report

    n, kwargs = STRIPS[case]
    result = _strip_result(n, **kwargs)
    build_html(result, build_report(result))
    assert len(caught) >= 3
    for k, fig in enumerate(caught, start=1):
        assert outside_canvas(fig) == [], f"figure {k}"


@pytest.mark.parametrize(("n_strips", "n_photos"), [(2, 4), (3, 8), (4, 15)])
def test_block_figure_is_inside_its_canvas(caught, n_strips, n_photos):
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.report.block import block_figure
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(n_strips, n_photos, preset="film", seed=1)
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = adjust_block(sim.observations, sim.control, sim.crs, specs)
    assert block_figure(result) is not None
    (fig,) = caught
    assert outside_canvas(fig) == []
    ax = fig.axes[0]
    (arrows,) = [c for c in ax.collections if type(c).__name__ == "Quiver"]
    markers = [c for c in ax.collections if type(c).__name__ == "PathCollection"]
    assert all(arrows.get_zorder() > m.get_zorder() for m in markers)
    assert any(type(a).__name__ == "QuiverKey" for a in ax.get_children())


def test_residual_arrows_are_above_the_markers_with_a_scale_arrow(caught):
    from strip_aerotri.report.html import build_html
    from strip_aerotri.report.record import build_report

    result = _strip_result(14, seed=1, control="every_k_models", control_every=2)
    build_html(result, build_report(result))
    fig = caught[1]  # figure 2: residuals in plan
    ax = fig.axes[0]
    arrows = [c for c in ax.collections if type(c).__name__ == "Quiver"]
    markers = [c for c in ax.collections if type(c).__name__ == "PathCollection"]
    assert arrows and markers
    assert min(a.get_zorder() for a in arrows) > max(m.get_zorder() for m in markers)
    assert any(type(a).__name__ == "QuiverKey" for a in ax.get_children())


def test_a_clipped_figure_is_found():
    """The check finds a legend put beside the axes of a figure with fixed
    margins (the strip layout's legend before it had a layout engine)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4.5))
    fig.subplots_adjust(left=0.07, right=0.97)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], label="projection centres")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    assert any("Legend" in problem for problem in outside_canvas(fig))
    fig.set_layout_engine("constrained")
    assert outside_canvas(fig) == []


def test_the_figures_artists_do_not_grow_with_the_strip(caught):
    """Every figure draws its points, pairs and models as collections (one
    artist per series), not one artist per point, bar or pair: the count of
    artists stays bounded from 20 to 260 photos.  What may grow is bounded
    by itself: the pairs ticked by their left photo (at most 16) and the
    names of at most 60 control points."""
    from strip_aerotri.report.html import build_html
    from strip_aerotri.report.record import build_report

    counts = {}
    for n in (20, 100, 260):
        caught.clear()
        result = _strip_result(n, preset="drone", seed=1)
        build_html(result, build_report(result))
        counts[n] = [len(fig.findobj()) for fig in caught]
    for n, per_figure in counts.items():
        assert len(per_figure) == 4, n
        assert max(per_figure) <= 400, (n, per_figure)
    # the per-pair and per-model figures: bars up to 120 pairs (a Rectangle
    # per bar would add 2 artists a pair, 160 from 20 to 100 photos), lines beyond
    for k in (2, 3):
        assert counts[100][k] - counts[20][k] <= 80, (k, counts)


def test_long_photo_names_and_flat_values_stay_inside(caught):
    """Camera file names as photo ids (the pairs' rotated tick labels reach
    left of the axes), a y-parallax of exactly zero everywhere (an axis of
    no range) and no control names: still inside the canvas."""
    import dataclasses

    from strip_aerotri.report.html import draw_figures
    from strip_aerotri.report.record import build_report

    result = _strip_result(14, seed=1, control="every_k_models", control_every=2)
    data = figures.figure_data(result, build_report(result)["models"])
    names = tuple(f"DJI_20240517_{k:06d}_W.JPG" for k in range(len(data.photo_ids)))
    flat = dataclasses.replace(
        data,
        photo_ids=names,
        left_photos=names[: len(data.left_photos)],
        sigma0_um=np.zeros_like(data.sigma0_um),
        max_parallax_um=np.zeros_like(data.max_parallax_um),
    )
    figures_drawn = draw_figures(flat)
    assert figures_drawn.parallax is not None and figures_drawn.ties is not None
    assert len(caught) == 4
    for k, fig in enumerate(caught, start=1):
        assert outside_canvas(fig) == [], f"figure {k}"


def test_plan_residuals_without_heights_have_no_colour_bar(caught):
    """Plan control only (no height residual anywhere): the residual figure
    has no colour bar, its points drawn as open circles, inside the canvas."""
    import dataclasses

    from strip_aerotri.report.record import build_report

    result = _strip_result(14, seed=1, control="every_k_models", control_every=2)
    data = figures.figure_data(result, build_report(result)["models"])
    assert data.control is not None and not data.plan.long
    residuals = data.control.residuals.copy()
    residuals[:, 2] = np.nan
    plan_only = dataclasses.replace(
        data, control=dataclasses.replace(data.control, residuals=residuals)
    )
    assert figures.figure_residuals(plan_only) is not None
    (fig,) = caught
    assert len(fig.axes) == 1  # no colour bar
    assert outside_canvas(fig) == []


def test_control_point_not_determined_is_drawn_without_numpy_warnings():
    """A control point the adjustment left undetermined (NaN, e.g. a bundle
    that rejected its rays) has no meridian convergence: the figures' data
    are built without numpy's "invalid value" warnings reaching the user,
    and the determined points keep pyproj's convergence."""
    import dataclasses

    from strip_aerotri.report.figures import Plan, figure_data
    from strip_aerotri.report.record import model_records

    result = _strip_result(6, seed=0, crs="EPSG:2180")
    idx, _ = figures.control_rows(result)
    points = np.array(result.ground.points)
    points[idx[0]] = np.nan
    lost = dataclasses.replace(result, ground=dataclasses.replace(result.ground, points=points))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data = figure_data(lost, model_records(lost))
        gamma = Plan(lost).convergence(lost, points[idx])
    assert data.control is not None
    assert gamma[0] == 0.0
    expected = result.ground.crs.meridian_convergence(points[idx[1:]])
    assert np.allclose(gamma[1:], expected) and np.all(np.abs(expected) > 1e-3)
