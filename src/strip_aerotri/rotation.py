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

import numpy as np

from ._typing import ArrayLike, FloatArray


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
    J(2): Janiszewski (1975), analytical strip aerotriangulation, formula (2);
    E. H. Thompson / G. H. Schut's algebraic rotation matrix.

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
