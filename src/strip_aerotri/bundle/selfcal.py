"""Which camera parameters a self-calibrating bundle estimates (method.md 6C).

``[adjustment] self_calibration`` names a list of Brown/Fraser parameters, or
``"ebner12"``, which are estimated as given, or ``"auto"``: start from all ten
Brown/Fraser parameters and hold, at their start values, those the data do not
determine or that are not significant, one decision per adjustment, until the
set is stable:

1. every parameter whose multiple correlation with the photos' orientation and
   the points exceeds its bound: :data:`PRINCIPAL_DISTANCE_CORRELATION`
   (1 - 1e-6) for c, :data:`INTERIOR_CORRELATION` (0.999) for x0, y0,
   :data:`MAX_ORIENTATION_CORRELATION` (0.9999) for the others.  c is the
   flying height's twin over flat ground seen from vertical photos, and x0,
   y0 the centres' unless GNSS centres or oblique photos separate them: a
   confusion the geometry makes exact.  c's bound holds only that exact
   confusion; with 1 - rho above 1e-6 its t value decides, as for the lens
   terms, because
   relief and oblique photos do determine c (its own information is the
   depth's spread within a photo) and, with the residuals in the
   observations' space, its t value is honest.  The correlation does not
   depend on the other camera parameters, so all such are held at once.
   While x0 or y0 is held so, the decentring terms p1, p2 are judged by the
   bound of x0, y0: over a small format the decentring field is mostly a
   shift of the principal point and a tilt of the image (Fraser 1997, the
   projective coupling of p1, p2 with x0, y0), so with the principal point
   absorbed by the orientation they stand in for its remainder rather than
   for the lens (on the real FC300X block they are held at a multiple
   correlation of 0.9995, and the check points gain 3 mm in plan over six
   control splits; docs/bundle.md);
2. of the most correlated pair of parameters above :data:`MAX_CORRELATION`,
   the one with the smaller t value;
3. the parameter with the smallest t value, if below :data:`T_CRITICAL`.

The chosen set must then lower the sum of squares significantly (an F test
of the set against the same adjustment without it, at ``alpha = 0.001``);
otherwise the camera is left as given ("never make a well-calibrated project
worse").  Every held parameter is named in a note with its reason.

How it runs (:func:`_auto`): rule 1 is judged first, from the normal
equations of all ten at the start values, no step taken (a multiple
correlation is the design's; a trial adjustment with c and x0 at a
correlation of 1.0000 needed 50 iterations and did not converge on a
2000-photo strip).  The rest are adjusted once, and rules 1-3 walk down that
adjustment's border one decision at a time by the algebra of
:mod:`strip_aerotri.bundle.camera_subsets` (each subset's estimates,
cofactors and sum of squares, k x k), instead of adjusting the block again
per decision; the set they end with is adjusted for real (from where the
last adjustment ended), and the rules run again on it until an adjustment
holds nothing more.  The F test takes the sum of squares without the camera
from the same algebra.  On the 2000-photo drone strip of
``benchmarks/bench_selfcal_scale.py`` this is one evaluation and one
adjustment of two iterations instead of nine adjustments; the choice is the
same as with every subset adjusted (tests/test_camera_subsets.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .._typing import FloatArray
from ..geometry.camera_model import (
    BROWN_PARAMETERS,
    EBNER_PARAMETERS,
    PARAMETER_UNITS,
    CameraModel,
)
from ..options import FlightDirection, SelfCalibration
from ..results import (
    BundleResult,
    CameraEstimate,
    FrameRefinement,
    ParameterOutcome,
    ResidualCells,
    SelfCalibrationOutcome,
)
from .adjust import CameraUndetermined
from .camera_subsets import LinearisedCamera

__all__ = [
    "INTERIOR_CORRELATION",
    "MAX_CORRELATION",
    "MAX_ORIENTATION_CORRELATION",
    "PRINCIPAL_DISTANCE_CORRELATION",
    "T_CRITICAL",
    "SelfCalibration",
    "Trials",
    "camera_model",
    "carried_choice",
    "ebner_base_mm",
    "final_outcome",
    "residual_cells",
    "start_model",
]

#: |t| below which "auto" holds a parameter (two-sided, about 0.3 %).
T_CRITICAL = 3.0
#: Correlation between two camera parameters above which "auto" holds one.
MAX_CORRELATION = 0.9
#: Multiple correlation with the orientation and points above which "auto"
#: holds a lens or affinity parameter whatever its t value (a variance
#: inflation of 5000).  A multiple correlation with thousands of unknowns is
#: high for every parameter of a strip (0.93-0.9998 for lens and affinity
#: terms that the data do determine, at t of 6-30: simulated drone blocks, the
#: real FC300X block), so the pairwise bound of 0.9 does not apply to it;
#: below this bound the t test decides.
MAX_ORIENTATION_CORRELATION = 0.9999
#: The same bound for x0 and y0, whose confusion with the centres the geometry
#: makes exact on flat ground (0.9999-1.0000 on every block here; on the real
#: FC300X block, oblique, x0 and y0 let in by their t values lower the check
#: RMSE of no control split: docs/bundle.md).
INTERIOR_CORRELATION = 0.999
#: The bound for c: 1 - rho below 1e-6 (a variance inflation above 5e5) is
#: the flying height's confusion made exact, vertical photos over flat ground
#: (1 - rho from 8e-9 to 3e-5 over the sweep's 78 simulated strips,
#: continuously; a film strip at 2e-7 with 49 um of uncorrected lens error
#: fails its blunder tests when c is let in there).  With 1 - rho above 1e-6
#: c's t value decides: the oblique FC300X block (1 - rho 3e-5 to 6e-5)
#: determines c at t of 3-10, and a start c 0.4 % off (the EXIF focal
#: length) is corrected to within 0.5 sd of the calibrated one; film strips
#: over relief of a quarter of their height, at 5e-6 to 1.4e-5, find a c
#: 0.33 % off within 3 sd (docs/bundle.md).
PRINCIPAL_DISTANCE_CORRELATION = 1.0 - 1e-6
#: False-alarm probability of the F test of the chosen set against none.
ALPHA_SET = 0.001

_FLIGHT = {
    FlightDirection.PLUS_X: np.array([[1.0, 0.0], [0.0, 1.0]]),
    FlightDirection.MINUS_X: np.array([[-1.0, 0.0], [0.0, -1.0]]),
    FlightDirection.PLUS_Y: np.array([[0.0, 1.0], [-1.0, 0.0]]),
    FlightDirection.MINUS_Y: np.array([[0.0, -1.0], [1.0, 0.0]]),
}

#: What the exterior orientation absorbs of each parameter, for the notes.
_ABSORBED_BY = {
    "c": "the flying height",
    "x0": "the centres and rotations",
    "y0": "the centres and rotations",
}
#: The decentring terms, and what they stand in for while the orientation
#: absorbs the principal point (module notes).
_COUPLED_WITH_PRINCIPAL_POINT = {
    "p1": "decentring, coupled with the principal point the orientation absorbs",
    "p2": "decentring, coupled with the principal point the orientation absorbs",
}

def camera_model(
    spec: SelfCalibration, names: tuple[str, ...], c_mm: float, base_mm: float
) -> CameraModel:
    """The camera model of ``spec`` estimating ``names``."""
    return CameraModel(
        spec.family, names, c_mm, base_mm, flight_matrix=_FLIGHT[spec.flight_direction]
    )


def ebner_base_mm(centres: FloatArray, points: FloatArray, c_mm: float) -> float:
    """The base at image scale (mm): the median distance of consecutive centres
    times c over the median height of the centres above the points."""
    good = points[np.all(np.isfinite(points), axis=1)]
    if centres.shape[0] < 2 or good.shape[0] == 0:
        return float("nan")
    step = float(np.median(np.linalg.norm(np.diff(centres, axis=0), axis=1)))
    height = float(np.median(centres[:, 2]) - np.median(good[:, 2]))
    return c_mm * step / height if height > 0 else float("nan")


class Trials(Protocol):
    """The adjustments ``"auto"`` chooses with (without blunder tests)."""

    def screen(self, model: CameraModel) -> BundleResult:
        """``model`` evaluated at the start values, without a step: the
        design's correlations (the camera's values are one linearised step's,
        ``bundle_adjust(max_iterations=0)``)."""

    def adjust(self, model: CameraModel | None, start: FloatArray | None) -> BundleResult:
        """An adjustment to convergence from the last one's photos and points,
        the camera from ``start`` (None: the start camera)."""


@dataclass
class _Choice:
    """What ``"auto"`` has held so far, why, and the last estimate of each."""

    held: dict[str, str] = field(default_factory=dict)
    absorbed: set[str] = field(default_factory=set)  # held because the orientation absorbs them
    last: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)

    def hold(self, name: str, reason: str, by_orientation: bool) -> None:
        self.held[name] = reason
        if by_orientation:
            self.absorbed.add(name)

    def seen(self, cam: CameraEstimate) -> None:
        """Every parameter of ``cam`` with its value, std, t and multiple correlation."""
        for i, name in enumerate(cam.names):
            self.last[name] = (
                float(cam.values[i]),
                float(cam.std[i]),
                float(cam.t_values[i]),
                float(cam.orientation_correlation[i]),
            )


def _auto(
    spec: SelfCalibration, trials: Trials, c_mm: float, base_mm: float
) -> tuple[CameraEstimate | None, SelfCalibrationOutcome]:
    """``"auto"`` (module notes): the orientation's correlations from the
    normal equations of every candidate at the start values; then an
    adjustment of the rest, whose border the rules walk down
    (:class:`LinearisedCamera`), until an adjustment of the set they end with
    holds nothing more."""

    def model(names: Sequence[str]) -> CameraModel:
        return camera_model(spec, tuple(names), c_mm, base_mm)

    choice = _Choice()
    active = _screened(trials, model, choice)
    fit: LinearisedCamera | None = None
    start: FloatArray | None = None
    while active:
        try:
            fit = LinearisedCamera.of(trials.adjust(model(active), start))
        except CameraUndetermined as exc:
            name = exc.name or active[-1]
            choice.hold(name, "not determined by the data", True)
            active.remove(name)
            fit, start = None, None
            continue
        chosen, walked = _walked(fit, choice, model)
        if chosen == active or not chosen:
            active = chosen
            break
        active, start = chosen, walked.estimate.values
    notes: list[str] = []
    if fit is None:  # every candidate held before any adjustment of the set
        sigma0_without = trials.adjust(None, None).sigma0
    else:
        k = len(fit.estimate.names)
        sigma0_without = float(np.sqrt(fit.cost_without / (fit.redundancy + k)))
    if active and fit is not None and not _significant(fit):
        notes.append(
            "self-calibration: the parameters "
            + ", ".join(active)
            + " do not lower the residuals significantly together (F test); the camera is "
            "left as given"
        )
        for name in active:
            choice.hold(name, "the set is not significant (F test against none)", False)
        active = []
    if choice.held:
        notes.insert(
            0,
            # the names first: a message cut at a list item still names them all
            f"self-calibration held {len(choice.held)} parameter(s) at their start values "
            f"({', '.join(choice.held)}): "
            + "; ".join(f"{n} ({why})" for n, why in choice.held.items()),
        )
    cam = fit.estimate if active and fit is not None else None
    outcome = _outcome(spec, cam, choice.held, choice.last, sigma0_without, tuple(notes))
    return cam, outcome


def _screened(
    trials: Trials, model: Callable[[Sequence[str]], CameraModel], choice: _Choice
) -> list[str]:
    """The candidates left once those the orientation absorbs are held (rule 1),
    judged from one step of all of them: a multiple correlation is the design's
    and does not depend on the other camera parameters."""
    active = list(BROWN_PARAMETERS)
    while active:
        try:
            cam = trials.screen(model(active)).camera
        except CameraUndetermined as exc:
            name = exc.name or active[-1]
            choice.hold(name, "not determined by the data", True)
            active.remove(name)
            continue
        assert cam is not None
        choice.seen(cam)  # one linearised step's estimates, for the held ones' record
        r_eo = dict(zip(cam.names, cam.orientation_correlation, strict=True))
        while hold := _absorbed(active, [r_eo[n] for n in active], choice.absorbed):
            for name, reason in hold:
                choice.hold(name, reason, True)
                active.remove(name)
        break
    return active


def _walked(
    fit: LinearisedCamera, choice: _Choice, model: Callable[[Sequence[str]], CameraModel]
) -> tuple[list[str], LinearisedCamera]:
    """The rules applied to ``fit``'s subsets, one decision at a time, down to
    the set they keep (with its linearised estimate)."""
    names = list(fit.estimate.names)
    current = fit
    while names:
        choice.seen(current.estimate)
        hold = _next_to_hold(current.estimate, choice.absorbed)
        if not hold:
            break
        for name, reason, by_orientation in hold:
            choice.hold(name, reason, by_orientation)
            names.remove(name)
        if names:
            current = fit.subset(names, model(names))
    return names, current


def _absorbed(
    names: Sequence[str], r_eo: Sequence[float], absorbed: set[str]
) -> list[tuple[str, str]]:
    """Rule 1: the parameters whose multiple correlation with the orientation
    is over their bound, with the reason; ``absorbed`` those held so far for it."""
    principal_point = {
        n for n, r in zip(names, r_eo, strict=True) if n in ("x0", "y0") and r > _bound(n, True)
    }
    coupled = bool((absorbed | principal_point) & {"x0", "y0"})
    why = dict(_ABSORBED_BY, **(_COUPLED_WITH_PRINCIPAL_POINT if coupled else {}))
    return [
        (n, _correlation_reason(n, r, why))
        for n, r in zip(names, r_eo, strict=True)
        if r > _bound(n, n in why)
    ]


def _bound(name: str, absorbed: bool) -> float:
    """Rule 1's bound for ``name``; ``absorbed``: judged as a parameter the
    orientation absorbs (c, x0, y0, and p1, p2 while x0 or y0 is held)."""
    if name == "c":
        return PRINCIPAL_DISTANCE_CORRELATION
    return INTERIOR_CORRELATION if absorbed else MAX_ORIENTATION_CORRELATION


def _correlation_reason(name: str, r: float, why: dict[str, str]) -> str:
    """``name``'s multiple correlation ``r`` with the orientation, and what
    absorbs it (six digits: c's bound is within 1e-6 of one)."""
    digits = 6 if r > 0.9999 else 4
    return f"correlation {r:.{digits}f} with the exterior orientation" + (
        f": {why[name]}" if name in why else ""
    )


def _next_to_hold(cam: CameraEstimate, absorbed: set[str]) -> list[tuple[str, str, bool]]:
    """The parameters to hold after one adjustment, with reasons and whether
    the orientation absorbs them (empty: stable); ``absorbed`` the parameters
    held so far because it does."""
    over = _absorbed(cam.names, list(cam.orientation_correlation), absorbed)
    if over:
        return [(name, reason, True) for name, reason in over]
    t = np.abs(cam.t_values)
    corr = np.abs(cam.correlations) - np.eye(len(cam.names))
    if corr.size and np.max(corr) > MAX_CORRELATION:
        i, j = np.unravel_index(int(np.argmax(corr)), corr.shape)
        weak, strong = (i, j) if t[i] < t[j] else (j, i)
        return [
            (
                cam.names[weak],
                f"correlation {corr[i, j]:.3f} with {cam.names[strong]}",
                False,
            )
        ]
    worst = int(np.argmin(t))
    if t[worst] < T_CRITICAL:
        name, r = cam.names[worst], float(cam.orientation_correlation[worst])
        reason = f"t = {t[worst]:.2f}, below {T_CRITICAL:g}"
        if name in _ABSORBED_BY and r > INTERIOR_CORRELATION:  # say what the t value means
            reason += f"; {_correlation_reason(name, r, _ABSORBED_BY)}"
        return [(name, reason, False)]
    return []


def _significant(fit: LinearisedCamera) -> bool:
    """F test: does the camera set lower the weighted sum of squares
    significantly (against the same adjustment with the camera as given)?"""
    from scipy.stats import f as f_dist

    k = len(fit.estimate.names)
    red = fit.redundancy
    if k <= 0 or red <= 0:
        return False
    statistic = (fit.cost_without - fit.cost) / k / (fit.cost / red)
    return bool(statistic > f_dist.ppf(1.0 - ALPHA_SET, k, red))


def _outcome(
    spec: SelfCalibration,
    cam: CameraEstimate | None,
    held: dict[str, str],
    last: dict[str, tuple[float, float, float, float]],
    sigma0_without: float,
    notes: tuple[str, ...],
) -> SelfCalibrationOutcome:
    """Every candidate's outcome, and the strongly correlated pairs."""
    current: dict[str, tuple[float, float, float, float]] = dict(last)
    correlations: list[tuple[str, str, float]] = []
    if cam is not None:
        for i, name in enumerate(cam.names):
            current[name] = (
                float(cam.values[i]),
                float(cam.std[i]),
                float(cam.t_values[i]),
                float(cam.orientation_correlation[i]),
            )
        corr = cam.correlations
        ii, jj = np.triu_indices(len(cam.names), 1)
        strong = np.abs(corr[ii, jj]) > MAX_CORRELATION
        correlations = [
            (cam.names[i], cam.names[j], float(corr[i, j]))
            for i, j in zip(ii[strong], jj[strong], strict=True)
        ]
    kept = set(cam.names) if cam is not None else set()
    candidates = EBNER_PARAMETERS if spec.family == "ebner" else BROWN_PARAMETERS
    if spec.choice not in ("auto", "ebner12"):
        candidates = tuple(spec.choice)
    nan4 = (float("nan"),) * 4
    parameters = tuple(
        ParameterOutcome(
            name=n,
            unit=PARAMETER_UNITS[n],
            value=current.get(n, nan4)[0],
            std=current.get(n, nan4)[1],
            t=current.get(n, nan4)[2],
            kept=n in kept,
            reason="" if n in kept else held.get(n, "not estimated"),
            orientation_correlation=current.get(n, nan4)[3],
        )
        for n in candidates
    )
    return SelfCalibrationOutcome(
        choice=spec.choice,
        family=spec.family,
        parameters=parameters,
        correlations=tuple(correlations),
        estimate=cam,
        sigma0_without=sigma0_without,
        notes=notes,
    )


def start_model(
    spec: SelfCalibration, trials: Trials, c_mm: float, base_mm: float
) -> tuple[CameraModel | None, FloatArray | None, SelfCalibrationOutcome | None]:
    """The model to adjust with (None: none), its start values and, for
    ``"auto"``, the outcome of the choice (completed by :func:`final_outcome`)."""
    if spec.choice != "auto":
        names = EBNER_PARAMETERS if spec.choice == "ebner12" else tuple(spec.choice)
        return camera_model(spec, names, c_mm, base_mm), None, None
    cam, outcome = _auto(spec, trials, c_mm, base_mm)
    if cam is None:
        return None, None, outcome
    return cam.model, cam.values, outcome


def final_outcome(
    spec: SelfCalibration, chosen: SelfCalibrationOutcome | None, cam: CameraEstimate | None
) -> SelfCalibrationOutcome:
    """The outcome with the delivered adjustment's estimates (after the blunder tests)."""
    if chosen is None:
        return _outcome(spec, cam, {}, {}, float("nan"), ())
    held = {p.name: p.reason for p in chosen.parameters if not p.kept}
    last = {
        p.name: (p.value, p.std, p.t, p.orientation_correlation) for p in chosen.parameters
    }
    return _outcome(spec, cam, held, last, chosen.sigma0_without, chosen.notes)


def residual_cells(
    cam: CameraEstimate, xy: FloatArray, residuals_mm: FloatArray, n_cells: int = 8
) -> ResidualCells | None:
    """Image residuals (K, 2; flight axes, mm) at the observations ``xy`` (K, 2)
    averaged in ``n_cells`` x ``n_cells`` cells over the format, in the sensor
    axes and µm, with the camera's correction (``after``: ``v = x̂ - x_obs``,
    ``x̂ + Δ(x̂) = x`` the projection) and without it (``before``: ``x - x_obs
    = v + Δ(x̂)``, ``x̂ = x_obs + v``)."""
    good = np.all(np.isfinite(residuals_mm), axis=1) & np.all(np.isfinite(xy), axis=1)
    if not good.any():
        return None
    turn = cam.model.flight_matrix
    xy_s = xy[good] @ turn  # rows f = M s: s = f M
    after = residuals_mm[good] @ turn
    true_xy = xy[good] + residuals_mm[good]
    before = after + cam.model.correction(true_xy, cam.values) @ turn
    lo, hi = xy_s.min(axis=0), xy_s.max(axis=0)
    x_edges = np.linspace(lo[0], hi[0], n_cells + 1)
    y_edges = np.linspace(lo[1], hi[1], n_cells + 1)
    ix = np.clip(np.searchsorted(x_edges, xy_s[:, 0], side="right") - 1, 0, n_cells - 1)
    iy = np.clip(np.searchsorted(y_edges, xy_s[:, 1], side="right") - 1, 0, n_cells - 1)
    cell = iy * n_cells + ix
    count = np.bincount(cell, minlength=n_cells * n_cells)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = [
            np.stack(
                [np.bincount(cell, v[:, j], n_cells * n_cells) / count for j in range(2)], axis=-1
            ).reshape(n_cells, n_cells, 2)
            * 1000.0
            for v in (after, before)
        ]
    return ResidualCells(x_edges, y_edges, means[0], means[1], count.reshape(n_cells, n_cells))


def carried_choice(
    spec: SelfCalibration, chosen: SelfCalibrationOutcome | None, fr: FrameRefinement
) -> tuple[FrameRefinement, SelfCalibrationOutcome | None, SelfCalibration | None]:
    """A refinement adjusted again (another pass, other weights) keeps the first
    one's choice of parameters and its reasons.

    ``chosen`` is the first adjustment's outcome (None: ``fr`` is the first).
    Returns ``fr`` with its outcome told the first one's reasons, the first
    outcome, and the self-calibration the next adjustment runs with: the kept
    parameters as a list (None when none was kept).
    """
    if fr.self_calibration is None:
        if chosen is None:
            return fr, None, None
        # nothing was kept, so this adjustment estimated no camera: the first's
        # choice and its reasons are still what the user asked to see
        held = dataclasses.replace(fr, self_calibration=final_outcome(spec, chosen, None))
        return held, chosen, None
    chosen = chosen or fr.self_calibration
    fr = dataclasses.replace(
        fr,
        self_calibration=dataclasses.replace(
            final_outcome(spec, chosen, fr.bundle.camera), cells=fr.self_calibration.cells
        ),
    )
    kept = chosen.kept
    if not kept:
        return fr, chosen, None
    family = "ebner12" if chosen.family == "ebner" else kept
    return fr, chosen, SelfCalibration(family, spec.flight_direction)
