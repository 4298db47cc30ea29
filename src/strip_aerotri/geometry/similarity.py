"""Three-dimensional similarity (seven-parameter, "orthogonal") transformation.

The strip model is brought onto the control by

``target = translation + scale * rotation @ source``

(method.md section 6.1, J section 2.2, B(145)-(149)): ``rotation`` is an
active rotation matrix that premultiplies column vectors, ``scale`` is
unitless (target units per source unit) and ``translation`` is in target units
(metres).  Points are rows, shape (N, 3); both frames are right-handed
Cartesian frames.

Two estimators are offered:

* :func:`similarity_from_points`, the closed form of Horn / Umeyama for three
  or more full, non-collinear point pairs;
* :func:`fit_similarity`, weighted least squares with full (X, Y, H), plan
  (X, Y) and height (H) control, J's minimum being two full points and one
  more height, not all in one vertical plane.  It returns residuals, the a
  posteriori sigma0, the covariance of the seven parameters, the redundancy
  numbers and the normalised residuals (w-test) needed for data snooping.

No geodesy happens here: both point sets are Cartesian, in metres or model
units.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._rows import add_to_columns
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError
from ..options import DEFAULT_MAX_ITERATIONS
from .control_geometry import (
    COINCIDENT_RTOL,
    COLLINEAR_MAGNIFICATION,
    COLLINEAR_RTOL,
    WEAK_COLLINEAR_MAGNIFICATION,
    WEAK_COLLINEAR_RTOL,
    _quote,
    control_count_problems,
    cross_tilt,
    height_plane_verdict,
)
from .control_geometry import (
    _validate_control_geometry as _validate_control_geometry,
)
from .rotation import matrix_from_rotvec, skew

__all__ = [
    "COINCIDENT_RTOL",
    "COLLINEAR_MAGNIFICATION",
    "COLLINEAR_RTOL",
    "WEAK_COLLINEAR_MAGNIFICATION",
    "WEAK_COLLINEAR_RTOL",
    "SimilarityResult",
    "SimilarityTransform",
    "control_count_problems",
    "cross_tilt",
    "fit_similarity",
    "height_plane_verdict",
    "similarity_from_points",
]

#: Condition number of the column-equilibrated normal matrix treated as singular.
SINGULAR_COND = 1e12
#: Fraction of its standard deviation below which a step of a linearly
#: converging iteration is negligible.
_NEGLIGIBLE_FRACTION = 0.01
#: Redundancy numbers below this are treated as zero (observation not controlled).
_R_MIN = 1e-10


# --------------------------------------------------------------------------- transform


@dataclass(frozen=True)
class SimilarityTransform:
    """A 3D similarity transformation ``target = translation + scale * rotation @ source``.

    Attributes
    ----------
    scale : float
        Unitless scale factor (target units per source unit), > 0.
    rotation : ndarray, shape (3, 3)
        Active rotation (det +1) that premultiplies column vectors of the
        source frame.
    translation : ndarray, shape (3,)
        Position of the source origin in the target frame, target units.

    Examples
    --------
    >>> import numpy as np
    >>> t = SimilarityTransform(2.0, np.eye(3), np.array([1.0, 0.0, 0.0]))
    >>> t.apply([[1.0, 1.0, 1.0]])
    array([[3., 2., 2.]])
    >>> t.inverse().apply(t.apply([[1.0, 2.0, 3.0]]))
    array([[1., 2., 3.]])
    """

    scale: float
    rotation: FloatArray
    translation: FloatArray

    def __post_init__(self) -> None:
        scale = float(self.scale)
        rotation = np.array(self.rotation, dtype=np.float64)
        translation = np.array(self.translation, dtype=np.float64)
        if not np.isfinite(scale) or scale <= 0.0:
            raise ValueError(f"Expected `scale` to be a finite number > 0, got {scale!r}")
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
            raise ValueError(
                f"Expected `rotation` to be a finite array of shape (3, 3), got {rotation.shape}"
            )
        if translation.shape != (3,) or not np.all(np.isfinite(translation)):
            raise ValueError(
                "Expected `translation` to be a finite array of shape (3,), "
                f"got {translation.shape}"
            )
        if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) or (
            np.linalg.det(rotation) < 0.0
        ):
            raise ValueError(
                "Expected `rotation` to be a proper rotation matrix (R Rᵀ = I, det +1)"
            )
        rotation.setflags(write=False)
        translation.setflags(write=False)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "rotation", rotation)
        object.__setattr__(self, "translation", translation)

    @classmethod
    def identity(cls) -> SimilarityTransform:
        """The identity transformation (scale 1, no rotation, no translation)."""
        return cls(1.0, np.eye(3), np.zeros(3))

    def apply(self, xyz: ArrayLike) -> FloatArray:
        """Transform points.

        Parameters
        ----------
        xyz : array_like, shape (N, 3) or (3,)
            Points in the source frame (rows).

        Returns
        -------
        ndarray, shape like `xyz`
            ``translation + scale * rotation @ xyz`` for each row.
        """
        xyz = np.asarray(xyz, dtype=np.float64)
        if xyz.shape[-1:] != (3,):
            raise ValueError(f"Expected `xyz` to have shape (N, 3), got {xyz.shape}")
        return add_to_columns(xyz @ (self.scale * self.rotation.T), self.translation)

    def apply_to_rotation(self, rotation: ArrayLike) -> FloatArray:
        """Carry attitudes (image -> source rotations) into the target frame.

        Parameters
        ----------
        rotation : array_like, shape (..., 3, 3)
            Rotation matrices mapping image vectors to the source frame
            (``l = R @ l_image``).

        Returns
        -------
        ndarray, shape (..., 3, 3)
            ``self.rotation @ rotation``: image -> target frame.
        """
        rotation = np.asarray(rotation, dtype=np.float64)
        if rotation.shape[-2:] != (3, 3):
            raise ValueError(
                f"Expected `rotation` to have shape (..., 3, 3), got {rotation.shape}"
            )
        turned: FloatArray = np.matmul(self.rotation, rotation)
        return turned

    def inverse(self) -> SimilarityTransform:
        """The inverse transformation (target -> source)."""
        rotation_t = self.rotation.T
        return SimilarityTransform(
            1.0 / self.scale, rotation_t, -(rotation_t @ self.translation) / self.scale
        )

    def compose(self, other: SimilarityTransform) -> SimilarityTransform:
        """Composition ``self ∘ other``: apply `other` first, then `self`.

        ``self.compose(other).apply(x) == self.apply(other.apply(x))``, so
        chains read like ``model2ground = strip2ground.compose(model2strip)``.
        """
        if not isinstance(other, SimilarityTransform):
            raise TypeError(f"Expected a SimilarityTransform, got {type(other).__name__}")
        return SimilarityTransform(
            self.scale * other.scale,
            self.rotation @ other.rotation,
            self.translation + self.scale * (self.rotation @ other.translation),
        )


# --------------------------------------------------------------------------- helpers


def _check_points(xyz: ArrayLike, name: str, n: int | None = None) -> FloatArray:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"Expected `{name}` to have shape (N, 3), got {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"Expected `{name}` to have shape ({n}, 3), got {arr.shape}")
    return arr


def _check_mask(mask: ArrayLike, n: int, name: str) -> BoolArray:
    arr = np.asarray(mask)
    if arr.shape != (n,):
        raise ValueError(f"Expected `{name}` to have shape ({n},), got {arr.shape}")
    if arr.dtype != np.bool_:
        raise ValueError(f"Expected `{name}` to be boolean, got dtype {arr.dtype}")
    return arr.astype(np.bool_, copy=True)


def _check_sigma(sigma: ArrayLike | None, n: int, name: str) -> FloatArray:
    if sigma is None:
        return np.ones(n)
    arr = np.asarray(sigma, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"Expected `{name}` to be a scalar or of shape ({n},), got {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ValueError(f"Expected `{name}` to be finite and > 0")
    return arr.copy()


def _check_ids(point_ids: Sequence[str] | None, n: int) -> tuple[str, ...]:
    if point_ids is None:
        return tuple(f"#{i}" for i in range(n))
    ids = tuple(str(p) for p in point_ids)
    if len(ids) != n:
        raise ValueError(f"Expected `point_ids` to have length {n}, got {len(ids)}")
    return ids


#: Unknowns up to which the condition number is computed exactly (eigenvalues);
#: larger designs (deformation splines over many sections) take a bound.
_EXACT_COND_MAX = 16


#: Columns from which a design is examined for sparse rows (splines over
#: sections: 6 nonzero terms per row of a few hundred or thousand).
_SPARSE_MIN_COLUMNS = 64


class RowSupport(NamedTuple):
    """The nonzero entries of each row of an (n, k) matrix, padded to the
    longest row: ``columns`` (n, w) their columns, ``value`` (n, w) their
    values (0 in the padding, whose column is 0)."""

    columns: IntArray
    value: FloatArray
    n_columns: int


def row_support(a: FloatArray) -> RowSupport | None:
    """The rows of ``a`` as a :class:`RowSupport` when they are sparse (at
    most a quarter of the columns nonzero in any row, and at least
    ``_SPARSE_MIN_COLUMNS`` columns), else None."""
    n, k = a.shape
    if k < _SPARSE_MIN_COLUMNS or n == 0:
        return None
    rows, cols = np.nonzero(a)
    counts = np.bincount(rows, minlength=n)
    width = int(counts.max())
    if 4 * width > k:
        return None
    position = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
    index = np.zeros((n, width), dtype=np.intp)
    value = np.zeros((n, width))
    index[rows, position] = cols
    value[rows, position] = a[rows, cols]
    return RowSupport(index, value, k)


def _gram(a: FloatArray, support: RowSupport | None) -> FloatArray:
    """``aᵀa``; from the rows' nonzero entries when they are given: O(n w²)
    instead of O(n k²) (a spline of 1670 terms over 2500 rows: 7 ms instead
    of 1-2 s)."""
    if support is None:
        return a.T @ a
    k = support.n_columns
    pairs = (support.columns[:, :, None] * k + support.columns[:, None, :]).reshape(-1)
    products = (support.value[:, :, None] * support.value[:, None, :]).reshape(-1)
    gram: FloatArray = np.bincount(pairs, products, minlength=k * k).reshape(k, k)  # type: ignore[assignment]  # float with weights
    return gram


def _normal_inverse(
    a_white: FloatArray, support: RowSupport | None = None
) -> tuple[FloatArray, float]:
    """Inverse of ``AᵀA`` by column equilibration, and its condition number.

    Returns ``(inverse, cond)``; ``cond`` is the 2-norm condition number of
    the equilibrated matrix (inf when a column is zero) for up to
    ``_EXACT_COND_MAX`` unknowns.  For more it is the upper bound
    ``‖N‖∞ ‖N⁻¹‖∞``, at most k times the 2-norm one for k unknowns, which
    costs O(k²) instead of an eigenvalue decomposition (4.5 ms at k = 340).
    ``support``: the nonzero entries of the rows of ``a_white``
    (:func:`row_support`), for sparse designs.
    """
    normal = _gram(a_white, support)
    diag = np.diag(normal).copy()
    if normal.size == 0:
        return normal, 1.0
    if np.any(diag <= 0.0):
        return np.full_like(normal, np.nan), np.inf
    d = 1.0 / np.sqrt(diag)
    scaled = normal * d[:, None] * d[None, :]
    singular = (np.full_like(normal, np.nan), np.inf)
    exact = scaled.shape[0] <= _EXACT_COND_MAX
    if exact:
        eig = np.linalg.eigvalsh(scaled)
        if eig[0] <= 0.0:
            return singular
    try:  # an exactly singular matrix can still show a rounding-size eigenvalue
        inverse = np.linalg.inv(scaled)
    except np.linalg.LinAlgError:
        return singular
    if exact:
        cond = float(eig[-1] / eig[0])
    else:
        cond = float(np.abs(scaled).sum(axis=1).max() * np.abs(inverse).sum(axis=1).max())
        if not np.isfinite(cond) or np.any(np.diag(inverse) <= 0.0):
            return singular
    return inverse * d[:, None] * d[None, :], cond


def _redundancy_numbers(
    a_white: FloatArray, q: FloatArray, support: RowSupport | None = None
) -> FloatArray:
    """Diagonal of ``I - A (AᵀPA)⁻¹ AᵀP`` for whitened rows ``a_white = sqrt(P) A``
    (``support``: their nonzero entries, :func:`row_support`)."""
    if a_white.shape[1] == 0:
        return np.ones(a_white.shape[0])
    if support is None:
        h = np.einsum("ij,ij->i", a_white @ q, a_white)  # a three-operand einsum is O(n k²) slow
    else:  # aᵢᵀ Q aᵢ over the row's nonzero entries only
        q_at = np.take(q, support.columns[:, :, None] * q.shape[1] + support.columns[:, None, :])
        h = np.einsum("nij,ni,nj->n", q_at, support.value, support.value)
    numbers: FloatArray = np.clip(1.0 - h, 0.0, 1.0)
    return numbers


def _normalized(v: FloatArray, sigma: FloatArray, r: FloatArray) -> FloatArray:
    """w-test statistic ``v / (sigma sqrt(r))``, NaN where ``r`` is (near) zero."""
    out = np.full(v.shape, np.nan)
    ok = np.isfinite(v) & (r > _R_MIN)
    out[ok] = v[ok] / (sigma[ok] * np.sqrt(r[ok]))
    return out


# --------------------------------------------------------------------------- closed form


def similarity_from_points(
    source: ArrayLike, target: ArrayLike, weights: ArrayLike | None = None
) -> SimilarityTransform:
    """Closed-form similarity from full point pairs (Horn 1987 / Umeyama 1991).

    Minimises ``sum_i w_i |target_i - (t + s R source_i)|²`` over a rotation
    with det +1 (a reflection is never returned, even for mirrored data).

    Parameters
    ----------
    source, target : array_like, shape (N, 3)
        Corresponding points, N >= 3, not collinear, all finite.
    weights : array_like, shape (N,), optional
        Non-negative weights (default 1).

    Returns
    -------
    SimilarityTransform
        ``target ≈ translation + scale * rotation @ source``.

    Raises
    ------
    GeometryError
        Fewer than three points with positive weight, or the source or target
        points collinear or coincident.
    ValueError
        Bad shapes, non-finite values, negative weights.

    References
    ----------
    S. Umeyama, "Least-squares estimation of transformation parameters between
    two point patterns", IEEE TPAMI 13(4), 1991, doi:10.1109/34.88573.
    """
    src = _check_points(source, "source")
    tgt = _check_points(target, "target", src.shape[0])
    n = src.shape[0]
    if not (np.all(np.isfinite(src)) and np.all(np.isfinite(tgt))):
        raise ValueError("Expected `source` and `target` to be finite")
    if weights is None:
        w = np.ones(n)
    else:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0.0):
            raise ValueError(f"Expected `weights` to be finite, >= 0, of shape ({n},)")
    used = w > 0.0
    if np.count_nonzero(used) < 3:
        raise GeometryError(
            "similarity from points needs at least three full points, "
            f"got {np.count_nonzero(used)}"
        )
    w = w / w.sum()
    mu_s = w @ src
    mu_t = w @ tgt
    s_c = src - mu_s
    t_c = tgt - mu_t
    for name, centred in (("source", s_c), ("target", t_c)):
        sv = np.linalg.svd(centred * np.sqrt(w)[:, None], compute_uv=False)
        if sv[0] == 0.0 or sv[1] <= COINCIDENT_RTOL * sv[0]:
            raise GeometryError(
                f"similarity from points needs non-collinear points, the {name} points are "
                "collinear or coincident"
            )
    cov = (t_c * w[:, None]).T @ s_c
    u, d, vt = np.linalg.svd(cov)
    sign = np.ones(3)
    sign[2] = 1.0 if np.linalg.det(u) * np.linalg.det(vt) > 0.0 else -1.0
    rotation = (u * sign) @ vt
    variance = float(np.sum(w * np.sum(s_c**2, axis=1)))
    scale = float(np.sum(d * sign) / variance)
    if scale <= 0.0:
        raise GeometryError("similarity from points gives a non-positive scale")
    translation = mu_t - scale * rotation @ mu_s
    return SimilarityTransform(scale, rotation, translation)


# --------------------------------------------------------------------------- least squares


@dataclass(frozen=True)
class SimilarityResult:
    """Weighted least-squares similarity on full, plan and height control.

    Attributes
    ----------
    transform : SimilarityTransform
        Source -> target.
    residuals : ndarray, shape (N, 3)
        ``target - transform.apply(source)`` in target units; NaN where the
        coordinate is not observed.
    sigma0 : float
        A posteriori standard deviation of unit weight, ``sqrt(vᵀPv / r)``
        with ``P = 1/sigma²``: unitless when sigmas were given (expected
        about 1), metres with the default unit weights; NaN when r = 0.
    redundancy : int
        r = number of observations - 7.
    iterations : int
        Gauss-Newton iterations performed.
    covariance : ndarray, shape (7, 7)
        Covariance of (tx, ty, tz, scale, phi_x, phi_y, phi_z): ``translation``
        in target units, ``scale`` unitless, and a small rotation vector in
        radians applied on the left (``rotation -> expm([phi]x) @ rotation``,
        i.e. about target-frame axes).  Scaled by sigma0² when r > 0,
        otherwise the a priori cofactor matrix.
    redundancy_numbers : ndarray, shape (N, 3)
        Diagonal of ``R = I - A (AᵀPA)⁻¹ AᵀP`` per observation (0..1); NaN
        where not observed.  They sum to ``redundancy``.
    normalized_residuals : ndarray, shape (N, 3)
        w-test statistic ``v / (sigma sqrt(r_i))`` with the a priori sigma of
        the observation; NaN where not observed or r_i = 0.
    point_ids : tuple of str
        Ids of the N points (``'#i'`` when none were given).
    """

    transform: SimilarityTransform
    residuals: FloatArray
    sigma0: float
    redundancy: int
    iterations: int
    covariance: FloatArray
    redundancy_numbers: FloatArray
    normalized_residuals: FloatArray
    point_ids: tuple[str, ...]


def _checked_control(
    source: ArrayLike,
    target: ArrayLike,
    use_xy: ArrayLike,
    use_z: ArrayLike,
    sigmas: tuple[ArrayLike | None, ArrayLike | None],
    point_ids: Sequence[str] | None,
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray, FloatArray, FloatArray, tuple[str, ...]]:
    """:func:`fit_similarity`'s arrays checked: source and target points,
    the plan and height masks, the sigmas and the ids."""
    src = _check_points(source, "source")
    n = src.shape[0]
    return (
        src,
        _check_points(target, "target", n),
        _check_mask(use_xy, n, "use_xy"),
        _check_mask(use_z, n, "use_z"),
        _check_sigma(sigmas[0], n, "sigma_xy"),
        _check_sigma(sigmas[1], n, "sigma_z"),
        _check_ids(point_ids, n),
    )


def _weighted_rows(
    centred: tuple[FloatArray, FloatArray],
    obs: BoolArray,
    sigma: FloatArray,
    transform: tuple[float, FloatArray, FloatArray],
) -> tuple[FloatArray, FloatArray]:
    """The design rows and misclosures of the observed target coordinates,
    each divided by its sigma, at ``transform`` (scale, rotation, shift) of
    the centred source and target (``centred``); unknowns: shift, scale,
    small rotation vector."""
    src_c, tgt_c = centred
    scale, rotation, shift = transform
    u = src_c @ rotation.T  # (N, 3)
    misclosure = (tgt_c - (shift + scale * u))[obs]
    jac = np.zeros((src_c.shape[0], 3, 7))
    jac[:, :, 0:3] = np.eye(3)
    jac[:, :, 3] = u
    jac[:, :, 4:7] = -scale * skew(u)
    a = jac[obs]
    w = 1.0 / sigma[obs]
    return a * w[:, None], misclosure * w


def _given_start(
    start: SimilarityTransform, c_src: FloatArray, c_tgt: FloatArray
) -> tuple[float, FloatArray, FloatArray]:
    """A given start in the centred frames: scale, rotation and the shift of
    ``target_c = shift + s R source_c``."""
    if not isinstance(start, SimilarityTransform):
        raise TypeError(
            f"Expected `start` to be a SimilarityTransform, got {type(start).__name__}"
        )
    # target = t + s R source  <=>  target_c = (t + s R c_src - c_tgt) + s R source_c
    scale, rotation = float(start.scale), start.rotation.copy()
    return scale, rotation, start.translation + scale * (rotation @ c_src) - c_tgt


def _solution(
    weighted: tuple[FloatArray, FloatArray],
    solved: tuple[float, FloatArray, FloatArray, int],
    centres: tuple[FloatArray, FloatArray],
    obs: BoolArray,
    sigma: FloatArray,
    ids: tuple[str, ...],
) -> SimilarityResult:
    """The result of :func:`fit_similarity` at the solution: the weighted
    design and misclosures there (``weighted``), the centred solution
    (scale, rotation, shift, iterations) and the centres of the source and
    target (``centres``); residuals, sigma0, the redundancy numbers, the
    normalised residuals and the covariance of the transform."""
    a_w, l_w = weighted
    scale, rotation, shift, iterations = solved
    c_src, c_tgt = centres
    n = obs.shape[0]
    used = obs.any(axis=1)
    q = _regular_inverse(a_w, [ids[i] for i in np.flatnonzero(used)])
    m = a_w.shape[0]
    redundancy = m - 7
    v_obs = l_w * sigma[obs]  # target - fitted, target units
    residuals = np.full((n, 3), np.nan)
    residuals[obs] = v_obs
    if redundancy > 0:
        sigma0 = float(np.sqrt(np.sum(l_w**2) / redundancy))
        var_factor = sigma0**2
    else:
        sigma0 = float("nan")
        var_factor = 1.0
    r_obs = _redundancy_numbers(a_w, q)
    red = np.full((n, 3), np.nan)
    red[obs] = r_obs
    normalized = np.full((n, 3), np.nan)
    normalized[obs] = _normalized(v_obs, sigma[obs], r_obs)

    translation = c_tgt + shift - scale * (rotation @ c_src)
    # Covariance of the true translation: t = c_tgt + shift - s R c_src.
    rc = rotation @ c_src
    jac = np.eye(7)
    jac[0:3, 3] = -rc
    jac[0:3, 4:7] = scale * skew(rc)
    covariance = var_factor * (jac @ q @ jac.T)

    return SimilarityResult(
        transform=SimilarityTransform(scale, rotation, translation),
        residuals=residuals,
        sigma0=sigma0,
        redundancy=int(redundancy),
        iterations=int(iterations),
        covariance=covariance,
        redundancy_numbers=red,
        normalized_residuals=normalized,
        point_ids=ids,
    )


def _start_values(
    src_c: FloatArray,
    tgt_c: FloatArray,
    use_xy: BoolArray,
    use_z: BoolArray,
) -> tuple[float, FloatArray, FloatArray]:
    """Constructive start (scale, rotation, translation) in the centred frames."""
    full = use_xy & use_z
    if np.count_nonzero(full) >= 3:
        s_f = src_c[full] - src_c[full].mean(axis=0)
        sv = np.linalg.svd(s_f, compute_uv=False)
        t_f = tgt_c[full] - tgt_c[full].mean(axis=0)
        svt = np.linalg.svd(t_f, compute_uv=False)
        if sv[1] > 1e-3 * sv[0] and svt[1] > 1e-3 * svt[0]:
            start = similarity_from_points(src_c[full], tgt_c[full])
            return start.scale, start.rotation.copy(), start.translation.copy()
    # Plan: 2D Helmert (scale and azimuth about Z) from the plan points.
    xy_s = src_c[use_xy, :2]
    xy_t = tgt_c[use_xy, :2]
    zs = (xy_s[:, 0] - xy_s[:, 0].mean()) + 1j * (xy_s[:, 1] - xy_s[:, 1].mean())
    zt = (xy_t[:, 0] - xy_t[:, 0].mean()) + 1j * (xy_t[:, 1] - xy_t[:, 1].mean())
    m = np.sum(np.conj(zs) * zt) / np.sum(np.abs(zs) ** 2)
    scale = float(np.abs(m))
    kappa = float(np.angle(m))
    rz = matrix_from_rotvec([0.0, 0.0, kappa])
    # Heights: Z_t = tz + s (z + phi_x y - phi_y x), linear in (tz, phi_x, phi_y).
    p = src_c[use_z]
    a = np.column_stack([np.full(p.shape[0], 1.0 / scale), p[:, 1], -p[:, 0]])
    rhs = tgt_c[use_z, 2] / scale - p[:, 2]
    sol, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    tilt = matrix_from_rotvec([sol[1], sol[2], 0.0])
    rotation = rz @ tilt
    u = src_c @ rotation.T * scale
    translation = np.array(
        [
            np.mean(tgt_c[use_xy, 0] - u[use_xy, 0]),
            np.mean(tgt_c[use_xy, 1] - u[use_xy, 1]),
            np.mean(tgt_c[use_z, 2] - u[use_z, 2]),
        ]
    )
    return scale, rotation, translation


def _regular_inverse(a_w: FloatArray, used_ids: Sequence[str]) -> FloatArray:
    """The inverse of the normal matrix of the weighted design ``a_w``; an
    error naming the control points when it is singular."""
    q, cond = _normal_inverse(a_w)
    if not np.isfinite(cond) or cond > SINGULAR_COND:
        raise GeometryError(
            "similarity transformation: the normal matrix is singular (condition "
            f"{cond:.1e}); the control does not determine the 7 parameters: "
            f"{_quote(used_ids)}"
        )
    return q


def _gauss_newton(
    linearise: Callable[[float, FloatArray, FloatArray], tuple[FloatArray, FloatArray]],
    scale: float,
    rotation: FloatArray,
    shift: FloatArray,
    extent: float,
    used_ids: list[str],
    max_iterations: int,
    tolerance: float,
) -> tuple[float, FloatArray, FloatArray, int]:
    """Gauss-Newton steps of the similarity until the update is negligible.

    ``linearise(scale, rotation, shift)`` gives the weighted design matrix and
    misclosures; ``extent`` (target units) makes the translation's update
    relative.  Returns the scale, rotation, shift and the iterations taken.
    """
    iterations = 0
    previous = np.inf
    converged = False
    for iterations in range(1, max_iterations + 1):
        a_w, l_w = linearise(scale, rotation, shift)
        q = _regular_inverse(a_w, used_ids)
        dx = q @ (a_w.T @ l_w)
        shift = shift + dx[0:3]
        scale = scale + dx[3]
        if scale <= 0.0:
            raise ConvergenceError(
                "similarity transformation: the scale became non-positive during iteration "
                f"{iterations}"
            )
        rotation = matrix_from_rotvec(dx[4:7]) @ rotation
        step = max(
            float(np.max(np.abs(dx[0:3]))) / max(extent, np.finfo(float).tiny),
            abs(float(dx[3])) / scale,
            float(np.max(np.abs(dx[4:7]))),
        )
        # Or, when the iteration converges only linearly (a step less than a
        # hundredth of the one before: a long strip model bent by its chain
        # leaves large residuals), negligible against its own standard
        # deviation (σ0 from the residuals after the step): such steps cease
        # to matter long before they reach the tolerance (bench_bundle's
        # 1000-photo strip: 4 iterations instead of 10, steps falling by a
        # factor 18 each).  Quadratic convergence goes on to the tolerance.
        redundancy = l_w.shape[0] - dx.shape[0]
        negligible = False
        if redundancy > 0 and step > 0.01 * previous:
            resid = l_w - a_w @ dx
            sigma_dx = np.sqrt(float(resid @ resid) / redundancy * np.diag(q))
            negligible = bool(np.all(np.abs(dx) < _NEGLIGIBLE_FRACTION * sigma_dx))
        if step < tolerance or (step < 1e-9 and step >= previous) or negligible:
            converged = True
            break
        previous = step
    if not converged:
        raise ConvergenceError(
            f"similarity transformation did not converge in {max_iterations} iterations "
            f"(last relative update {step:.1e})"
        )
    return scale, rotation, shift, iterations


def fit_similarity(
    source: ArrayLike,
    target: ArrayLike,
    *,
    use_xy: ArrayLike,
    use_z: ArrayLike,
    sigma_xy: ArrayLike | None = None,
    sigma_z: ArrayLike | None = None,
    point_ids: Sequence[str] | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = 1e-12,
    start: SimilarityTransform | None = None,
    served: ArrayLike | None = None,
) -> SimilarityResult:
    """Seven-parameter similarity by weighted least squares on mixed control.

    Model ``target = translation + scale * rotation @ source`` (active
    rotation, column vectors; rows in the arrays).  Full control observes X,
    Y and Z, plan control X and Y, height control Z (J section 2.2, B(149)).

    Parameters
    ----------
    source : array_like, shape (N, 3)
        Model (strip) coordinates of the points, any unit.
    target : array_like, shape (N, 3)
        Control coordinates (metres); NaN where a coordinate is not given.
        Entries not used are never read.
    use_xy : array_like of bool, shape (N,)
        X and Y of the point are observed (full and plan control).
    use_z : array_like of bool, shape (N,)
        Z of the point is observed (full and height control).
    sigma_xy, sigma_z : float or array_like, shape (N,), optional
        A priori standard deviations of the target coordinates in metres
        (weights ``1/sigma²``).  Default 1 (unit weights; sigma0 is then in
        metres).
    point_ids : sequence of str, length N, optional
        Names used in messages and kept in the result.
    max_iterations : int
        Gauss-Newton iteration limit.
    tolerance : float
        Convergence when the largest relative update (translation against the
        control extent, scale against the scale, rotation in radians) falls
        below it, or stops decreasing at round-off level (below 1e-9).
    start : SimilarityTransform, optional
        Start values (e.g. the solution of a neighbouring problem); by default
        they are constructed from the control (see Notes).  They change the
        number of iterations, not the solution.
    served : array_like, shape (M, 3), optional
        Source coordinates of the points the transformation is for (e.g. a
        sample of the strip model's points; non-finite rows ignored).  Given,
        the warning about height control nearly in one vertical plane is
        issued when an error of its heights reaches the served point farthest
        from that plane more than ``WEAK_COLLINEAR_MAGNIFICATION`` times
        magnified, instead of by the ratio ``WEAK_COLLINEAR_RTOL`` of its
        plan singular values.  The error for collinear height control
        (ratio below ``COLLINEAR_RTOL``) is the same either way.

    Returns
    -------
    SimilarityResult

    Raises
    ------
    GeometryError
        Fewer than two plan (full or plan) points, fewer than three height
        (full or height) points, plan points coincident, height points all in
        one vertical plane (J: collinear in plan), non-finite used
        coordinates, or a singular normal matrix.  The message names the rule
        and the points.
    ConvergenceError
        No convergence within `max_iterations`.
    ValueError
        Bad shapes or arguments.

    Notes
    -----
    Both point sets are centred first (numerical conditioning with large
    grid coordinates).  Start values: with three or more non-collinear full
    points the closed form of :func:`similarity_from_points`; otherwise
    scale and azimuth from a 2D Helmert fit of the plan points and the two
    tilts (with the height offset) from a linear solve of the heights, which
    works for J's minimum configuration and assumes the source frame is
    roughly level (tilts well below 30 degrees), as a strip model is.  Then
    Gauss-Newton on (translation, scale, small rotation vector updating the
    rotation multiplicatively) to convergence.

    The redundancy numbers ``r_i`` and the normalised residuals
    ``w_i = v_i / (sigma_i sqrt(r_i))`` serve data snooping (Baarda): under
    the null hypothesis each ``w_i`` is standard normal when the a priori
    sigmas are right.
    """
    src, tgt, mask_xy, mask_z, sxy, sz, ids = _checked_control(
        source, target, use_xy, use_z, (sigma_xy, sigma_z), point_ids
    )
    if int(max_iterations) < 1:
        raise ValueError(f"Expected `max_iterations` >= 1, got {max_iterations!r}")
    if not (np.isfinite(tolerance) and tolerance > 0.0):
        raise ValueError(f"Expected `tolerance` > 0, got {tolerance!r}")
    served_xyz = None
    if served is not None:
        served_xyz = np.asarray(served, dtype=np.float64).reshape(-1, 3)
        served_xyz = served_xyz[np.isfinite(served_xyz).all(axis=1)]
    _validate_control_geometry(src, tgt, mask_xy, mask_z, ids, served_xyz)

    obs = np.column_stack([mask_xy, mask_xy, mask_z])  # (N, 3)
    sigma = np.column_stack([sxy, sxy, sz])
    used = mask_xy | mask_z
    c_src = src[used].mean(axis=0)
    c_tgt = np.array(
        [tgt[mask_xy, 0].mean(), tgt[mask_xy, 1].mean(), tgt[mask_z, 2].mean()], dtype=np.float64
    )
    src_c = np.where(used[:, None], src - c_src, 0.0)
    tgt_c = np.where(obs, np.where(obs, tgt, 0.0) - c_tgt, 0.0)
    extent = float(np.max(np.ptp(np.where(obs, tgt_c, 0.0)[used], axis=0)))

    if start is None:
        scale, rotation, shift = _start_values(src_c, tgt_c, mask_xy, mask_z)
    else:
        scale, rotation, shift = _given_start(start, c_src, c_tgt)

    def linearise(
        scale: float, rotation: FloatArray, shift: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        return _weighted_rows((src_c, tgt_c), obs, sigma, (scale, rotation, shift))

    scale, rotation, shift, iterations = _gauss_newton(
        linearise,
        scale,
        rotation,
        shift,
        extent,
        [ids[i] for i in np.flatnonzero(used)],
        int(max_iterations),
        tolerance,
    )
    # Re-orthonormalise (accumulated products of rotations).
    u_svd, _, vt_svd = np.linalg.svd(rotation)
    rotation = u_svd @ vt_svd

    return _solution(
        linearise(scale, rotation, shift),
        (scale, rotation, shift, int(iterations)),
        (c_src, c_tgt),
        obs,
        sigma,
        ids,
    )
