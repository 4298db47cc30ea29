"""The self-calibration's distortion figure: a key arrow with its length in
µm, the radial profile's axes labelled with their units
(report/figures_calibration.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from strip_aerotri.options import SelfCalibration
from strip_aerotri.pipeline import triangulate
from strip_aerotri.report.figures_calibration import (
    cells_figure,
    distortion_field,
    distortion_figure,
    figure_distortion,
    key_length,
)
from strip_aerotri.simulate import simulate_strip


@pytest.mark.parametrize(
    ("largest", "length"),
    [(118.1, 100.0), (0.35, 0.2), (7.0, 5.0), (1.0, 1.0), (2.0, 2.0), (19.99, 10.0), (0.0, 0.0)],
)
def test_the_key_is_the_largest_round_length_not_above_the_largest_vector(largest, length):
    assert key_length(largest) == pytest.approx(length, rel=1e-12)


def test_no_key_without_a_finite_vector():
    assert key_length(float("nan")) == 0.0 and key_length(-1.0) == 0.0


@pytest.fixture(scope="module")
def outcome():
    sim = simulate_strip(12, seed=1, crs="local", camera_errors={"k1": -3e-8})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = triangulate(
            sim.observations, sim.control, sim.crs, refine="bundle",
            self_calibration=SelfCalibration("auto"),
        )  # fmt: skip
    assert res.refined is not None and res.refined.self_calibration is not None
    assert "k1" in res.refined.self_calibration.kept
    return res.refined.self_calibration


def test_the_distortion_field_has_a_key_arrow_in_micrometres(outcome):
    """The key arrow's length (µm) is drawn to the vectors' scale: the key and
    the vectors are of one Quiver, and its label names the length in µm."""
    from matplotlib.quiver import Quiver, QuiverKey

    fig = distortion_figure(outcome)
    assert fig is not None
    field, profile = fig.axes
    (key,) = [a for a in field.artists if isinstance(a, QuiverKey)]
    (arrows,) = [c for c in field.collections if isinstance(c, Quiver)]
    assert key.Q is arrows
    d = np.column_stack([arrows.U, arrows.V])
    largest = float(np.max(np.hypot(d[:, 0], d[:, 1])))
    # the vectors are the field in µm at the grid points
    grid = np.asarray(arrows.XY)
    assert np.allclose(d, distortion_field(outcome, grid) * 1000.0, rtol=1e-9, atol=1e-9)
    assert key.U == key_length(largest) and 0.5 * largest < key.U <= largest
    assert key.text.get_text() == f"{key.U:g} µm"
    # the radial profile: units on both axes
    assert profile.get_xlabel() == "r (mm)"
    assert profile.get_ylabel() == "radial correction (µm)"
    assert field.get_xlabel() == "x (mm)" and field.get_ylabel() == "y (mm)"
    assert figure_distortion(outcome)  # the PNG is drawn with the key


def _inside(ax, arrows) -> bool:
    """Every arrow's tail and tip within ``ax``'s limits (data units)."""
    xy = np.asarray(arrows.XY)
    tips = xy + np.column_stack([arrows.U, arrows.V]) / arrows.scale
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    both = np.vstack([xy, tips])
    return bool(
        np.all((both[:, 0] >= x0) & (both[:, 0] <= x1) & (both[:, 1] >= y0) & (both[:, 1] <= y1))
    )


def _outward_cells():
    """8 x 8 cells over a 6 x 4.5 mm sensor, residuals pointing outward
    (a radial error, largest 12 µm at the corners) before, a tenth after."""
    from strip_aerotri.results import ResidualCells

    x_edges, y_edges = np.linspace(-3.0, 3.0, 9), np.linspace(-2.25, 2.25, 9)
    gx, gy = np.meshgrid(0.5 * (x_edges[1:] + x_edges[:-1]), 0.5 * (y_edges[1:] + y_edges[:-1]))
    before = np.stack([gx, gy], axis=-1) * (12.0 / np.hypot(gx, gy).max())
    count = np.full(gx.shape, 5)
    return ResidualCells(x_edges, y_edges, 0.1 * before, before, count)


def test_the_cells_share_one_scale_and_key_and_no_arrow_leaves_its_axes(outcome):
    """Before and after at one scale, a key arrow on each panel of the same
    length (the round length under the largest "before" cell, µm); the
    arrows of the edge cells stay inside their axes (they ran off them)."""
    from matplotlib.quiver import Quiver, QuiverKey

    cells = _outward_cells()
    fig = cells_figure(cells)
    assert fig is not None
    largest = float(np.nanmax(np.hypot(cells.before[..., 0], cells.before[..., 1])))
    scales = set()
    for ax, field in zip(fig.axes, (cells.before, cells.after), strict=True):
        (key,) = [a for a in ax.artists if isinstance(a, QuiverKey)]
        (arrows,) = [c for c in ax.collections if isinstance(c, Quiver)]
        assert key.Q is arrows and key.U == key_length(largest) == 10.0
        assert key.text.get_text() == f"{key.U:g} µm"
        drawn = np.column_stack([arrows.U, arrows.V])
        assert np.allclose(drawn, np.nan_to_num(field).reshape(-1, 2))
        assert _inside(ax, arrows)
        scales.add(arrows.scale)
    assert len(scales) == 1
    field_fig = distortion_figure(outcome)
    (arrows,) = [c for c in field_fig.axes[0].collections if isinstance(c, Quiver)]
    assert _inside(field_fig.axes[0], arrows)
