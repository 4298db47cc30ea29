"""The figures of the HTML report (matplotlib, PNG as base64): the strip's
layout, the control residuals in plan and along the strip, the residual
y-parallaxes and the tie points per model.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..results import SelfCalibrationOutcome
from .figures_frame import fixed_title
from .values import control_rows, point_roles

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.colorbar import Colorbar
    from matplotlib.figure import Figure
    from matplotlib.legend import Legend

    from .._typing import BoolArray, FloatArray, IntArray
    from ..results import StripResult

_MAX_PLOT_POINTS = 20000
_RASTERIZE_ABOVE = 1000
"""Scatters of more points are rasterised in a vector export of a figure."""


LONG_STRIP_RATIO = 8.0
"""A strip longer than this times its width is drawn along its axis, not to scale."""


_ROLE_STYLE = {
    # role: (label, marker, colour, size, zorder)
    "tie": ("tie points", ".", "#9a9a9a", 4, 2),
    "model": ("points in one model", ".", "#c8c8c8", 4, 2),
    "line": ("straight-line points", "x", "#e67e00", 22, 4),
    "check": ("check points", "s", "#8e44ad", 40, 6),
    "control-full": ("full control", "^", "#c0392b", 60, 7),
    "control-plan": ("plan control", ">", "#2471a3", 55, 7),
    "control-height": ("height control", "o", "#1e8449", 45, 7),
}


def _png(fig: Figure) -> str:
    """The figure as a PNG at :data:`_DPI`, base64 (for an inline ``<img>``).

    Drawn once on its Agg canvas (the one :func:`_fitted_png` measured it
    on, whose font metrics are cached; ``savefig`` would draw it again on a
    canvas of its own), the pixels written by :func:`.figures_png.png_bytes`.
    """
    import base64

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from .figures_png import png_bytes

    canvas = fig.canvas
    if not isinstance(canvas, FigureCanvasAgg) or fig.dpi != _DPI:
        fig.set_dpi(_DPI)
        canvas = FigureCanvasAgg(fig)
    canvas.draw()  # type: ignore[no-untyped-call]  # matplotlib's Agg canvas is untyped
    pixels = np.asarray(canvas.buffer_rgba())  # type: ignore[no-untyped-call]  # as draw
    return base64.b64encode(png_bytes(pixels, _DPI)).decode("ascii")


def _fitted_png(
    fig: Figure,
    *,
    beside: Legend | None = None,
    colorbar: Colorbar | None = None,
    best: Legend | None = None,
) -> str:
    """:func:`_png` of ``fig`` with its axes placed by :func:`.figures_frame.fit`
    (``beside``: a legend beside the axes; ``colorbar``: one right of them;
    ``best``: a legend inside the axes at matplotlib's "best" place)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from .figures_frame import fit

    fig.set_dpi(_DPI)
    FigureCanvasAgg(fig)
    fit(fig, beside=beside, colorbar=colorbar, best=best)
    return _png(fig)


#: Resolution of the report's figures (pixels per inch).
_DPI = 96


class Plan:
    """Plan coordinates for plotting: metres east and north (grid or local).

    Projected and local CRSs are plotted in their own X, Y; a geographic CRS
    in metres on a plane tangent at the strip's centre (display only).
    Directions from local east-north-up are turned into grid directions by the
    meridian convergence.
    """

    def __init__(self, result: StripResult) -> None:
        crs = result.ground.crs
        self.projected = not (crs.is_local or crs.is_geographic)  # meridian convergence
        centres = np.asarray(result.photo_centres, dtype=np.float64)
        self.geographic = crs.is_geographic
        if self.geographic:
            ok = np.isfinite(centres).all(axis=1)
            self.lon0, self.lat0 = np.mean(centres[ok, :2], axis=0)
            ell = crs.ellipsoid
            assert ell is not None  # a geographic CRS has one
            self.radius = float(ell.semi_major_metre)
            self.unit = "m from the strip centre"
        else:
            self.unit = "m"
        self.centres = centres
        cxy = self.xy(centres)
        good = np.isfinite(cxy).all(axis=1)
        self.axis_start = cxy[good][0] if good.any() else np.zeros(2)
        self.axis_end = cxy[good][-1] if good.any() else np.array([1.0, 0.0])
        self.long = False

    def decide_long(self, xy: np.ndarray) -> None:
        """Use strip axes (not to scale) when the strip is much longer than wide."""
        sa = self.strip_axes(xy[np.isfinite(xy).all(axis=1)])
        if sa.size:
            length = float(np.ptp(sa[:, 0]))
            width = float(np.ptp(sa[:, 1]))
            self.long = length > LONG_STRIP_RATIO * max(width, 1e-9)

    def xy(self, xyh: np.ndarray) -> np.ndarray:
        xyh = np.asarray(xyh, dtype=np.float64)
        if not self.geographic:
            return xyh[:, :2]
        k = np.pi / 180.0 * self.radius
        return np.column_stack(
            [
                (xyh[:, 0] - self.lon0) * k * np.cos(np.radians(self.lat0)),
                (xyh[:, 1] - self.lat0) * k,
            ]
        )

    def strip_axes(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) plan xy -> (along, across): metres from the first photo along the
        line to the last one, and to its left."""
        d = self.axis_end - self.axis_start
        u = d / (np.hypot(d[0], d[1]) or 1.0)
        rel = np.asarray(xy, dtype=np.float64) - self.axis_start
        return np.stack([rel @ u, rel @ np.array([-u[1], u[0]])], axis=-1)

    def vectors_to_strip(self, de: np.ndarray, dn: np.ndarray) -> np.ndarray:
        """Plan vectors (grid east, north) -> (along, across) components."""
        d = self.axis_end - self.axis_start
        u = d / (np.hypot(d[0], d[1]) or 1.0)
        return np.stack([de * u[0] + dn * u[1], -de * u[1] + dn * u[0]], axis=-1)

    def convergence(self, result: StripResult, xyh: np.ndarray) -> np.ndarray:
        """Meridian convergence (radians) at ground points of ``result``'s CRS;
        zero in a local or geographic CRS, at points not determined (NaN), or
        where pyproj cannot give it."""
        gamma = np.zeros(len(xyh))
        known = np.isfinite(xyh).all(axis=1)
        if not self.projected or not known.any():
            return gamma
        try:
            gamma[known] = result.ground.crs.meridian_convergence(xyh[known])
        except Exception:  # display only: fall back to true north
            gamma[:] = 0.0
        return gamma


def _footprints(result: StripResult, plan: Plan) -> np.ndarray | None:
    """(M, 4, 2) plan corners of each photo's footprint at the mean point height."""
    obs = result.strip.observations
    xy = np.asarray(obs.xy, dtype=np.float64)
    if xy.size == 0:
        return None
    half = np.max(np.abs(xy), axis=0)
    c = float(obs.principal_distance)
    corners = np.array(
        [
            [half[0], half[1], -c],
            [-half[0], half[1], -c],
            [-half[0], -half[1], -c],
            [half[0], -half[1], -c],
        ]
    )
    rot = np.asarray(result.ground.photo_rotations_enu, dtype=np.float64)
    rays = np.einsum("mij,kj->mki", rot, corners)  # (M, 4, 3) east, north, up
    centres = np.asarray(result.photo_centres, dtype=np.float64)
    points = np.asarray(result.points, dtype=np.float64)
    # mean height of the points seen on each photo (median of all where none)
    position = np.full(obs.n_photos, -1, dtype=np.intp)
    position[np.asarray(result.strip.photo_index)] = np.arange(len(centres))
    row_photo = position[np.asarray(obs.photo)]
    row_h = points[np.asarray(obs.point), 2]
    use = (row_photo >= 0) & np.isfinite(row_h)
    total = np.bincount(row_photo[use], weights=row_h[use], minlength=len(centres))
    count = np.bincount(row_photo[use], minlength=len(centres))
    fallback = float(np.nanmedian(points[:, 2])) if np.isfinite(points[:, 2]).any() else 0.0
    h = np.where(count > 0, total / np.maximum(count, 1), fallback)
    depth = centres[:, 2] - h
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -depth[:, None] / rays[:, :, 2]
    en = rays[:, :, :2] * t[:, :, None]
    gamma = plan.convergence(result, centres)
    cg, sg = np.cos(gamma)[:, None], np.sin(gamma)[:, None]
    # true azimuth alpha -> grid azimuth alpha - gamma: turn counter-clockwise by gamma
    e = cg * en[:, :, 0] - sg * en[:, :, 1]
    n = sg * en[:, :, 0] + cg * en[:, :, 1]
    grid = np.stack([e, n], axis=-1)
    # the grid scale factor (about 1) is ignored: display only
    out = plan.xy(centres)[:, None, :] + grid
    bad = ~np.isfinite(out).all(axis=(1, 2)) | (t <= 0).any(axis=1)
    footprints: FloatArray = out[~bad]
    return footprints


@dataclass(frozen=True)
class ControlFigureData:
    """The control and check points of the residual figure: C rows."""

    xy: FloatArray  # (C, 2) plan coordinates of the points
    residuals: FloatArray  # (C, 3) given − adjusted E, N, H [m]
    grid: FloatArray  # (C, 2) the plan residuals turned to grid east, north [m]
    is_check: BoolArray  # (C,)
    names: tuple[str, ...]  # (C,) point ids


@dataclass(frozen=True)
class StripFigureData:
    """What the strip page's figures show, taken from a result as plain
    arrays (:func:`figure_data`): a few MB that pickle without the result or
    its CRS, for the process that draws them (:mod:`.aside`)."""

    plan: Plan
    points: FloatArray  # (P, 3) the result's points
    roles: np.ndarray  # (P,) str, :func:`.values.point_roles`
    footprints: FloatArray | None  # (M, 4, 2) plan corners of the photos
    photo_ids: tuple[str, ...]  # the strip's photos in order
    control: ControlFigureData | None  # None without control rows
    n_pairs: int
    sigma0_um: FloatArray  # (pairs,) relative orientation per pair
    max_parallax_um: FloatArray  # (pairs,)
    parallax_um: FloatArray  # every residual y-parallax
    left_photos: tuple[str, ...]  # the left photo of each pair (model)
    models: tuple[tuple[int, tuple[float | None, ...]], ...]  # report.json's index, tie_rms_m
    calibration: SelfCalibrationOutcome | None = None


def figure_data(
    result: StripResult,
    models: Sequence[Mapping[str, Any]],
    *,
    calibration: bool = False,
    roles: np.ndarray | None = None,
) -> StripFigureData:
    """The inputs of the strip's figures (``models``: report.json's
    ``models``; ``calibration``: with the self-calibration's outcome;
    ``roles``: :func:`.values.point_roles` of the result, if known)."""
    plan = Plan(result)
    points = np.asarray(result.points, dtype=np.float64)
    finite = np.isfinite(points).all(axis=1)
    plan.decide_long(np.vstack([plan.xy(plan.centres), plan.xy(points[finite])]))
    idx, resid = control_rows(result)
    control = None
    if idx.size:
        # residuals are along east/north; turn them to the grid like the footprints
        gamma = plan.convergence(result, points[idx])
        de = np.cos(gamma) * resid[:, 0] - np.sin(gamma) * resid[:, 1]
        dn = np.sin(gamma) * resid[:, 0] + np.cos(gamma) * resid[:, 1]
        names = np.asarray(result.point_ids, dtype=object)[idx]
        control = ControlFigureData(
            plan.xy(points[idx]),
            resid,
            np.column_stack([de, dn]),
            np.asarray(result.ground.is_check, dtype=bool),
            tuple(str(n) for n in names),
        )
    strip = result.strip
    rel = strip.relative
    ids = strip.photo_ids  # a property that builds the tuple: read once
    refined = getattr(result, "refined", None)
    return StripFigureData(
        plan=plan,
        points=points,
        roles=point_roles(result) if roles is None else roles,
        footprints=_footprints(result, plan),
        photo_ids=tuple(result.photo_ids),
        control=control,
        n_pairs=int(rel.n_pairs),
        sigma0_um=np.asarray(rel.sigma0_um),
        max_parallax_um=np.asarray(rel.max_parallax_um),
        parallax_um=np.asarray(rel.parallax_um, dtype=np.float64),
        left_photos=tuple(ids[i] for i in strip.model_photo_positions[:-1]),
        models=tuple((int(m["index"]), tuple(m["tie_rms_m"])) for m in models),
        calibration=refined.self_calibration if calibration and refined is not None else None,
    )


def _decimate(index: np.ndarray, limit: int) -> np.ndarray:
    if index.size <= limit:
        return index
    return index[np.linspace(0, index.size - 1, limit).astype(np.intp)]


def figure_layout(data: StripFigureData) -> str:
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    plan, points, roles = data.plan, data.points, data.roles
    ok = np.isfinite(points).all(axis=1)
    pxy = np.full((len(points), 2), np.nan)
    pxy[ok] = plan.xy(points[ok])
    cxy = plan.xy(plan.centres)
    feet = data.footprints
    if plan.long:
        pxy = plan.strip_axes(pxy)
        cxy = plan.strip_axes(cxy)
        if feet is not None and len(feet):
            feet = plan.strip_axes(feet.reshape(-1, 2)).reshape(feet.shape)
    fig = Figure(figsize=(10, 4.5 if plan.long else 6.5))
    ax = fig.subplots()
    if feet is not None and len(feet):
        step = max(1, len(feet) // 400)
        ax.add_collection(
            PolyCollection(
                feet[::step],  # type: ignore[arg-type]  # (n, 4, 2): PolyCollection's fast path
                facecolors="#5dade2",
                edgecolors="#2e86c1",
                alpha=0.08,
                linewidths=0.6,
                zorder=1,
                label="photo footprints",
            )
        )
    ax.plot(cxy[:, 0], cxy[:, 1], "-", color="#2e86c1", lw=0.8, zorder=3)
    ax.plot(
        cxy[:, 0], cxy[:, 1], "o", ms=3.5, color="#1b4f72", zorder=3, label="projection centres"
    )
    ax.annotate(
        data.photo_ids[0],
        cxy[0],
        textcoords="offset points",
        xytext=(4, 4),
        fontsize=8,
        color="#1b4f72",
    )
    ax.annotate(
        data.photo_ids[-1],
        cxy[-1],
        textcoords="offset points",
        xytext=(4, 4),
        fontsize=8,
        color="#1b4f72",
    )
    for role, (label, marker, colour, size, z) in _ROLE_STYLE.items():
        sel = np.flatnonzero(ok & (roles == role))
        if sel.size == 0:
            continue
        count = sel.size
        sel = _decimate(sel, _MAX_PLOT_POINTS)
        crowded = sel.size > 400 and marker not in (".", "x")
        ax.scatter(
            pxy[sel, 0],
            pxy[sel, 1],
            s=size / 4 if crowded else size,
            marker=marker,
            c=colour,
            zorder=z,
            label=f"{label} ({count})",
            linewidths=1.0 if marker == "x" else 0.4,
            edgecolors=None if marker in (".", "x") or crowded else "black",
            # thousands of markers: one image in a vector export (the PNG is raster anyway)
            rasterized=sel.size > _RASTERIZE_ABOVE,
        )
    ax.autoscale_view()
    _plan_axes(ax, plan)
    fixed_title(
        ax, "Strip layout along the strip axis (not to scale)" if plan.long else "Strip layout"
    )
    if plan.long:
        beside = ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
        return _fitted_png(fig, beside=beside)
    return _fitted_png(fig, best=ax.legend(loc="best", fontsize=8, framealpha=0.85))


def _plan_axes(ax: Axes, plan: Plan) -> None:
    if plan.long:
        ax.set_xlabel(f"along the strip from the first photo [{plan.unit}]")
        ax.set_ylabel("across the strip, left positive [m]")
    else:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"X (east) [{plan.unit}]")
        ax.set_ylabel(f"Y (north) [{plan.unit}]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.grid(True, lw=0.3, alpha=0.5)


def _nice(value: float) -> float:
    """1, 2 or 5 times a power of ten, not above ``value``."""
    if not (np.isfinite(value) and value > 0):
        return 1.0
    exp = np.floor(np.log10(value))
    base = value / 10**exp
    step = 5.0 if base >= 5 else 2.0 if base >= 2 else 1.0
    return float(step * 10**exp)


def figure_residuals(data: StripFigureData) -> str | None:
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure

    control, plan = data.control, data.plan
    if control is None:
        return None
    resid, is_check, pxy = control.residuals, control.is_check, control.xy
    cxy = plan.xy(plan.centres)
    de, dn = control.grid[:, 0], control.grid[:, 1]
    plan_len = np.hypot(de, dn)
    if plan.long:
        return _figure_residuals_along(plan, resid, pxy, de, dn, is_check)
    fig = Figure(figsize=(10, 6.5))
    ax = fig.subplots()
    ax.plot(
        cxy[:, 0], cxy[:, 1], "-", color="#aab7b8", lw=1.0, zorder=1, label="projection centres"
    )
    extent = float(np.nanmax(np.ptp(np.vstack([cxy, pxy]), axis=0))) or 1.0
    largest = float(np.nanmax(plan_len)) if np.isfinite(plan_len).any() else 0.0
    key = _nice(largest) if largest > 0 else 0.1
    # arrow of the largest residual: 8 % of the extent
    scale = (largest if largest > 0 else key) / (0.08 * extent)
    has_plan = np.isfinite(plan_len)
    for sel, colour, label in ((~is_check, "#c0392b", "control"), (is_check, "#8e44ad", "check")):
        sel = sel & has_plan
        if sel.any():
            q = ax.quiver(
                pxy[sel, 0],
                pxy[sel, 1],
                de[sel],
                dn[sel],
                angles="xy",
                scale_units="xy",
                scale=scale,
                color=colour,
                width=0.0025,
                zorder=6,  # above the point markers (5)
                label=f"plan residual, {label}",
            )
    if has_plan.any():
        # the arrows' tips inside the axes: quiver does not widen the limits
        tips = pxy[has_plan] + np.column_stack([de, dn])[has_plan] / scale
        ax.update_datalim(tips)
        ax.quiverkey(
            q, 0.85, 0.04, key, f"{key:g} m", labelpos="E", coordinates="axes", color="black"
        )
    dh = resid[:, 2]
    has_h = np.isfinite(dh)
    bar: Colorbar | None = None
    if has_h.any():
        lim = float(np.nanmax(np.abs(dh))) or 1.0
        norm = TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim)
        for sel, marker in ((~is_check, "^"), (is_check, "s")):
            sel = sel & has_h
            if sel.any():
                sc = ax.scatter(
                    pxy[sel, 0],
                    pxy[sel, 1],
                    c=dh[sel],
                    cmap="RdBu_r",
                    norm=norm,
                    marker=marker,
                    s=70,
                    edgecolors="black",
                    linewidths=0.5,
                    zorder=5,
                )
        # beside the axes, placed by figures_frame.fit
        bar = fig.colorbar(sc, cax=fig.add_axes((0.9, 0.1, 0.02, 0.8)))
        bar.set_label("height residual dH [m] (given − adjusted)")
    no_h = ~has_h
    if no_h.any():
        ax.scatter(
            pxy[no_h, 0],
            pxy[no_h, 1],
            facecolors="white",
            edgecolors="black",
            marker="o",
            s=30,
            zorder=5,
            label="no height residual",
        )
    if len(control.names) <= 60:
        for (x, y), name in zip(pxy, control.names, strict=True):
            ax.annotate(
                str(name),
                (x, y),
                textcoords="offset points",
                xytext=(5, -10),
                fontsize=7,
                color="#333333",
            )
    _plan_axes(ax, plan)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)
    fixed_title(ax, "Residuals at control (▲) and check (■) points: arrows plan, colour height")
    return _fitted_png(fig, colorbar=bar)


def _figure_residuals_along(
    plan: Plan,
    resid: FloatArray,
    pxy: FloatArray,
    de: FloatArray,
    dn: FloatArray,
    is_check: BoolArray,
) -> str:
    """Residual components against the distance along a long strip (three panels)."""
    from matplotlib.figure import Figure

    along = plan.strip_axes(pxy)[:, 0]
    comp = plan.vectors_to_strip(de, dn)
    fig = Figure(figsize=(10, 7.5))
    axes = fig.subplots(3, 1, sharex=True)
    few = len(resid) <= 300
    panels = (
        (comp[:, 0], "along-strip residual [m]"),
        (comp[:, 1], "across-strip residual [m]"),
        (resid[:, 2], "height residual dH [m]"),
    )
    for ax, (values, label) in zip(axes, panels, strict=True):
        for sel, marker, colour, name in (
            (~is_check, "^", "#c0392b", "control"),
            (is_check, "s", "#8e44ad", "check"),
        ):
            sel = sel & np.isfinite(values)
            if sel.any():
                ax.scatter(
                    along[sel],
                    values[sel],
                    marker=marker,
                    c=colour,
                    s=28 if few else 6,
                    rasterized=int(sel.sum()) > _RASTERIZE_ABOVE,
                    label=name,
                    linewidths=0.3 if few else 0.0,
                    **({"edgecolors": "black"} if few else {}),
                )
        ax.axhline(0.0, color="black", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"along the strip from the first photo [{plan.unit}]")
    fixed_title(
        axes[0], "Residuals (given − adjusted) at control and check points along the strip"
    )
    return _fitted_png(fig)


def _bars_or_lines(
    ax: Axes,
    x: FloatArray | IntArray,
    values: Sequence[FloatArray],
    labels: Sequence[str],
    colours: Sequence[str],
    width: float = 0.4,
) -> None:
    """Grouped bars (one collection per series) up to 120 positions, lines beyond."""
    from matplotlib.collections import PolyCollection

    many = len(x) > 120
    for k, (v, label, colour) in enumerate(zip(values, labels, colours, strict=True)):
        if many:
            ax.plot(x, v, "-", lw=0.9, color=colour, label=label)
            continue
        # the bars of ax.bar, drawn as one artist: corners (n, 4, 2)
        left = np.asarray(x, dtype=np.float64) + (k - (len(values) - 1) / 2) * width - width / 2
        top = np.nan_to_num(np.asarray(v, dtype=np.float64))
        corners = np.stack(
            [
                np.column_stack([left, np.zeros_like(top)]),
                np.column_stack([left, top]),
                np.column_stack([left + width, top]),
                np.column_stack([left + width, np.zeros_like(top)]),
            ],
            axis=1,
        )
        bars = PolyCollection(
            corners,  # type: ignore[arg-type]  # (n, 4, 2): PolyCollection's fast path
            facecolors=colour,
            edgecolors="none",
            linewidths=0,
            label=label,
        )
        bars.sticky_edges.y.append(0.0)  # as ax.bar: no margin below the bars' foot
        ax.add_collection(bars)
    if not many:
        ax.autoscale_view()


def _left_photo_ticks(ax: Any, x: FloatArray | IntArray, left: Sequence[str]) -> None:
    """Tick the pairs (models) at ``x`` by their ``left`` photo's id, at most 16."""
    index = np.asarray(x, dtype=np.intp)
    if index.size == 0 or index.max() >= len(left):
        return
    from matplotlib.ticker import FixedFormatter, FixedLocator

    shown = index[:: max(1, int(np.ceil(index.size / 16)))]
    # as ax.set_xticks(shown, labels, rotation=...), without making a tick
    # object per label (figures_ticks draws them)
    ax.xaxis.set_major_locator(FixedLocator(shown.astype(np.float64).tolist()))
    ax.xaxis.set_major_formatter(FixedFormatter([left[i] for i in shown]))
    ax.tick_params(axis="x", labelrotation=45 if shown.size > 6 else 0)


def figure_parallax(data: StripFigureData) -> str:
    from matplotlib.figure import Figure

    x = np.arange(data.n_pairs)
    fig = Figure(figsize=(11, 3.8))
    (ax, hx) = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.3, 1]})
    _bars_or_lines(
        ax,
        x,
        [data.sigma0_um, data.max_parallax_um],
        ["σ0 (one image coordinate)", "max |y-parallax|"],
        ["#2e86c1", "#e67e22"],
    )
    _left_photo_ticks(ax, x, data.left_photos)
    ax.set_xlabel("pair (its left photo)")
    ax.set_ylabel("µm at image scale")
    fixed_title(ax, "Relative orientation: residual y-parallax per pair")
    ax.grid(True, axis="y", lw=0.3)
    best = ax.legend(loc="best", fontsize=8)
    q = data.parallax_um
    q = q[np.isfinite(q)]
    if q.size:
        rms = float(np.sqrt(np.mean(q**2)))
        counts, edges = np.histogram(q, bins=min(60, max(10, q.size // 20)))
        hx.stairs(counts, edges, fill=True, color="#5d6d7e")  # one artist, as hist's bars
        for sign in (-1, 1):
            hx.axvline(sign * 3 * rms, color="#c0392b", lw=1.0, ls="--")
        fixed_title(hx, f"All {q.size} y-parallaxes; ±3 RMS dashed", fontsize=10)
        hx.set_xlabel("µm")
    return _fitted_png(fig, best=best)


def figure_ties(data: StripFigureData) -> str | None:
    from matplotlib.figure import Figure

    models = data.models
    if len(models) < 2:
        return None
    x = np.array([index for index, _ in models], dtype=np.float64)
    rms = np.array([[np.nan if v is None else v for v in m] for _, m in models], dtype=np.float64)
    plan = np.hypot(rms[:, 0], rms[:, 1])
    fig = Figure(figsize=(11, 3.6))
    ax = fig.subplots()
    _bars_or_lines(
        ax,
        x[1:],
        [plan[1:], np.abs(rms[1:, 2])],
        ["plan (X, Y)", "height (Z)"],
        ["#16a085", "#8e44ad"],
    )
    _left_photo_ticks(ax, x[1:], data.left_photos)
    ax.set_xlabel("model (its left photo)")
    ax.set_ylabel("RMS difference [m]")
    fixed_title(ax, "Differences between the two determinations of tie points, per model")
    ax.grid(True, axis="y", lw=0.3)
    return _fitted_png(fig, best=ax.legend(loc="best", fontsize=8))
