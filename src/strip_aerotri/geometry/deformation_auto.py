"""The automatic choice of the deformation polynomial type
(``polynomial = "auto"``): every type fitted and judged by its misfit
and its precision at the check-free points (:func:`select_kind_auto`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import GeometryError, StripAerotriWarning
from ..options import DEFAULT_SECTIONS
from .deformation import DeformationResult, StraightLine, fit_deformation
from .deformation_basis import _check_kind
from .similarity import _check_sigma

__all__ = ["KindSelection", "KindSummary", "select_kind_auto"]


class KindSummary(NamedTuple):
    """One row of the table of :func:`select_kind_auto`.

    ``feasible`` False means the kind was not fitted (``reason`` says why) and
    the numbers are NaN.  ``sigma0_xyz`` is unitless (the fit is weighted
    with the expected sigmas), ``rms_xyz`` in metres at the control,
    ``statistic_xyz`` the control part of vᵀPv and ``dof_xyz`` its degrees of
    freedom (sum of the control redundancy numbers), ``critical_xyz`` the
    chi-square quantile it is compared with, ``passed`` whether all three
    tests accept.
    """

    kind: int
    feasible: bool
    reason: str
    sigma0: float
    redundancy: int
    sigma0_xyz: FloatArray
    redundancy_xyz: tuple[int, int, int]
    rms_xyz: FloatArray
    statistic_xyz: FloatArray
    dof_xyz: FloatArray
    critical_xyz: FloatArray
    passed: bool


class KindSelection(NamedTuple):
    """The polynomial type chosen by :func:`select_kind_auto` and the table it used."""

    kind: int
    table: tuple[KindSummary, ...]


def select_kind_auto(
    xyz: ArrayLike,
    target: ArrayLike,
    *,
    use_xy: ArrayLike,
    use_z: ArrayLike,
    expected_sigma_xy: ArrayLike,
    expected_sigma_z: ArrayLike,
    lines: Sequence[StraightLine] = (),
    point_ids: Sequence[str] | None = None,
    kinds: Sequence[int] = (0, 1, 2, 3),
    min_redundancy: int = 2,
    confidence: float = 0.95,
    sections: int = DEFAULT_SECTIONS,
) -> KindSelection:
    """Choose the polynomial type ("auto"), as a photogrammetrist would.

    J's criterion (section 2.2): the best polynomial is the one that brings
    the residuals at the control down to the level expected from the random
    errors of the control and of the photogrammetric measurement.

    Rule
    ----
    1. Each kind in `kinds` (J(16) types 0..3) is fitted with
       :func:`fit_deformation`, weights ``1/expected_sigma²``, only if every
       coordinate has enough observations and a redundancy of at least
       `min_redundancy`; other kinds are listed as infeasible with the reason.
    2. For each fitted kind and each coordinate X, Y, Z the variance factor
       is tested: ``T = sum(v²/sigma²)`` over the control observations of
       that coordinate is compared with the upper quantile of chi-square with
       ``dof = sum of their redundancy numbers`` (equal to the redundancy when
       there are no straight lines; line equations are left out of T because
       their weight is a device to make the condition effective, not a
       measured precision).  The three tests run at level
       ``(1 - confidence) / 3`` each (Bonferroni), so the kind is accepted at
       the overall level ``1 - confidence`` (5 % by default).  A coordinate
       with ``dof = 0`` is not tested.
    3. The chosen kind is the lowest accepted one; if none is accepted, the
       highest feasible kind.

    Parameters
    ----------
    xyz, target, use_xy, use_z, lines, point_ids
        As for :func:`fit_deformation`.
    expected_sigma_xy, expected_sigma_z : float or array_like, shape (N,)
        Expected random error (metres) of a control coordinate after a
        correct deformation model: control survey, identification and
        photogrammetric measurement together.
    kinds : sequence of int
        Kinds to try.
    min_redundancy : int
        Minimum redundancy per coordinate for a kind to be tried.
    confidence : float
        Confidence level of the test (0.95).
    sections : int
        Sections along the strip for every type >= 1 (:func:`fit_deformation`).

    Returns
    -------
    KindSelection
        ``(kind, table)``; `table` has one :class:`KindSummary` per kind tried.

    Raises
    ------
    GeometryError
        No kind is feasible.
    """
    if not 0.0 < float(confidence) < 1.0:
        raise ValueError(f"Expected `confidence` in (0, 1), got {confidence!r}")
    if int(min_redundancy) < 0:
        raise ValueError(f"Expected `min_redundancy` >= 0, got {min_redundancy!r}")
    kinds_tried = tuple(_check_kind(k) for k in kinds)
    if not kinds_tried:
        raise ValueError("Expected at least one kind in `kinds`")
    alpha = (1.0 - float(confidence)) / 3.0
    table: list[KindSummary] = []
    nan3 = np.full(3, np.nan)
    for k in sorted(set(kinds_tried)):
        try:
            with warnings.catch_warnings():
                # a candidate without redundancy is judged by min_redundancy below
                warnings.filterwarnings("ignore", ".*no redundancy", StripAerotriWarning)
                res = fit_deformation(
                    xyz,
                    target,
                    use_xy=use_xy,
                    use_z=use_z,
                    kind=k,
                    sigma_xy=expected_sigma_xy,
                    sigma_z=expected_sigma_z,
                    lines=lines,
                    point_ids=point_ids,
                    sections=sections if k > 0 else 1,
                )
        except GeometryError as exc:
            table.append(
                KindSummary(
                    k, False, str(exc), np.nan, 0, nan3, (0, 0, 0), nan3, nan3, nan3, nan3, False
                )
            )
            continue
        if min(res.redundancy_xyz) < int(min_redundancy):
            table.append(
                KindSummary(
                    k,
                    False,
                    f"redundancy {res.redundancy_xyz} (X, Y, Z) below {int(min_redundancy)}",
                    res.sigma0,
                    res.redundancy,
                    res.sigma0_xyz,
                    res.redundancy_xyz,
                    nan3,
                    nan3,
                    nan3,
                    nan3,
                    False,
                )
            )
            continue
        rms, stat, dof, crit, ok = _variance_tests(
            res, (expected_sigma_xy, expected_sigma_z), alpha
        )
        table.append(
            KindSummary(
                k,
                True,
                "",
                res.sigma0,
                res.redundancy,
                res.sigma0_xyz,
                res.redundancy_xyz,
                rms,
                stat,
                dof,
                crit,
                ok,
            )
        )
    feasible = [row for row in table if row.feasible]
    if not feasible:
        reasons = "; ".join(f"type {row.kind}: {row.reason}" for row in table)
        raise GeometryError(f"no polynomial type is feasible for the control: {reasons}")
    passed = [row for row in feasible if row.passed]
    chosen = passed[0].kind if passed else feasible[-1].kind
    return KindSelection(chosen, tuple(table))


def _variance_tests(
    res: DeformationResult,
    expected_sigmas: tuple[ArrayLike, ArrayLike],
    alpha: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, bool]:
    """The variance factor of a fitted kind tested per coordinate X, Y, Z
    (rule 2 of :func:`select_kind_auto`): the RMS residual, ``T = sum(v² /
    sigma²)``, its degrees of freedom (the sum of the redundancy numbers),
    the chi-square quantile at ``1 - alpha`` (NaN where untested) and
    whether every tested coordinate passes."""
    from scipy.stats import chi2  # deferred: scipy.stats is slow to import

    n = res.residuals.shape[0]
    sig = np.column_stack(
        [
            _check_sigma(expected_sigmas[0], n, "expected_sigma_xy"),
            _check_sigma(expected_sigmas[0], n, "expected_sigma_xy"),
            _check_sigma(expected_sigmas[1], n, "expected_sigma_z"),
        ]
    )
    observed = np.isfinite(res.residuals)
    rms = np.full(3, np.nan)
    stat = np.full(3, np.nan)
    dof = np.full(3, np.nan)
    crit = np.full(3, np.nan)
    ok = True
    for c in range(3):
        o = observed[:, c]
        if not np.any(o):
            continue
        v = res.residuals[o, c]
        rms[c] = np.sqrt(np.mean(v**2))
        stat[c] = np.sum((v / sig[o, c]) ** 2)
        dof[c] = np.sum(res.redundancy_numbers[o, c])
        if dof[c] > 1e-9:
            crit[c] = chi2.ppf(1.0 - alpha, dof[c])
            ok = ok and bool(stat[c] <= crit[c])
    return rms, stat, dof, crit, ok
