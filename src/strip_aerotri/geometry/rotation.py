"""Rotation matrices and their parametrisations.

Conventions (the whole package, see ``docs/conventions.md``):

* right-handed frames, right-handed (counter-clockwise seen from the tip of
  the axis) elementary rotations;
* a rotation matrix ``R`` is *active* and maps image vectors to the
  object/strip frame, ``l = R @ l_image``; matrices premultiply column
  vectors, and arrays of points are ``(N, 3)`` rows, so code writes
  ``xyz @ R.T``;
* stacks of matrices have shape ``(..., 3, 3)``; every function broadcasts
  over the leading dimensions and never modifies its inputs;
* angles are radians unless ``degrees=True`` is given.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..errors import GeometryError, StripAerotriWarning

__all__ = [
    "SCHUT_MAX_ANGLE_DEG",
    "cardan_from_matrix",
    "cardan_from_opk",
    "cardan_from_schut",
    "check_matrix",
    "matrix_from_cardan",
    "matrix_from_opk",
    "matrix_from_rotvec",
    "matrix_from_schut",
    "opk_from_cardan",
    "opk_from_matrix",
    "opk_from_schut",
    "rotvec_from_matrix",
    "schut_from_cardan",
    "schut_from_matrix",
    "schut_from_opk",
    "skew",
]

#: Largest rotation angle (degrees) that :func:`schut_from_matrix` accepts.
#: Schut's parameters are ``tan(theta/2) * axis``: at 179 deg their length is
#: already about 115 and at 180 deg they are infinite.
SCHUT_MAX_ANGLE_DEG = 179.0

#: Gimbal lock is declared when the cosine of the middle angle (omega of
#: alpha-omega-chi, phi of omega-phi-kappa) is below this value, i.e. when the
#: middle angle is within about 5.7e-8 deg of +-90 deg.
_GIMBAL_LOCK_COS = 1e-9


def _as_vectors(value: ArrayLike, name: str) -> FloatArray:
    """Coerce to float64 and check the trailing dimension is 3."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f"Expected `{name}` to have shape (..., 3), got {arr.shape}.")
    return arr


def skew(v: ArrayLike) -> FloatArray:
    """Cross-product (skew-symmetric) matrix of a vector.

    Parameters
    ----------
    v : array_like, shape (..., 3)
        Vector(s), any unit.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``[v]x`` such that ``skew(a) @ b == np.cross(a, b)``.

    Notes
    -----
    ``[v]x = [[0, -v3, v2], [v3, 0, -v1], [-v2, v1, 0]]``; premultiplies column
    vectors. ``I + [phi]x`` is the first-order rotation by the small rotation
    vector ``phi`` (radians).

    Examples
    --------
    >>> import numpy as np
    >>> skew([1.0, 2.0, 3.0])
    array([[ 0., -3.,  2.],
           [ 3.,  0., -1.],
           [-2.,  1.,  0.]])
    >>> bool(np.allclose(skew([1, 2, 3]) @ [4, 5, 6], np.cross([1, 2, 3], [4, 5, 6])))
    True
    """
    v = _as_vectors(v, "v")
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = np.zeros_like(x)
    return np.stack(
        [
            np.stack([zero, -z, y], axis=-1),
            np.stack([z, zero, -x], axis=-1),
            np.stack([-y, x, zero], axis=-1),
        ],
        axis=-2,
    )


def matrix_from_schut(abc: ArrayLike) -> FloatArray:
    """Rotation matrix from Schut's algebraic parameters a, b, c.

    Convention: Cayley/Gibbs form, ``(a, b, c) = tan(theta/2) * axis`` for an
    active right-handed rotation by ``theta`` about the unit ``axis``; image ->
    object; premultiplies column vectors.

    Parameters
    ----------
    abc : array_like, shape (..., 3)
        Schut parameters (a, b, c), dimensionless.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``R = g * [[1+a²-b²-c², 2ab-2c, 2ac+2b], [2ab+2c, 1-a²+b²-c², 2bc-2a],
        [2ac-2b, 2bc+2a, 1-a²-b²+c²]]`` with ``g = 1/(1+a²+b²+c²)``.

    Notes
    -----
    Singular at ``theta = 180°`` (parameters infinite); for small rotations
    ``R ≈ I + [2(a, b, c)]x``.

    References
    ----------
    J(2): Janiszewski (1975), analytical strip aerotriangulation (ODRA 1204),
    formula (2), Schut's algebraic rotation matrix.

    Examples
    --------
    >>> import numpy as np
    >>> R = matrix_from_schut([0.0, 0.0, 1.0])   # tan(90°/2) = 1: 90° about z
    >>> np.round(R, 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    abc = _as_vectors(abc, "abc")
    a, b, c = abc[..., 0], abc[..., 1], abc[..., 2]
    aa, bb, cc = a * a, b * b, c * c
    g = 1.0 / (1.0 + aa + bb + cc)
    m = np.stack(
        [
            np.stack([1.0 + aa - bb - cc, 2.0 * (a * b - c), 2.0 * (a * c + b)], axis=-1),
            np.stack([2.0 * (a * b + c), 1.0 - aa + bb - cc, 2.0 * (b * c - a)], axis=-1),
            np.stack([2.0 * (a * c - b), 2.0 * (b * c + a), 1.0 - aa - bb + cc], axis=-1),
        ],
        axis=-2,
    )
    return g[..., np.newaxis, np.newaxis] * m


def matrix_from_cardan(angles: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Rotation matrix from the Cardan angles alpha, omega, chi of B(133).

    Convention: ``A = Ry(-alpha) @ Rx(omega) @ Rz(chi)`` (right-handed
    elementary rotations, applied chi first), active, image -> object;
    premultiplies column vectors.

    Parameters
    ----------
    angles : array_like, shape (..., 3)
        ``(alpha, omega, chi)``: longitudinal tilt (about Y, primary axis),
        transverse tilt, swing; radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Angles are in degrees.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``A = [[a1, a2, a3], [b1, b2, b3], [c1, c2, c3]]`` with, element by
        element (B(133))::

            a1 = cosα cosχ − sinα sinω sinχ   a2 = −cosα sinχ − sinα sinω cosχ   a3 = −sinα cosω
            b1 = cosω sinχ                    b2 = cosω cosχ                     b3 = −sinω
            c1 = sinα cosχ + cosα sinω sinχ   c2 = −sinα sinχ + cosα sinω cosχ   c3 = cosα cosω

    References
    ----------
    B(133): Bulgarian photogrammetry textbook, chapter on analytical
    aerotriangulation, formula (133); R3 (3.5).

    Examples
    --------
    >>> import numpy as np
    >>> A = matrix_from_cardan([3.0, 0.0, 0.0], degrees=True)
    >>> np.round(A @ [80.637, 2.517, -100.0], 3)   # R3 worked example
    array([ 85.76 ,   2.517, -95.643])
    """
    ang = _as_vectors(angles, "angles")
    if degrees:
        ang = np.deg2rad(ang)
    alpha, omega, chi = ang[..., 0], ang[..., 1], ang[..., 2]
    sa, ca = np.sin(alpha), np.cos(alpha)
    sw, cw = np.sin(omega), np.cos(omega)
    sc, cc = np.sin(chi), np.cos(chi)
    return np.stack(
        [
            np.stack([ca * cc - sa * sw * sc, -ca * sc - sa * sw * cc, -sa * cw], axis=-1),
            np.stack([cw * sc, cw * cc, -sw], axis=-1),
            np.stack([sa * cc + ca * sw * sc, -sa * sc + ca * sw * cc, ca * cw], axis=-1),
        ],
        axis=-2,
    )


# ---------------------------------------------------------------------------
# validation helpers


def _index_text(flat_index: int, shape: tuple[int, ...]) -> str:
    """Human-readable index of a rotation in a stack."""
    if not shape:
        return "the rotation"
    idx = np.unravel_index(flat_index, shape)
    return "rotation " + str(tuple(int(i) for i in idx) if len(idx) > 1 else int(idx[0]))


def check_matrix(matrix: ArrayLike, *, tolerance: float = 1e-6) -> FloatArray:
    """Coerce to float64 and check that `matrix` holds proper rotation matrices.

    Convention: any rotation matrix (orthonormal, det = +1); this function
    does not care about the direction it maps.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrix or stack of them, dimensionless.
    tolerance : float, optional
        Largest accepted ``max |R^T R - I|`` and ``|det R - 1|``.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        The matrices as a new float64 array (the input is never modified).

    Raises
    ------
    ValueError
        If the shape is not (..., 3, 3), if a matrix is not finite, not
        orthonormal or has ``det != +1`` (a reflection); the message names the
        worst rotation and by how much it fails.

    Examples
    --------
    >>> import numpy as np
    >>> check_matrix(np.eye(3)).shape
    (3, 3)
    >>> check_matrix(np.diag([1.0, 1.0, -1.0]))
    Traceback (most recent call last):
    ...
    ValueError: Expected `matrix` to be a rotation (det = +1), got det = -1 for the rotation.
    """
    m = np.array(matrix, dtype=np.float64)  # a copy: callers may modify the result
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"Expected `matrix` to have shape (..., 3, 3), got {m.shape}.")
    if not np.all(np.isfinite(m)):
        raise ValueError("Expected `matrix` to be finite, got NaN or infinity.")
    stack = m.shape[:-2]
    err = np.abs(np.swapaxes(m, -1, -2) @ m - np.eye(3)).max(axis=(-2, -1))
    worst = int(np.argmax(err)) if err.size else 0
    if err.size and err.flat[worst] > tolerance:
        raise ValueError(
            "Expected `matrix` to be orthonormal, got max |R^T R - I| = "
            f"{err.flat[worst]:.3g} (tolerance {tolerance:g}) for {_index_text(worst, stack)}."
        )
    det = np.linalg.det(m)
    bad = np.abs(det - 1.0)
    worst = int(np.argmax(bad)) if bad.size else 0
    if bad.size and bad.flat[worst] > tolerance:
        raise ValueError(
            "Expected `matrix` to be a rotation (det = +1), got det = "
            f"{det.flat[worst]:.6g} for {_index_text(worst, stack)}."
        )
    return m


def _gimbal_warning(lock: np.ndarray, what: str, middle: str, stacklevel: int) -> None:
    """Warn once per call about rotations in gimbal lock."""
    if not np.any(lock):
        return
    n = int(np.count_nonzero(lock))
    first = _index_text(int(np.flatnonzero(lock)[0]), lock.shape)
    warnings.warn(
        f"Gimbal lock in {what}: {middle} is within {np.rad2deg(_GIMBAL_LOCK_COS):.1e} deg "
        f"of +-90 deg for {n} of {lock.size} rotation(s) (first: {first}); "
        "only the sum or difference of the outer angles is defined, the third angle "
        "is set to 0.",
        StripAerotriWarning,
        stacklevel=stacklevel + 1,
    )


# ---------------------------------------------------------------------------
# alpha-omega-chi (B(133))


def _cardan_from_matrix(m: FloatArray, degrees: bool, stacklevel: int) -> FloatArray:
    a1, a3 = m[..., 0, 0], m[..., 0, 2]
    b1, b2, b3 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    c1, c3 = m[..., 2, 0], m[..., 2, 2]
    cos_omega = np.hypot(b1, b2)
    omega = np.arctan2(-b3, cos_omega)  # sin omega = -b3, B(129) and [fix] B(135)
    lock = cos_omega < _GIMBAL_LOCK_COS
    # tan alpha = -a3/c3 (B(129)); in gimbal lock chi = 0 and the first column
    # is (cos alpha, 0, sin alpha).
    alpha = np.where(lock, np.arctan2(c1, a1), np.arctan2(-a3, c3))
    # tan chi = b1/b2 (B(129)), evaluated as the residual rotation
    # Rz(chi) = Rx(-omega) Ry(alpha) A: identical for an exact matrix, but it
    # keeps the round trip at rounding level close to gimbal lock.
    sa, ca = np.sin(alpha), np.cos(alpha)
    sw, cw = np.sin(omega), np.cos(omega)
    chi = np.arctan2(cw * b1 + sw * (ca * c1 - sa * a1), ca * a1 + sa * c1)
    chi = np.where(lock, 0.0, chi)
    _gimbal_warning(lock, "alpha-omega-chi", "omega", stacklevel + 1)
    out = np.stack([alpha, omega, chi], axis=-1)
    return np.rad2deg(out) if degrees else out


def cardan_from_matrix(matrix: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Cardan angles alpha, omega, chi of B(133) from a rotation matrix.

    Convention: ``A = Ry(-alpha) @ Rx(omega) @ Rz(chi)`` (right-handed
    elementary rotations), active, image -> object; premultiplies column
    vectors.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices (checked by :func:`check_matrix`).
    degrees : bool, optional
        Return degrees instead of radians.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(alpha, omega, chi)`` with alpha, chi in [-180, 180] deg and omega
        in [-90, 90] deg; radians unless ``degrees=True``.

    Warns
    -----
    StripAerotriWarning
        In gimbal lock (``cos omega < 1e-9``): chi is set to 0 and alpha takes
        the whole rotation about the vertical; the angles still reproduce the
        matrix to within ``2 cos omega``.

    Notes
    -----
    B(129): ``tan alpha = -a3/c3``, ``sin omega = -b3``, ``tan chi = b1/b2``,
    evaluated with ``arctan2`` so that the quadrants are right. B(135) prints
    ``sin omega2 = -b32/c32``, a misprint: it is ``sin omega2 = -b32`` [fix].

    References
    ----------
    B(129), B(133), B(135): Bulgarian photogrammetry textbook, method of
    partially dependent models.

    Examples
    --------
    >>> import numpy as np
    >>> A = matrix_from_cardan([10.0, -20.0, 30.0], degrees=True)
    >>> np.round(cardan_from_matrix(A, degrees=True), 10)
    array([ 10., -20.,  30.])
    """
    return _cardan_from_matrix(check_matrix(matrix), degrees, stacklevel=2)


# ---------------------------------------------------------------------------
# omega-phi-kappa


def matrix_from_opk(opk: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Rotation matrix from omega, phi, kappa.

    Convention: ``R = Rx(omega) @ Ry(phi) @ Rz(kappa)`` (right-handed
    elementary rotations, kappa applied first), active, image -> object;
    premultiplies column vectors. ``R`` is the transpose of Wolf, Dewitt &
    Wilkinson's object -> image matrix ``M = M_kappa M_phi M_omega``, and
    equals ``scipy.spatial.transform.Rotation.from_euler("XYZ", opk)``.

    Parameters
    ----------
    opk : array_like, shape (..., 3)
        ``(omega, phi, kappa)``: radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Angles are in degrees.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ::

            [[ cp ck,              -cp sk,               sp    ],
             [ sw sp ck + cw sk,   -sw sp sk + cw ck,   -sw cp ],
             [-cw sp ck + sw sk,    cw sp sk + sw ck,    cw cp ]]

        with ``sw = sin omega``, ``cp = cos phi``, ``ck = cos kappa`` etc.

    References
    ----------
    P. R. Wolf, B. A. Dewitt, B. E. Wilkinson, Elements of Photogrammetry with
    Applications in GIS, 4th ed., McGraw-Hill 2014: the omega-phi-kappa
    rotation matrix ``M`` (object -> image) of the collinearity equations.

    Examples
    --------
    >>> import numpy as np
    >>> R = matrix_from_opk([0.0, 0.0, 90.0], degrees=True)   # kappa = 90 deg
    >>> np.round(R @ [1.0, 0.0, 0.0], 12) + 0.0               # image x -> object y
    array([0., 1., 0.])
    """
    ang = _as_vectors(opk, "opk")
    if degrees:
        ang = np.deg2rad(ang)
    sw, cw = np.sin(ang[..., 0]), np.cos(ang[..., 0])
    sp, cp = np.sin(ang[..., 1]), np.cos(ang[..., 1])
    sk, ck = np.sin(ang[..., 2]), np.cos(ang[..., 2])
    return np.stack(
        [
            np.stack([cp * ck, -cp * sk, sp], axis=-1),
            np.stack([sw * sp * ck + cw * sk, -sw * sp * sk + cw * ck, -sw * cp], axis=-1),
            np.stack([-cw * sp * ck + sw * sk, cw * sp * sk + sw * ck, cw * cp], axis=-1),
        ],
        axis=-2,
    )


def _opk_from_matrix(m: FloatArray, degrees: bool, stacklevel: int) -> FloatArray:
    r11, r12, r13 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    r21, r22, r23 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    r31, r32, r33 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    cos_phi = np.hypot(r11, r12)
    phi = np.arctan2(r13, cos_phi)
    lock = cos_phi < _GIMBAL_LOCK_COS
    # tan omega = -r23/r33; in gimbal lock kappa = 0 and the second column is
    # (0, cos omega, sin omega).
    omega = np.where(lock, np.arctan2(r32, r22), np.arctan2(-r23, r33))
    # tan kappa = -r12/r11, evaluated as the residual rotation
    # Rz(kappa) = Ry(-phi) Rx(-omega) R (stable near gimbal lock).
    sw, cw = np.sin(omega), np.cos(omega)
    sp, cp = np.sin(phi), np.cos(phi)
    kappa = np.arctan2(cw * r21 + sw * r31, cp * r11 - sp * (cw * r31 - sw * r21))
    kappa = np.where(lock, 0.0, kappa)
    _gimbal_warning(lock, "omega-phi-kappa", "phi", stacklevel + 1)
    out = np.stack([omega, phi, kappa], axis=-1)
    return np.rad2deg(out) if degrees else out


def opk_from_matrix(matrix: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Omega, phi, kappa from a rotation matrix.

    Convention: ``R = Rx(omega) @ Ry(phi) @ Rz(kappa)`` (right-handed
    elementary rotations), active, image -> object; premultiplies column
    vectors (the transpose of Wolf/Dewitt's object -> image ``M``).

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices (checked by :func:`check_matrix`).
    degrees : bool, optional
        Return degrees instead of radians.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(omega, phi, kappa)`` with omega, kappa in [-180, 180] deg and phi
        in [-90, 90] deg; radians unless ``degrees=True``.

    Warns
    -----
    StripAerotriWarning
        In gimbal lock (``cos phi < 1e-9``): kappa is set to 0 and omega takes
        the rotation about the common axis; the angles still reproduce the
        matrix to within ``2 cos phi``.

    Notes
    -----
    ``sin phi = r13``, ``tan omega = -r23/r33``, ``tan kappa = -r12/r11``
    (evaluated with ``arctan2``; kappa as the residual rotation
    ``Rz(kappa) = Ry(-phi) Rx(-omega) R``, which is the same for an exact
    matrix and stable near gimbal lock).

    References
    ----------
    P. R. Wolf, B. A. Dewitt, B. E. Wilkinson, Elements of Photogrammetry with
    Applications in GIS, 4th ed., McGraw-Hill 2014 (omega-phi-kappa).

    Examples
    --------
    >>> import numpy as np
    >>> R = matrix_from_opk([2.0, -3.0, 120.0], degrees=True)
    >>> np.round(opk_from_matrix(R, degrees=True), 10)
    array([  2.,  -3., 120.])
    """
    return _opk_from_matrix(check_matrix(matrix), degrees, stacklevel=2)


# ---------------------------------------------------------------------------
# Schut a-b-c (J(2))


def _schut_from_matrix(m: FloatArray) -> FloatArray:
    # vee(R - R^T) = 2 sin(theta) axis, 1 + trace = 2 + 2 cos(theta), so
    # vee / (1 + trace) = tan(theta/2) axis (inverse of J(2)).
    vee = np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
        axis=-1,
    )
    trace = np.trace(m, axis1=-2, axis2=-1)
    theta = np.arctan2(0.5 * np.linalg.norm(vee, axis=-1), 0.5 * (trace - 1.0))
    too_big = theta > np.deg2rad(SCHUT_MAX_ANGLE_DEG)
    if np.any(too_big):
        first = int(np.flatnonzero(too_big)[0])
        raise GeometryError(
            f"Cannot express {_index_text(first, too_big.shape)} in Schut's a-b-c: its "
            f"rotation angle is {np.rad2deg(theta.flat[first]):.4f} deg, beyond the limit of "
            f"{SCHUT_MAX_ANGLE_DEG:g} deg ({int(np.count_nonzero(too_big))} of "
            f"{too_big.size} rotation(s)); the parameters tan(theta/2) * axis are infinite "
            "at 180 deg. Use Schut parameters for near-identity (relative) rotations only, "
            "and angles or rotation vectors for absolute orientations."
        )
    schut: FloatArray = vee / (1.0 + trace)[..., np.newaxis]
    return schut


def schut_from_matrix(matrix: ArrayLike) -> FloatArray:
    """Schut's algebraic parameters a, b, c from a rotation matrix.

    Convention: Cayley/Gibbs form, ``(a, b, c) = tan(theta/2) * axis`` of the
    active right-handed rotation by ``theta`` about the unit ``axis``; image
    -> object; premultiplies column vectors. Inverse of :func:`matrix_from_schut`.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices (checked by :func:`check_matrix`).

    Returns
    -------
    ndarray, shape (..., 3)
        ``(a, b, c) = (r32 - r23, r13 - r31, r21 - r12) / (1 + trace R)``,
        dimensionless.

    Raises
    ------
    GeometryError
        If a rotation angle exceeds ``SCHUT_MAX_ANGLE_DEG`` (179 deg), where
        ``|tan(theta/2)| > 114.6`` and the parametrisation breaks down; the
        message names the rotation and its angle.

    References
    ----------
    J(2): Janiszewski (1975), analytical strip aerotriangulation (ODRA 1204),
    formula (2), Schut's rotation matrix.

    Examples
    --------
    >>> import numpy as np
    >>> R = matrix_from_schut([0.1, -0.2, 0.3])
    >>> np.round(schut_from_matrix(R), 12)
    array([ 0.1, -0.2,  0.3])
    """
    return _schut_from_matrix(check_matrix(matrix))


# ---------------------------------------------------------------------------
# rotation vectors


def matrix_from_rotvec(rotvec: ArrayLike) -> FloatArray:
    """Rotation matrix from a rotation vector (axis times angle).

    Convention: active right-handed rotation by ``|rotvec|`` radians about
    ``rotvec/|rotvec|``; image -> object; premultiplies column vectors.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Rotation vector(s), radians.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rodrigues' formula ``R = I + sin(t)/t [v]x + (1 - cos t)/t^2 [v]x^2``,
        ``t = |v|``, evaluated with ``sinc`` so that it is exact near 0.

    References
    ----------
    Rodrigues' rotation formula; equals
    ``scipy.spatial.transform.Rotation.from_rotvec(rotvec).as_matrix()``.

    Examples
    --------
    >>> import numpy as np
    >>> R = matrix_from_rotvec([0.0, 0.0, np.pi / 2])
    >>> np.round(R, 12) + 0.0
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    v = _as_vectors(rotvec, "rotvec")
    t = np.linalg.norm(v, axis=-1)
    k = skew(v)
    first = np.sinc(t / np.pi)  # sin(t)/t
    second = 0.5 * np.sinc(t / (2.0 * np.pi)) ** 2  # (1 - cos t)/t^2
    matrix: FloatArray = np.eye(3) + first[..., None, None] * k + second[..., None, None] * (k @ k)
    return matrix


def _quaternion_from_matrix(m: FloatArray) -> FloatArray:
    """Unit quaternion (x, y, z, w), w >= 0, by Shepperd's method (vectorised)."""
    r00, r11, r22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = r00 + r11 + r22
    # four candidate (unnormalised) quaternions, each 4 q_i q_k times its pivot
    cand = np.stack(
        [
            np.stack(
                [
                    1 + 2 * r00 - trace,
                    m[..., 1, 0] + m[..., 0, 1],
                    m[..., 2, 0] + m[..., 0, 2],
                    m[..., 2, 1] - m[..., 1, 2],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 1, 0] + m[..., 0, 1],
                    1 + 2 * r11 - trace,
                    m[..., 2, 1] + m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 2, 0] + m[..., 0, 2],
                    m[..., 2, 1] + m[..., 1, 2],
                    1 + 2 * r22 - trace,
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                axis=-1,
            ),
            np.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                    1 + trace,
                ],
                axis=-1,
            ),
        ],
        axis=-2,
    )
    pivot = np.argmax(np.stack([r00, r11, r22, trace], axis=-1), axis=-1)
    q = np.take_along_axis(cand, pivot[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    quaternion: FloatArray = np.where(q[..., 3:] < 0, -q, q)
    return quaternion


def rotvec_from_matrix(matrix: ArrayLike) -> FloatArray:
    """Rotation vector (axis times angle) from a rotation matrix.

    Convention: active right-handed rotation by ``|rotvec|`` radians about
    ``rotvec/|rotvec|``; image -> object; premultiplies column vectors.
    Inverse of :func:`matrix_from_rotvec`.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices (checked by :func:`check_matrix`).

    Returns
    -------
    ndarray, shape (..., 3)
        Rotation vectors, radians, with ``|rotvec| <= pi``. At exactly 180 deg
        ``v`` and ``-v`` are the same rotation; either may be returned.

    Notes
    -----
    Via the unit quaternion (Shepperd's method), so that it is accurate at
    small angles and near 180 deg.

    References
    ----------
    S. W. Shepperd, "Quaternion from rotation matrix", Journal of Guidance
    and Control 1(3), 1978, pp. 223-224.

    Examples
    --------
    >>> import numpy as np
    >>> rotvec_from_matrix(matrix_from_rotvec([0.1, -0.2, 0.3])).round(12)
    array([ 0.1, -0.2,  0.3])
    """
    q = _quaternion_from_matrix(check_matrix(matrix))
    xyz, w = q[..., :3], q[..., 3]
    n = np.linalg.norm(xyz, axis=-1)
    safe_n = np.where(n > 0.0, n, 1.0)
    scale = np.where(n > 0.0, 2.0 * np.arctan2(n, w) / safe_n, 2.0)
    return scale[..., np.newaxis] * xyz


# ---------------------------------------------------------------------------
# conversions through the matrix


def opk_from_cardan(angles: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Omega, phi, kappa of the rotation given by Cardan alpha, omega, chi.

    Convention: input ``A = Ry(-alpha) Rx(omega) Rz(chi)`` (B(133)), output
    ``R = Rx(omega) Ry(phi) Rz(kappa)``; both active, image -> object,
    premultiplying column vectors; ``R == A``.

    Parameters
    ----------
    angles : array_like, shape (..., 3)
        ``(alpha, omega, chi)``, radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Input and output in degrees.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(omega, phi, kappa)``, radians (degrees if ``degrees=True``).

    Warns
    -----
    StripAerotriWarning
        Gimbal lock at phi = +-90 deg (see :func:`opk_from_matrix`).

    References
    ----------
    B(133); Wolf, Dewitt & Wilkinson, Elements of Photogrammetry, 4th ed.

    Examples
    --------
    >>> opk_from_cardan([0.0, 5.0, 0.0], degrees=True).round(12) + 0.0  # pure omega
    array([5., 0., 0.])
    """
    return _opk_from_matrix(matrix_from_cardan(angles, degrees=degrees), degrees, stacklevel=2)


def cardan_from_opk(opk: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Cardan alpha, omega, chi of the rotation given by omega, phi, kappa.

    Convention: input ``R = Rx(omega) Ry(phi) Rz(kappa)``, output
    ``A = Ry(-alpha) Rx(omega) Rz(chi)`` (B(133)); both active, image ->
    object, premultiplying column vectors; ``A == R``.

    Parameters
    ----------
    opk : array_like, shape (..., 3)
        ``(omega, phi, kappa)``, radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Input and output in degrees.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(alpha, omega, chi)``, radians (degrees if ``degrees=True``).

    Warns
    -----
    StripAerotriWarning
        Gimbal lock at omega = +-90 deg (see :func:`cardan_from_matrix`).

    References
    ----------
    B(129), B(133); Wolf, Dewitt & Wilkinson, Elements of Photogrammetry, 4th ed.

    Examples
    --------
    >>> cardan_from_opk([0.0, 4.0, 0.0], degrees=True).round(12) + 0.0  # phi = -alpha
    array([-4.,  0.,  0.])
    """
    return _cardan_from_matrix(matrix_from_opk(opk, degrees=degrees), degrees, stacklevel=2)


def schut_from_cardan(angles: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Schut's a, b, c of the rotation given by Cardan alpha, omega, chi.

    Convention: input ``A = Ry(-alpha) Rx(omega) Rz(chi)`` (B(133)), output
    ``(a, b, c) = tan(theta/2) * axis`` (J(2)); both active, image -> object,
    premultiplying column vectors.

    Parameters
    ----------
    angles : array_like, shape (..., 3)
        ``(alpha, omega, chi)``, radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Input angles in degrees.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(a, b, c)``, dimensionless.

    Raises
    ------
    GeometryError
        Rotation angle beyond 179 deg (see :func:`schut_from_matrix`).

    References
    ----------
    B(133); J(2).

    Examples
    --------
    >>> import numpy as np
    >>> np.round(schut_from_cardan([0.0, 0.0, 90.0], degrees=True), 12) + 0.0
    array([0., 0., 1.])
    """
    return _schut_from_matrix(matrix_from_cardan(angles, degrees=degrees))


def cardan_from_schut(abc: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Cardan alpha, omega, chi of the rotation given by Schut's a, b, c.

    Convention: input ``(a, b, c) = tan(theta/2) * axis`` (J(2)), output
    ``A = Ry(-alpha) Rx(omega) Rz(chi)`` (B(133)); both active, image ->
    object, premultiplying column vectors.

    Parameters
    ----------
    abc : array_like, shape (..., 3)
        Schut parameters, dimensionless.
    degrees : bool, optional
        Return degrees instead of radians.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(alpha, omega, chi)``, radians (degrees if ``degrees=True``).

    Warns
    -----
    StripAerotriWarning
        Gimbal lock at omega = +-90 deg (see :func:`cardan_from_matrix`).

    References
    ----------
    J(2); B(129), B(133).

    Examples
    --------
    >>> import numpy as np
    >>> np.round(cardan_from_schut([0.0, 0.0, 1.0], degrees=True), 12) + 0.0
    array([ 0.,  0., 90.])
    """
    return _cardan_from_matrix(matrix_from_schut(abc), degrees, stacklevel=2)


def opk_from_schut(abc: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Omega, phi, kappa of the rotation given by Schut's a, b, c.

    Convention: input ``(a, b, c) = tan(theta/2) * axis`` (J(2)), output
    ``R = Rx(omega) Ry(phi) Rz(kappa)``; both active, image -> object,
    premultiplying column vectors.

    Parameters
    ----------
    abc : array_like, shape (..., 3)
        Schut parameters, dimensionless.
    degrees : bool, optional
        Return degrees instead of radians.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(omega, phi, kappa)``, radians (degrees if ``degrees=True``).

    Warns
    -----
    StripAerotriWarning
        Gimbal lock at phi = +-90 deg (see :func:`opk_from_matrix`).

    References
    ----------
    J(2); Wolf, Dewitt & Wilkinson, Elements of Photogrammetry, 4th ed.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(opk_from_schut([1.0, 0.0, 0.0], degrees=True), 12) + 0.0
    array([90.,  0.,  0.])
    """
    return _opk_from_matrix(matrix_from_schut(abc), degrees, stacklevel=2)


def schut_from_opk(opk: ArrayLike, *, degrees: bool = False) -> FloatArray:
    """Schut's a, b, c of the rotation given by omega, phi, kappa.

    Convention: input ``R = Rx(omega) Ry(phi) Rz(kappa)``, output
    ``(a, b, c) = tan(theta/2) * axis`` (J(2)); both active, image -> object,
    premultiplying column vectors.

    Parameters
    ----------
    opk : array_like, shape (..., 3)
        ``(omega, phi, kappa)``, radians (degrees if ``degrees=True``).
    degrees : bool, optional
        Input angles in degrees.

    Returns
    -------
    ndarray, shape (..., 3)
        ``(a, b, c)``, dimensionless.

    Raises
    ------
    GeometryError
        Rotation angle beyond 179 deg (see :func:`schut_from_matrix`).

    References
    ----------
    J(2); Wolf, Dewitt & Wilkinson, Elements of Photogrammetry, 4th ed.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(schut_from_opk([0.0, 90.0, 0.0], degrees=True), 12) + 0.0
    array([0., 1., 0.])
    """
    return _schut_from_matrix(matrix_from_opk(opk, degrees=degrees))
