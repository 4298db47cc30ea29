"""Results every stage shares: blunder rejections, warnings about one point
and accuracy figures."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._text import named
from .._typing import FloatArray

__all__ = ["AccuracyStatistics", "PointWarning", "Rejection"]


@dataclass(frozen=True)
class Rejection:
    """One observation that failed its test.

    Attributes
    ----------
    stage : str
        One of :data:`STAGES`.
    point : str
        The point id; ``""`` for a GNSS centre or an IMU attitude.
    photos : tuple of str
        The photos involved (a pair, the photos of a model pair, the photo
        of a GNSS centre or IMU attitude, or none for ground control).
    component : str
        What was tested: ``"y-parallax"``, ``"X"``/``"Y"``/``"Z"`` of a tie
        difference, ``"plan"``/``"height"`` of a control point, ``"line"``,
        ``"x"``/``"y"`` of an image coordinate, ``"E"``/``"N"``/``"U"`` of a
        GNSS centre (the component of the largest ``|w|``), ``"about x"``/
        ``"about y"``/``"about z"`` of an IMU attitude (rotation about the
        photo's image axis, unit ``"deg"``).
    residual : float
        The residual, in ``unit``.
    unit : str
    w : float
        Test value.
    critical : float
    applied : bool
        False when the run only reports (``action = "report"``).
    effect : str
        What the rejection did (e.g. sigma0 before and after).
    """

    stage: str
    point: str
    photos: tuple[str, ...]
    component: str
    residual: float
    unit: str
    w: float
    critical: float
    applied: bool
    effect: str = ""

    def describe(self) -> str:
        if self.point:
            where = f" point {self.point!r}"
            where += f" on {'-'.join(self.photos)}" if self.photos else ""
        else:  # GNSS centre, IMU attitude: an observation of the photo itself
            where = f" photo {'-'.join(self.photos)}"
        verb = "rejected" if self.applied else "would be rejected"
        return (
            f"{self.stage}:{where} {verb}: {self.component} residual "
            f"{self.residual:.4g} {self.unit}, w = {self.w:.2f} > {self.critical:.2f}"
            + (f" ({self.effect})" if self.effect else "")
        )


class PointWarning(str):
    """A warning about one point: the text (this string, as a run's
    ``warnings`` list it) and, as data, what it is about.

    It is a ``str``, so that the warnings stay a tuple of texts everywhere
    (report.json, the page, the command line); the summary sums up warnings
    of one ``kind`` and ``cause`` by these attributes, never by reading the
    text.

    Attributes
    ----------
    kind : str
        ``"weak check"`` (a check point weakly determined by its own rays),
        ``"control not triangulated"`` or ``"check not triangulated"`` (a
        ground point left out); ``"points not triangulated"`` for the one
        warning about all the points the strip method left out for a cause.
    point : str
        The point's id, as given (any characters); ``""`` for a warning
        about several.
    cause : str
        Why, where the text names one (``""`` otherwise).
    points : tuple of str
        The points of a warning about several (``(point,)`` for one).
    """

    kind: str
    point: str
    cause: str
    points: tuple[str, ...]

    def __new__(
        cls,
        text: str,
        *,
        kind: str,
        point: str,
        cause: str = "",
        points: tuple[str, ...] | None = None,
    ) -> PointWarning:
        self = super().__new__(cls, text)
        about = (point,) if points is None else tuple(points)
        for name, value in (("kind", kind), ("point", point), ("cause", cause), ("points", about)):
            object.__setattr__(self, name, value)
        return self

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"PointWarning is immutable (setting {name!r})")

    def __reduce__(self) -> tuple[Any, ...]:
        return _point_warning, (str(self), self.kind, self.point, self.cause, self.points)

    @classmethod
    def weak_check(cls, point: str, text: str) -> PointWarning:
        """A check point weakly determined by its own rays, ``text`` saying
        how (:func:`strip_aerotri.ground.check_precision.weak_check_message`)."""
        return cls(text, kind="weak check", point=point)

    @classmethod
    def not_triangulated(cls, point: str, cause: str, *, check: bool = False) -> PointWarning:
        """A control (or ``check``) point that no model determines, left out:
        ``control point 'P' is not triangulated (cause): left out``."""
        kind = "check" if check else "control"
        return cls(
            f"{kind} point {point!r} is not triangulated ({cause}): left out",
            kind=f"{kind} not triangulated", point=point, cause=cause,
        )  # fmt: skip

    @classmethod
    def points_not_triangulated(cls, points: Sequence[str], cause: str) -> PointWarning:
        """All the points the strip method left out for one ``cause``:
        ``N point(s) not triangulated (cause): 'A', 'B' ...`` (five named)."""
        return cls(
            f"{len(points)} point(s) not triangulated ({cause}): {named(points)}",
            kind="points not triangulated", point="", cause=cause, points=tuple(points),
        )  # fmt: skip


def _point_warning(
    text: str, kind: str, point: str, cause: str, points: tuple[str, ...] | None = None
) -> PointWarning:
    """:class:`PointWarning` from its pickled fields."""
    return PointWarning(text, kind=kind, point=point, cause=cause, points=points)


@dataclass(frozen=True)
class AccuracyStatistics:
    """Discrepancies (given minus adjusted) at a set of points, metres.

    ``rmse`` is (E, N, H); ``rmse_plan`` = sqrt(rmse_E² + rmse_N²);
    ``mean_plan`` the mean plan discrepancy (the figure R4 §1.7.7 limits);
    ``max_plan``, ``max_height`` the largest absolute ones; counts of points
    with plan and with height discrepancies.
    """

    n_plan: int
    n_height: int
    rmse: FloatArray
    rmse_plan: float
    mean_plan: float
    max_plan: float
    max_height: float

    @classmethod
    def from_residuals(cls, residuals: FloatArray) -> AccuracyStatistics:
        r = np.asarray(residuals, dtype=np.float64).reshape(-1, 3)
        plan_ok = np.isfinite(r[:, 0]) & np.isfinite(r[:, 1])
        h_ok = np.isfinite(r[:, 2])
        with np.errstate(invalid="ignore"):
            rmse = np.array(
                [
                    np.sqrt(np.mean(r[plan_ok, 0] ** 2)) if plan_ok.any() else np.nan,
                    np.sqrt(np.mean(r[plan_ok, 1] ** 2)) if plan_ok.any() else np.nan,
                    np.sqrt(np.mean(r[h_ok, 2] ** 2)) if h_ok.any() else np.nan,
                ]
            )
        plan = np.hypot(r[plan_ok, 0], r[plan_ok, 1])
        return cls(
            n_plan=int(plan_ok.sum()),
            n_height=int(h_ok.sum()),
            rmse=rmse,
            rmse_plan=float(np.hypot(rmse[0], rmse[1])),
            mean_plan=float(plan.mean()) if plan.size else float("nan"),
            max_plan=float(plan.max()) if plan.size else float("nan"),
            max_height=float(np.abs(r[h_ok, 2]).max()) if h_ok.any() else float("nan"),
        )
