"""An axis's fixed ticks drawn as few artists: all tick marks as one line of
markers, all grid lines as one line, a text per tick label.

matplotlib draws a tick as an object of five artists (two marks, a grid
line, two labels), made and styled one by one, and lays its label out at
each draw: with some 120 ticks the report's figures spent a third of their
drawing time on them.  Once :func:`.figures_frame.fit` has fixed the ticks
and placed the axes, :func:`draw_light` draws the same marks, grid lines
and labels, styled as the axis's first tick, and leaves the axis itself
without ticks (its label stays where ``fit`` pinned it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axis import Axis

    from .._typing import FloatArray

__all__ = ["draw_light"]


def draw_light(axis: Axis, locs: FloatArray, labels: list[str]) -> bool:
    """Draw ``axis``'s ticks at ``locs`` (data coordinates) with ``labels``
    as three kinds of artists of its axes and take its own ticks away.

    Only an axis whose labels are plain (no offset text, which its own
    ticks would draw) and whose ticks are on one side; returns whether it
    was done.
    """
    from matplotlib.lines import Line2D
    from matplotlib.text import Text

    ax = axis.axes
    formatter = axis.get_major_formatter()
    if formatter.get_offset() or len(locs) != len(labels):
        return False
    tick = axis.get_major_ticks(1)[0]
    low = bool(tick.tick1line.get_visible() or tick.label1.get_visible())
    high = bool(tick.tick2line.get_visible() or tick.label2.get_visible())
    if low == high:
        return False
    mark, label = (tick.tick1line, tick.label1) if low else (tick.tick2line, tick.label2)
    x = axis is ax.xaxis
    z = axis.get_zorder()
    locs = np.asarray(locs, dtype=np.float64)
    edge = np.zeros_like(locs) if low else np.ones_like(locs)

    marks = Line2D(locs if x else edge, edge if x else locs)
    marks.update_from(mark)
    marks.set(transform=mark.get_transform(), clip_on=False, zorder=z, visible=mark.get_visible())
    ax.add_artist(marks)

    grid = tick.gridline
    if grid.get_visible() and locs.size:
        along = np.repeat(locs, 3)
        along[2::3] = np.nan
        across = np.tile([0.0, 1.0, np.nan], locs.size)
        lines = Line2D(along if x else across, across if x else along)
        lines.update_from(grid)
        lines.set(transform=grid.get_transform(), zorder=z)
        lines.set_clip_path(ax.patch)
        ax.add_artist(lines)

    if label.get_visible():
        for loc, text in zip(locs, labels, strict=True):
            edge_at = 0.0 if low else 1.0
            artist = Text(x=loc if x else edge_at, y=edge_at if x else loc, text=text)
            artist.update_from(label)
            artist.set(transform=label.get_transform(), clip_on=False, zorder=z)
            ax.add_artist(artist)

    axis.set_ticks([])
    return True
