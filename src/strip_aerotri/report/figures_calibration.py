"""Figures of a self-calibration: the camera's correction over the format and
the image residuals averaged in cells (sensor axes, x right, y up)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .figures import _fitted_png
from .figures_frame import fixed_title

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .._typing import FloatArray
    from ..results import ResidualCells, SelfCalibrationOutcome

__all__ = [
    "cells_figure",
    "distortion_field",
    "distortion_figure",
    "figure_cells",
    "figure_distortion",
    "key_length",
]

#: The interior orientation's parameters, left out of the distortion field.
_INTERIOR = ("c", "x0", "y0")


def distortion_field(outcome: SelfCalibrationOutcome, xy_sensor: FloatArray) -> FloatArray:
    """The estimated correction (mm, sensor axes) at ``xy_sensor`` (K, 2),
    without the change of c and of the principal point."""
    est = outcome.estimate
    assert est is not None
    turn = est.model.flight_matrix
    values = np.where([n in _INTERIOR for n in est.names], 0.0, est.values)
    out: FloatArray = est.model.correction(xy_sensor @ turn.T, values) @ turn
    return out


def key_length(largest_um: float) -> float:
    """The key arrow's length (µm): the largest 1, 2 or 5 times a power of
    ten not above ``largest_um`` (0 for no vector)."""
    if not (math.isfinite(largest_um) and largest_um > 0.0):
        return 0.0
    power = 10.0 ** math.floor(math.log10(largest_um))
    return max(m * power for m in (1.0, 2.0, 5.0) if m * power <= largest_um * (1 + 1e-12))


def _quiver(
    ax: Axes, x: FloatArray, y: FloatArray, d: FloatArray, scale: float, largest: float = 0.0
) -> None:
    """Vectors ``d`` (µm) at ``x, y`` (mm), ``scale`` µm per mm of the axes;
    with ``largest`` (µm) a key arrow above the axes' right end gives the
    length of :func:`key_length` in µm (the title then goes left)."""
    arrows = ax.quiver(
        x, y, d[..., 0], d[..., 1], angles="xy", scale_units="xy", scale=scale, width=0.004
    )
    # the axes hold the points and the arrows' tips (matplotlib's limits
    # hold the points only: an arrow of an edge cell ran off the axes)
    (x0, x1), (y0, y1) = (
        (float(np.min([p, p + q / scale])), float(np.max([p, p + q / scale])))
        for p, q in ((x, d[..., 0]), (y, d[..., 1]))
    )
    pad = 0.05 * max(x1 - x0, y1 - y0, 1e-9)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    length = key_length(largest)
    if length > 0.0:
        # the arrow (centred on its place) ends at the axes' right edge
        end = 1.0 - 0.5 * length / scale / (x1 - x0 + 2.0 * pad)
        ax.quiverkey(
            arrows, end, 1.045, length, f"{length:g} µm", labelpos="W", coordinates="axes"
        )
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")


def figure_distortion(outcome: SelfCalibrationOutcome) -> str | None:
    """The PNG (base64) of :func:`distortion_figure`."""
    fig = distortion_figure(outcome)
    return None if fig is None else _fitted_png(fig)


def distortion_figure(outcome: SelfCalibrationOutcome) -> Figure | None:
    """Vectors of the correction on a 15 x 15 grid over the observed area
    (µm, with a key arrow), and its radial component's mean over the
    directions against r."""
    from matplotlib.figure import Figure

    cells = outcome.cells
    if outcome.estimate is None or cells is None:
        return None
    lo = np.array([cells.x_edges[0], cells.y_edges[0]])
    hi = np.array([cells.x_edges[-1], cells.y_edges[-1]])
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 15), np.linspace(lo[1], hi[1], 15))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    d_um = distortion_field(outcome, grid) * 1000.0
    largest = float(np.max(np.hypot(d_um[:, 0], d_um[:, 1]), initial=0.0))
    fig = Figure(figsize=(9.0, 3.8))
    ax1, ax2 = fig.subplots(1, 2)
    step = float(hi[0] - lo[0]) / 14.0
    _quiver(ax1, grid[:, 0], grid[:, 1], d_um, max(largest, 1e-9) / (0.9 * step), largest)
    fixed_title(ax1, f"correction, largest {largest:.1f} µm", loc="left")
    r_max = float(np.max(np.hypot(*np.abs(np.vstack([lo, hi])).max(axis=0)), initial=1.0))
    radii = np.linspace(0.0, r_max, 60)
    angles = np.linspace(0.0, 2 * np.pi, 36, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=-1)  # (36, 2)
    pts = (radii[:, None, None] * ring[None]).reshape(-1, 2)
    radial = np.sum(distortion_field(outcome, pts).reshape(60, 36, 2) * ring[None], axis=-1)
    ax2.plot(radii, radial.mean(axis=1) * 1000.0, color="C0")
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set_xlabel("r (mm)")
    ax2.set_ylabel("radial correction (µm)")
    fixed_title(ax2, "radial profile (mean over directions)")
    return fig


def figure_cells(cells: ResidualCells) -> str | None:
    """The PNG (base64) of :func:`cells_figure`."""
    fig = cells_figure(cells)
    return None if fig is None else _fitted_png(fig)


def cells_figure(cells: ResidualCells) -> Figure | None:
    """Mean residual per cell (µm), before (correction added back) and
    after, at one scale with a key arrow on each panel."""
    from matplotlib.figure import Figure

    if not np.any(cells.count):
        return None
    xc = 0.5 * (cells.x_edges[1:] + cells.x_edges[:-1])
    yc = 0.5 * (cells.y_edges[1:] + cells.y_edges[:-1])
    gx, gy = np.meshgrid(xc, yc)
    largest = float(
        np.nanmax(np.hypot(cells.before[..., 0], cells.before[..., 1]), initial=0.0)
    )
    step = float(xc[1] - xc[0]) if xc.size > 1 else 1.0
    scale = max(largest, 1e-9) / (0.9 * step)
    fig = Figure(figsize=(9.0, 3.8))
    for ax, field, title in zip(
        fig.subplots(1, 2),
        (cells.before, cells.after),
        ("before", "after"),  # the page's caption says what each is
        strict=True,
    ):
        _quiver(ax, gx, gy, np.nan_to_num(field), scale, largest)
        rms = float(np.sqrt(np.nanmean(np.sum(field**2, axis=-1))))
        fixed_title(ax, f"{title}: RMS {rms:.2f} µm", loc="left")
    return fig
