"""The rows, error and normal blocks that :mod:`strip_aerotri.geometry.normals`
and its kernels (:mod:`strip_aerotri.geometry._normal_assembly`) share: the
four kinds of rows with their whitening, the normal blocks of one
linearisation, what a singular system raises, and the shape of a structure
the kernels read (so that neither imports the other back)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import GeometryError
from ._normal_pattern import Pattern


class StructureLike(Protocol):
    """What the kernels read of a :class:`~strip_aerotri.geometry.normals.NormalStructure`."""

    @property
    def n_units(self) -> int: ...

    @property
    def unit_size(self) -> int: ...

    @property
    def n_points(self) -> int: ...

    @property
    def n_border(self) -> int: ...

    @property
    def pattern(self) -> Pattern: ...

    def unit_name(self, i: int) -> str: ...

    def point_name(self, i: int) -> str: ...

    def parameter_name(self, j: int) -> str: ...


#: Ratio of smallest to largest eigenvalue of a point's (damped) 3 x 3 normal
#: block below which the point counts as undetermined.
POINT_RANK_TOL = 1e-10


class SingularNormalsError(GeometryError):
    """The normal equations are singular; ``kind`` is "unit", "point" or
    "border", ``index`` the unit, point or border parameter, ``parameter``
    the component within the unit or point (None when not known)."""

    def __init__(self, message: str, kind: str, index: int, parameter: int | None = None):
        super().__init__(message)
        self.kind = kind
        self.index = index
        self.parameter = parameter


def _as_weight(weight: ArrayLike | None, g: int, r: int) -> FloatArray | None:
    if weight is None:
        return None
    w = np.asarray(weight, dtype=np.float64)
    if w.shape not in ((g, r), (g, r, r)):
        raise ValueError(f"Expected `weight` to have shape {(g, r)} or {(g, r, r)}, got {w.shape}")
    if w.ndim == 2 and not np.all(w >= 0.0):
        raise ValueError("Expected non-negative diagonal weights")
    return w


def _whiten(weight: FloatArray | None, *arrays: FloatArray) -> tuple[FloatArray, ...]:
    """Rows times T (Tᵀ T = weight); each array (g, r, ...)."""
    if weight is None:
        return arrays
    if weight.ndim == 2:
        s = np.sqrt(weight)
        return tuple(a * s.reshape(s.shape + (1,) * (a.ndim - 2)) for a in arrays)
    try:
        t = np.swapaxes(np.linalg.cholesky(weight), 1, 2)  # P = L Lᵀ, T = Lᵀ
    except np.linalg.LinAlgError as exc:
        raise ValueError("Expected positive definite weight matrices") from exc
    out = []
    for a in arrays:
        flat = a.reshape(a.shape[0], a.shape[1], -1)
        out.append((t @ flat).reshape(a.shape))
    return tuple(out)


def _check(a: ArrayLike, shape: tuple[int, ...], name: str) -> FloatArray:
    x = np.asarray(a, dtype=np.float64)
    if x.shape != shape:
        raise ValueError(f"Expected `{name}` to have shape {shape}, got {x.shape}")
    return x


@dataclass(frozen=True)
class UnitPointRows:
    """Rows on one unit and one point each (see the module docstring).

    ``unit_shift``: the unit's first three parameters shift it as the
    opposite shift of the point does, ``unit_jacobian[..., :3] ==
    -point_jacobian`` exactly (a photo's projection centre against its image
    points); the blocks are then formed from the distinct products alone
    (ValueError when the Jacobians do not agree)."""

    unit: IntArray
    point: IntArray
    unit_jacobian: FloatArray
    point_jacobian: FloatArray
    residual: FloatArray
    weight: FloatArray | None = None
    border_jacobian: FloatArray | None = None
    unit_shift: bool = False

    def whitened(self, k: int, d: int) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """T A_unit, T A_point, T f, T A_border for k border and d unit parameters."""
        g, r = np.shape(self.residual)
        au = _check(self.unit_jacobian, (g, r, d), "unit_jacobian")
        ap = _check(self.point_jacobian, (g, r, 3), "point_jacobian")
        f = _check(self.residual, (g, r), "residual")
        ab = _border(self.border_jacobian, g, r, k)
        return _whiten(_as_weight(self.weight, g, r), au, ap, f, ab)  # type: ignore[return-value]


@dataclass(frozen=True)
class UnitRows:
    """Rows on units alone: ``units`` (g, q), ``jacobian`` (g, r, q, d)."""

    units: IntArray
    jacobian: FloatArray
    residual: FloatArray
    weight: FloatArray | None = None
    border_jacobian: FloatArray | None = None

    def whitened(self, k: int, d: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """T A, T f, T A_border for k border and d unit parameters."""
        g, r = np.shape(self.residual)
        q = np.shape(self.units)[1]
        a = _check(self.jacobian, (g, r, q, d), "jacobian")
        f = _check(self.residual, (g, r), "residual")
        ab = _border(self.border_jacobian, g, r, k)
        return _whiten(_as_weight(self.weight, g, r), a, f, ab)  # type: ignore[return-value]


@dataclass(frozen=True)
class PointRows:
    """Rows on points alone: ``point`` (g,), ``jacobian`` (g, r, 3)."""

    point: IntArray
    jacobian: FloatArray
    residual: FloatArray
    weight: FloatArray | None = None
    border_jacobian: FloatArray | None = None

    def whitened(self, k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        g, r = np.shape(self.residual)
        a = _check(self.jacobian, (g, r, 3), "jacobian")
        f = _check(self.residual, (g, r), "residual")
        ab = _border(self.border_jacobian, g, r, k)
        return _whiten(_as_weight(self.weight, g, r), a, f, ab)  # type: ignore[return-value]


@dataclass(frozen=True)
class BorderRows:
    """Rows on the border alone: ``jacobian`` (g, r, k)."""

    jacobian: FloatArray
    residual: FloatArray
    weight: FloatArray | None = None

    def whitened(self, k: int) -> tuple[FloatArray, FloatArray]:
        g, r = np.shape(self.residual)
        a = _check(self.jacobian, (g, r, k), "jacobian")
        f = _check(self.residual, (g, r), "residual")
        return _whiten(_as_weight(self.weight, g, r), a, f)  # type: ignore[return-value]


Rows = UnitPointRows | UnitRows | PointRows | BorderRows


def _border(a: FloatArray | None, g: int, r: int, k: int) -> FloatArray:
    if a is None:
        return np.zeros((g, r, k))
    return _check(a, (g, r, k), "border_jacobian")


@dataclass
class _Normals:
    """The normal blocks at one linearisation (position order for the band)."""

    band: FloatArray  # (n, w+1, d, d) U alone, position order
    g_unit: FloatArray  # (n, d) Aᵀ T f by unit
    v: FloatArray  # (p, 3, 3)
    g_point: FloatArray  # (p, 3)
    w: FloatArray  # (d, 3, n_pairs), entry-major (the pairs last)
    unit_border: FloatArray  # (n, d, k)
    point_border: FloatArray  # (p, 3, k)
    border: FloatArray  # (k, k)
    g_border: FloatArray  # (k,)
    cost: float
