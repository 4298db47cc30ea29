"""The state of the relative orientation of every pair at once: the rotations
and bases of the dependent (b_y, b_z, Schut's a, b, c; J(5)-(10)) and the
base (B's five angles, B(125)-(135)) parametrisations, their updates and
snapshots, and the blocks of rows the y-parallaxes are computed in
(:mod: iterates them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..geometry.rotation import (
    cardan_from_matrix,
    matrix_from_cardan,
    matrix_from_schut,
    schut_from_matrix,
)

__all__ = ["chain_rotations"]


# An image vector's components over a block: x, y (nb, width) and z, which is
# one float where it is one constant (-c) for all rows.
_Components = tuple[FloatArray, FloatArray, FloatArray | float]


_J = np.array([0.0, 1.0, 0.0])
_EX = np.array([1.0, 0.0, 0.0])
_EY = np.array([0.0, 1.0, 0.0])
_EZ = np.array([0.0, 0.0, 1.0])


# J(9) fixed: the Schut parameters of the correcting rotation are half of the
# rotation vector a (phi = 2 (a, b, c)); the printed factor 1 converges only
# linearly (tests patch this to show it).
_SCHUT_FACTOR = 0.5


def chain_rotations(first: ArrayLike, relative: ArrayLike) -> FloatArray:
    """Rotations of the photos of a chain from the pairs' relative rotations.

    Parameters
    ----------
    first : array_like, shape (3, 3)
        Image -> strip rotation of the first photo.
    relative : array_like, shape (n_pairs, 3, 3)
        Right image -> left image rotation of each pair.

    Returns
    -------
    ndarray, shape (n_pairs + 1, 3, 3)
        ``R[0] = first``, ``R[m + 1] = R[m] @ relative[m]``.

    Notes
    -----
    The products are formed by a parallel prefix scan (Hillis-Steele):
    ``log2(n_pairs)`` batched 3 × 3 products instead of a Python loop over
    the pairs; the round-off is that of the sequential products.
    """
    first = np.asarray(first, dtype=np.float64)
    prefix = np.array(relative, dtype=np.float64)  # a copy
    shift = 1
    while shift < prefix.shape[0]:
        # prefix[m] = relative[m - 2 shift + 1] ... relative[m], in chain order
        prefix[shift:] = prefix[:-shift] @ prefix[shift:]
        shift *= 2
    out = np.empty((prefix.shape[0] + 1, 3, 3))
    out[0] = first
    out[1:] = first @ prefix
    return out


def _segment_starts(pair: IntArray, n_pairs: int) -> IntArray:
    return np.searchsorted(pair, np.arange(n_pairs)).astype(np.intp)


@dataclass(frozen=True)
class _Block:
    """Rows of a group of pairs as a padded (pairs, width) table.

    ``rows[i, k]`` indexes the flat (pair-sorted) arrays; padding cells repeat
    the pair's last row and are marked invalid, so maxima need no mask and
    sums only a zero weight.
    """

    pairs: IntArray  # (nb,)
    rows: IntArray  # (nb, width)
    valid: np.ndarray  # (nb, width) bool
    counts: IntArray  # (nb,) valid cells per pair
    # image vectors on the left and the right photo (mm): components x, y, z,
    # each (nb, width), z a float where it is one constant (-c) for all rows
    left: _Components
    right: _Components
    design: FloatArray = field(init=False, repr=False)  # (nb, 6, width) work buffer
    # (weights, sqrt w of the cells) for the last weights array, see root_weight
    _root: tuple[FloatArray | None, FloatArray | None] = field(
        init=False, repr=False, compare=False, default=(None, None)
    )

    def __post_init__(self) -> None:
        # Reused by every evaluation of the block: fresh 48 bytes per row per
        # evaluation would cost page faults comparable to the arithmetic.
        object.__setattr__(self, "design", np.empty((self.rows.shape[0], 6, self.rows.shape[1])))

    def root_weight(self, weight: FloatArray) -> FloatArray:
        """sqrt(w) of the cells (0 in padding), (nb, width), for the flat
        weights ``weight``; kept for the last weights array passed (the
        weights are replaced, never changed in place, when rows lose theirs)."""
        if self._root[0] is not weight:
            root: FloatArray = np.sqrt(np.take(weight, self.rows) * self.valid)
            object.__setattr__(self, "_root", (weight, root))
            return root
        cached = self._root[1]
        assert cached is not None
        return cached


class _Snapshot:
    """Copies of a state's unknowns (per-pair arrays), for steps taken back."""

    def __init__(self, state: _StateBase) -> None:
        self.arrays: dict[str, FloatArray] = {
            name: getattr(state, name).copy() for name in state.UNKNOWNS
        }

    def save(self, mask: BoolArray, state: _StateBase) -> None:
        """Copy the unknowns of the pairs in ``mask`` from ``state``."""
        if mask.any():
            for name, values in self.arrays.items():
                values[mask] = getattr(state, name)[mask]


class _StateBase:
    """Snapshot and restore of the per-pair unknowns listed in ``UNKNOWNS``."""

    UNKNOWNS: tuple[str, ...] = ()

    def snapshot(self) -> _Snapshot:
        return _Snapshot(self)

    def restore(self, mask: BoolArray, snapshot: _Snapshot) -> None:
        """Unknowns of the pairs in ``mask`` back to those of ``snapshot``."""
        if mask.any():
            for name, values in snapshot.arrays.items():
                current = getattr(self, name).copy()
                current[mask] = values[mask]
                setattr(self, name, current)
            self._refresh()

    def _refresh(self) -> None:
        """Recompute what derives from the unknowns (nothing by default)."""


def _rotate(
    matrices: FloatArray, x: FloatArray, y: FloatArray, z: FloatArray | float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Rows of ``matrices`` (nb, 3, 3) applied to the block's vectors (x, y, z),
    each (nb, width): the components of ``R @ v`` as three (nb, width) arrays."""
    r = matrices[:, :, :, None]
    c0, c1, c2 = (r[:, i, 0] * x + r[:, i, 1] * y + r[:, i, 2] * z for i in range(3))
    return c0, c1, c2


class _DependentState(_StateBase):
    """Unknowns of J's dependent pairs, solved in the left photo's image frame.

    Per pair: the relative rotation ``Q`` (right image -> left image) and the
    base components ``(b_y, b_z)`` along the left photo's image y and z axes
    (``b_x = 1``).  The y-parallax J(5) is taken along the left photo's image
    y axis, ``j = R_l (0, 1, 0)``: J's strip y axis when ``R_l = I`` (his first
    pair), and within the photos' tilts of it along a strip flown along x.
    The triple products of J(5) do not change under a common rotation, so the
    pair is solved in the left image frame: the left rays need no rotation,
    the right rays only ``Q``, and a pair's solution does not depend on the
    orientation of its left photo, whatever the heading and the given first
    orientation.  The chain of rotations is formed once, at the end.  The
    corrections of the rotation are found in the left image frame, where
    J's correcting rotation ``R_schut(a / 2)`` (fixed J(9)) premultiplies ``Q``.
    """

    UNKNOWNS = ("relative", "beta")

    def __init__(self, n_pairs: int, first: FloatArray) -> None:
        self.n_pairs = n_pairs
        self.first = first
        self.relative = np.broadcast_to(np.eye(3), (n_pairs, 3, 3)).copy()
        self.beta = np.zeros((n_pairs, 2))

    def terms(self, pairs: IntArray, block: _Block, m: FloatArray) -> FloatArray:
        """Fill ``m[:, :5]`` with the design rows (J(7) fixed) and ``m[:, 5]``
        with the y-parallax q (J(5)) of the block; return q at image scale (mm)."""
        lx, ly, lz = block.left
        p0, p1, p2 = _rotate(self.relative[pairs], *block.right)
        b1, b2 = self.beta[pairs].T[:, :, None]
        c0 = ly * p2 - lz * p1  # l × p
        c1 = lz * p0 - lx * p2
        c2 = lx * p1 - ly * p0
        inv_d = 1.0 / c1  # D = j·(l × p), j = (0, 1, 0)
        num = c0 + b1 * c1 + b2 * c2  # b·(l × p), b = (1, b_y, b_z)
        q = num * inv_d
        np.multiply(c1, inv_d, out=m[:, 0])  # ∂q/∂b_y = (l × p)_y / D
        np.multiply(c2, inv_d, out=m[:, 1])
        # ∂q/∂a = p × ((b − q j) × l) / D = (u (p·l) − l (p·u)) / D, u = b − q j
        u1 = b1 - q
        pl = p0 * lx + p1 * ly + p2 * lz
        pu = p0 + p1 * u1 + p2 * b2
        m[:, 2] = (pl - lx * pu) * inv_d
        m[:, 3] = (u1 * pl - ly * pu) * inv_d
        m[:, 4] = (b2 * pl - lz * pu) * inv_d
        m[:, 5] = q
        # At the left photo's image scale: q / k_l with k_l = j·(b × p) / D (J(12)).
        q_img: FloatArray = num / (b2 * p0 - p2)
        return q_img

    def residuals(self, pairs: IntArray, block: _Block) -> tuple[FloatArray, FloatArray]:
        """The y-parallaxes of ``terms`` without the design rows: q (model
        units) and q at image scale (mm), by the same operations."""
        lx, ly, lz = block.left
        p0, p1, p2 = _rotate(self.relative[pairs], *block.right)
        b1, b2 = self.beta[pairs].T[:, :, None]
        c1 = lz * p0 - lx * p2
        inv_d = 1.0 / c1
        num = (ly * p2 - lz * p1) + b1 * c1 + b2 * (lx * p1 - ly * p0)
        return num * inv_d, num / (b2 * p0 - p2)

    def set_start(self, elements: FloatArray) -> None:
        self.beta = elements[:, :2].copy()
        self.relative = matrix_from_schut(elements[:, 2:])

    def restart(self, mask: BoolArray, relative: FloatArray, base_dir: FloatArray) -> None:
        self.relative[mask] = relative
        self.beta[mask] = base_dir[:, 1:] / base_dir[:, :1]

    def update(self, corr: FloatArray) -> None:
        self.relative = matrix_from_schut(_SCHUT_FACTOR * corr[:, 2:]) @ self.relative
        self.beta = self.beta + corr[:, :2]

    def base_strip(self, r_left: FloatArray) -> FloatArray:
        """Base vectors in the strip system, given the left rotations of the chain."""
        beta = np.column_stack([np.ones(self.n_pairs), self.beta])
        base: FloatArray = np.einsum("mij,mj->mi", r_left, beta)
        return base

    def rotations(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        chain = chain_rotations(self.first, self.relative)
        # separate arrays: rotation_left and rotation_right are not views of each other
        return chain[:-1].copy(), chain[1:].copy(), self.relative.copy()

    def elements(self) -> FloatArray:
        return np.column_stack([self.beta, schut_from_matrix(self.relative)])


class _BaseState(_StateBase):
    """Unknowns of B's base system: alpha'1, chi'1 of the left photo and the right
    photo's rotation (alpha'2, omega'2, chi'2) relative to the base system, whose
    x axis is the base.  Independent of the chain; the strip values follow from
    A_tau_nu = R_left · A(alpha'1, 0, chi'1)^T, B(126)-(136)."""

    UNKNOWNS = ("angles_left", "r_right_base")

    def __init__(self, n_pairs: int, first: FloatArray) -> None:
        self.n_pairs = n_pairs
        self.first = first
        self.angles_left = np.zeros((n_pairs, 2))  # alpha'1, chi'1
        self.r_right_base = np.broadcast_to(np.eye(3), (n_pairs, 3, 3)).copy()
        self._refresh()

    def _left_base(self) -> FloatArray:
        a = np.zeros((self.angles_left.shape[0], 3))
        a[:, 0] = self.angles_left[:, 0]
        a[:, 2] = self.angles_left[:, 1]
        return matrix_from_cardan(a)

    def _refresh(self) -> None:
        self.l_base = self._left_base()

    def terms(self, pairs: IntArray, block: _Block, m: FloatArray) -> FloatArray:
        """As ``_DependentState.terms`` with b = (1, 0, 0) and j = (0, 1, 0) in
        the base system: B(131)-(136) for the elements alpha'1, chi'1 (left)
        and a rotation correction of the right photo."""
        l_base = self.l_base[pairs]
        l0, l1, l2 = _rotate(l_base, *block.left)
        p0, p1, p2 = _rotate(self.r_right_base[pairs], *block.right)
        num = l1 * p2 - l2 * p1  # (l × p)_x
        inv_d = 1.0 / (l2 * p0 - l0 * p2)  # (l × p)_y
        q = num * inv_d
        u1 = -q  # u = b − q j = (1, −q, 0)
        lu = l0 + u1 * l1
        pl = p0 * l0 + p1 * l1 + p2 * l2
        pu = p0 + u1 * p1
        # left photo: g = l × (p × u) / D = (p (l·u) − u (l·p)) / D
        g0 = (p0 * lu - pl) * inv_d
        g1 = (p1 * lu - u1 * pl) * inv_d
        g2 = p2 * lu * inv_d
        np.negative(g1, out=m[:, 0])  # alpha'1 turns the left ray about the base-system y axis
        e0, e1, e2 = l_base[:, :, 2].T[:, :, None]  # chi'1: about the left image z axis
        m[:, 1] = e0 * g0 + e1 * g1 + e2 * g2
        # right photo: p × (u × l) / D = (u (p·l) − l (p·u)) / D
        m[:, 2] = (pl - l0 * pu) * inv_d
        m[:, 3] = (u1 * pl - l1 * pu) * inv_d
        m[:, 4] = -l2 * pu * inv_d
        m[:, 5] = q
        return num / -p2  # q / k_l with k_l = j·(b × p) / D = −p_z / D

    def residuals(self, pairs: IntArray, block: _Block) -> tuple[FloatArray, FloatArray]:
        """The y-parallaxes of ``terms``: q (model units) and at image scale (mm)."""
        m = np.empty_like(block.design)
        q_img = self.terms(pairs, block, m)
        return m[:, 5], q_img

    def restart(self, mask: BoolArray, relative: FloatArray, base_dir: FloatArray) -> None:
        # Base system: x' along the base, z' in the principal plane of the left
        # photo (B §125), so the left photo needs no omega'.
        x = base_dir / np.linalg.norm(base_dir, axis=1, keepdims=True)
        z = _EZ - x[:, 2:3] * x
        z /= np.linalg.norm(z, axis=1, keepdims=True)
        y = np.cross(z, x)
        left_base = np.stack([x, y, z], axis=1)  # rows: base axes in the left image
        angles = cardan_from_matrix(left_base)
        self.angles_left[mask] = angles[:, [0, 2]]
        self.r_right_base[mask] = self._left_base()[mask] @ relative
        self._refresh()

    def set_start(self, elements: FloatArray) -> None:
        self.angles_left = elements[:, :2].copy()
        self.r_right_base = matrix_from_cardan(elements[:, 2:])
        self._refresh()

    def update(self, corr: FloatArray) -> None:
        self.angles_left = self.angles_left + corr[:, :2]
        self.r_right_base = matrix_from_schut(_SCHUT_FACTOR * corr[:, 2:]) @ self.r_right_base
        self._refresh()

    def rotations(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        relative = np.swapaxes(self.l_base, 1, 2) @ self.r_right_base
        chain = chain_rotations(self.first, relative)
        return chain[:-1].copy(), chain[1:].copy(), relative

    def base_strip(self, r_left: FloatArray) -> FloatArray:
        """Base vectors in the strip system, given the left rotations of the chain."""
        # A_tau_nu = R_left A'^T; its first column is the base direction, B(130).
        a_tau_nu = r_left @ np.swapaxes(self.l_base, 1, 2)
        b = a_tau_nu[:, :, 0]
        along = np.einsum("mi,mi->m", b, r_left[:, :, 0])  # component along image x
        base: FloatArray = b / along[:, None]
        return base

    def elements(self) -> FloatArray:
        right = cardan_from_matrix(self.r_right_base)
        return np.column_stack([self.angles_left, right])


_State = _DependentState | _BaseState
