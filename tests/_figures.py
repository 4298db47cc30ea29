"""Checks on the report's figures shared by their tests."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def outside_canvas(fig: Figure, tolerance_px: float = 1.0) -> list[str]:
    """The artists of ``fig`` that reach beyond its canvas, drawn at 96 dpi.

    Every axes with its ticks, labels, title and legend, every colour bar,
    every text and legend of the figure: their extents (clipped where the
    artist is clipped) must lie inside the figure's box.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.set_dpi(96)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    box = fig.bbox
    found = []
    artists = [*fig.texts, *fig.legends]
    for ax in fig.axes:
        artists += [ax, *ax.get_default_bbox_extra_artists()]
    for artist in artists:
        if not artist.get_visible():
            continue
        extent = artist.get_tightbbox(renderer)
        if extent is None or extent.width == 0 or extent.height == 0:
            continue
        if (
            extent.x0 < box.x0 - tolerance_px
            or extent.y0 < box.y0 - tolerance_px
            or extent.x1 > box.x1 + tolerance_px
            or extent.y1 > box.y1 + tolerance_px
        ):
            label = getattr(artist, "get_label", lambda: "")() or ""
            found.append(
                f"{type(artist).__name__} {label!r}: {np.round(extent.extents)} "
                f"outside {np.round(box.extents)}"
            )
    return found
