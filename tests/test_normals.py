"""The structured normal-equation engine (geometry/normals.py) against a dense
least-squares solution of the same rows (np.linalg.solve / inv of AᵀPA)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from strip_aerotri.geometry.normals import (
    BorderRows,
    NormalStructure,
    PointRows,
    SingularNormalsError,
    UnitPointRows,
    UnitRows,
)


@dataclass
class Problem:
    n: int
    d: int
    p: int
    k: int
    upr: list[UnitPointRows]
    ur: list[UnitRows]
    pr: list[PointRows]
    br: list[BorderRows]


def _weight(rng: np.random.Generator, g: int, r: int, full: bool) -> np.ndarray:
    if not full:
        return rng.uniform(0.5, 4.0, (g, r))
    m = rng.normal(size=(g, r, r))
    return m @ np.swapaxes(m, 1, 2) + r * np.eye(r)


def make_problem(
    seed: int = 2345,
    *,
    n: int = 14,
    d: int = 6,
    strips: int = 1,
    window: int = 4,
    k: int = 0,
    unit_rows: bool = True,
    point_rows: bool = True,
    full_weights: bool = False,
    shuffle_units: bool = False,
    per_window: int = 3,
) -> Problem:
    """Random rows with the structure of a strip (points seen by `window`
    consecutive units) or a block (`strips` strips side by side, points also
    seen by the neighbouring strip's units at the same place)."""
    rng = np.random.default_rng(seed)
    per_strip = n // strips
    unit_list, point_list = [], []
    p = 0
    for s in range(strips):
        for start in range(per_strip - 1):
            for _ in range(per_window):  # points of this window
                q = int(rng.integers(2, window + 1))
                units = s * per_strip + np.arange(start, min(start + q, per_strip))
                if s + 1 < strips and rng.random() < 0.5:  # a point in the side lap
                    units = np.r_[units, (s + 1) * per_strip + start]
                unit_list.append(units)
                point_list.append(np.full(units.size, p))
                p += 1
    unit = np.concatenate(unit_list)
    point = np.concatenate(point_list)
    if shuffle_units:
        perm = rng.permutation(n)
        unit = perm[unit]
    g = unit.size
    r = 2
    upr = [
        UnitPointRows(
            unit[: g // 2],
            point[: g // 2],
            rng.normal(size=(g // 2, r, d)),
            rng.normal(size=(g // 2, r, 3)),
            rng.normal(size=(g // 2, r)),
            _weight(rng, g // 2, r, full_weights),
            rng.normal(size=(g // 2, r, k)) * 0.3 if k else None,
        ),
        UnitPointRows(
            unit[g // 2 :],
            point[g // 2 :],
            rng.normal(size=(g - g // 2, r, d)),
            rng.normal(size=(g - g // 2, r, 3)),
            rng.normal(size=(g - g // 2, r)),
            _weight(rng, g - g // 2, r, full_weights),
            rng.normal(size=(g - g // 2, r, k)) * 0.3 if k else None,
        ),
    ]
    ur: list[UnitRows] = []
    if unit_rows:
        gu = n
        ur.append(  # a prior on every unit (GNSS-like), 3 rows
            UnitRows(
                np.arange(n)[:, None],
                rng.normal(size=(gu, 3, 1, d)),
                rng.normal(size=(gu, 3)),
                rng.uniform(0.5, 2.0, (gu, 3)),
            )
        )
        a = np.arange(n - 1)
        a = a[(a + 1) % per_strip != 0]  # neighbours along each strip
        ur.append(  # conditions linking neighbours, 2 rows
            UnitRows(
                np.stack([a, a + 1], axis=1),
                rng.normal(size=(a.size, 2, 2, d)),
                rng.normal(size=(a.size, 2)),
                None,
                rng.normal(size=(a.size, 2, k)) * 0.3 if k else None,
            )
        )
    pr: list[PointRows] = []
    if point_rows:
        ctrl = rng.choice(p, size=max(3, p // 5), replace=False)
        pr.append(
            PointRows(
                ctrl,
                rng.normal(size=(ctrl.size, 3, 3)),
                rng.normal(size=(ctrl.size, 3)),
                _weight(rng, ctrl.size, 3, full_weights),
                rng.normal(size=(ctrl.size, 3, k)) * 0.3 if k else None,
            )
        )
    br: list[BorderRows] = []
    if k:
        br.append(BorderRows(rng.normal(size=(2, 1, k)), rng.normal(size=(2, 1)), None))
    return Problem(n, d, p, k, upr, ur, pr, br)


def _t(weight: np.ndarray | None, g: int, r: int) -> np.ndarray:
    if weight is None:
        return np.broadcast_to(np.eye(r), (g, r, r))
    if weight.ndim == 2:
        return np.asarray(np.sqrt(weight)[:, :, None] * np.eye(r), dtype=np.float64)
    return np.asarray(np.swapaxes(np.linalg.cholesky(weight), 1, 2), dtype=np.float64)


def dense(prob: Problem) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Whitened A (rows, unknowns) and f; unknowns: units, points, border."""
    n, d, p, k = prob.n, prob.d, prob.p, prob.k
    cols = n * d + 3 * p + k
    blocks_a, blocks_f, sizes = [], [], []

    def add(a: np.ndarray, f: np.ndarray, weight: np.ndarray | None) -> None:
        g, r = f.shape
        t = _t(weight, g, r)
        blocks_a.append(np.einsum("gij,gjc->gic", t, a).reshape(g * r, cols))
        blocks_f.append(np.einsum("gij,gj->gi", t, f).reshape(-1))
        sizes.append((g, r))

    for rows in prob.upr:
        g, r = rows.residual.shape
        a = np.zeros((g, r, cols))
        for i in range(d):
            a[np.arange(g), :, rows.unit * d + i] = rows.unit_jacobian[:, :, i]
        for i in range(3):
            a[np.arange(g), :, n * d + rows.point * 3 + i] = rows.point_jacobian[:, :, i]
        if k:
            a[:, :, n * d + 3 * p :] = rows.border_jacobian
        add(a, rows.residual, rows.weight)
    for urows in prob.ur:
        g, r = urows.residual.shape
        a = np.zeros((g, r, cols))
        for j in range(urows.units.shape[1]):
            for i in range(d):
                a[np.arange(g), :, urows.units[:, j] * d + i] += urows.jacobian[:, :, j, i]
        if k and urows.border_jacobian is not None:
            a[:, :, n * d + 3 * p :] = urows.border_jacobian
        add(a, urows.residual, urows.weight)
    for prows in prob.pr:
        g, r = prows.residual.shape
        a = np.zeros((g, r, cols))
        for i in range(3):
            a[np.arange(g), :, n * d + prows.point * 3 + i] = prows.jacobian[:, :, i]
        if k:
            a[:, :, n * d + 3 * p :] = prows.border_jacobian
        add(a, prows.residual, prows.weight)
    for brows in prob.br:
        g, r = brows.residual.shape
        a = np.zeros((g, r, cols))
        a[:, :, n * d + 3 * p :] = brows.jacobian
        add(a, brows.residual, brows.weight)
    return np.concatenate(blocks_a), np.concatenate(blocks_f), sizes  # type: ignore[return-value]


def _structure(prob: Problem, order: str = "auto") -> NormalStructure:
    return NormalStructure(prob.n, prob.d, prob.p, prob.upr, prob.ur, n_border=prob.k, order=order)


def _solve(prob: Problem, order: str = "auto"):  # type: ignore[no-untyped-def]
    st = _structure(prob, order)
    return st, st.solve(prob.upr, prob.ur, prob.pr, prob.br)


CASES = {
    "strip": {},
    "strip-d7": {"d": 7},
    "strip-border": {"k": 3},
    "strip-bare": {"unit_rows": False, "point_rows": False, "window": 5, "per_window": 8},
    "strip-full-weights": {"full_weights": True, "k": 2},
    "block": {"strips": 3, "n": 15},
    "block-border": {"strips": 3, "n": 15, "k": 2},
    "block-shuffled": {"strips": 2, "n": 16, "shuffle_units": True},
}


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_step_equals_dense_solution(case: str) -> None:
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    a, f, _ = dense(prob)
    st, sol = _solve(prob)
    n_d = prob.n * prob.d
    expected = np.linalg.solve(a.T @ a, -a.T @ f)
    got = np.concatenate(
        [sol.unit_step.ravel(), sol.point_step.ravel(), sol.border_step.ravel()]
    )
    assert np.linalg.norm(got - expected) <= 1e-10 * np.linalg.norm(expected)
    assert sol.cost == pytest.approx(float(f @ f), rel=1e-12)
    assert sol.predicted_cost == pytest.approx(float(np.sum((f + a @ expected) ** 2)), rel=1e-9)
    assert got[:n_d].size == n_d


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_selected_inverse_equals_dense_inverse(case: str) -> None:
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    a, _, _ = dense(prob)
    q = np.linalg.inv(a.T @ a)
    st, sol = _solve(prob)
    cof = sol.cofactors()
    n, d, p, k = prob.n, prob.d, prob.p, prob.k
    scale = np.abs(q).max()
    unit_q = np.stack([q[i * d : (i + 1) * d, i * d : (i + 1) * d] for i in range(n)])
    np.testing.assert_allclose(cof.unit, unit_q, atol=1e-10 * scale)
    o = n * d
    point_q = np.stack([q[o + 3 * j : o + 3 * j + 3, o + 3 * j : o + 3 * j + 3] for j in range(p)])
    np.testing.assert_allclose(cof.point, point_q, atol=1e-10 * scale)
    # unit-point blocks of every coupled pair
    unit = np.concatenate([r.unit for r in prob.upr])
    point = np.concatenate([r.point for r in prob.upr])
    up = cof.unit_point(unit, point)
    for i, j, blk in zip(unit, point, up):
        np.testing.assert_allclose(
            blk, q[i * d : (i + 1) * d, o + 3 * j : o + 3 * j + 3], atol=1e-10 * scale
        )
    # the band: every pair of units within the band of each other
    pos = np.empty(n, int)
    pos[st.order] = np.arange(n)
    ia, ib = np.nonzero(np.abs(pos[:, None] - pos[None, :]) <= st.width)
    blocks = cof.unit_blocks(ia, ib)
    for i, j, blk in zip(ia, ib, blocks):
        q_ij = q[i * d : (i + 1) * d, j * d : (j + 1) * d]
        np.testing.assert_allclose(blk, q_ij, atol=1e-10 * scale)
    if k:
        b = n * d + 3 * p
        np.testing.assert_allclose(cof.border, q[b:, b:], atol=1e-10 * scale)
        np.testing.assert_allclose(
            cof.unit_border, q[:o, b:].reshape(n, d, k), atol=1e-10 * scale
        )
        np.testing.assert_allclose(
            cof.point_border, q[o:b, b:].reshape(p, 3, k), atol=1e-10 * scale
        )


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_redundancy_numbers(case: str) -> None:
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    a, _, sizes = dense(prob)
    q = np.linalg.inv(a.T @ a)
    expected = 1.0 - np.einsum("ij,jk,ik->i", a, q, a)
    _, sol = _solve(prob)
    cof = sol.cofactors()
    all_rows = [*prob.upr, *prob.ur, *prob.pr, *prob.br]
    got = np.concatenate([cof.redundancy(rows).ravel() for rows in all_rows])
    np.testing.assert_allclose(got, expected, atol=1e-10)
    assert got.sum() == pytest.approx(a.shape[0] - a.shape[1], abs=1e-9)


@pytest.mark.parametrize("case", ["block", "block-shuffled", "strip-border"])
def test_order_does_not_change_the_solution(case: str) -> None:
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    solutions = {o: _solve(prob, o) for o in ("given", "rcm", "auto")}
    ref = solutions["given"][1]
    widths = {o: s[0].width for o, s in solutions.items()}
    assert widths["auto"] == min(widths["given"], widths["rcm"])
    for o, (_, sol) in solutions.items():
        np.testing.assert_allclose(sol.unit_step, ref.unit_step, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(sol.point_step, ref.point_step, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(
            sol.cofactors().point, ref.cofactors().point, rtol=1e-9, atol=1e-12
        )


def test_shuffled_units_are_reordered_to_a_narrow_band() -> None:
    prob = make_problem(strips=1, n=30, shuffle_units=True, unit_rows=False)
    given = _structure(prob, "given")
    auto = _structure(prob, "auto")
    assert auto.width < given.width
    assert auto.width <= 4  # the window of the strip (points on up to 4 consecutive units)


def test_bandwidth_of_a_strip_is_its_window() -> None:
    prob = make_problem(window=3, unit_rows=False)
    assert _structure(prob, "given").width == 2


def test_damping_scales_the_diagonals() -> None:
    prob = make_problem()
    a, f, _ = dense(prob)
    n_mat = a.T @ a
    lam = 0.3
    damped = n_mat + lam * np.diag(np.diag(n_mat))
    st = _structure(prob)
    sol = st.solve(prob.upr, prob.ur, prob.pr, prob.br, damping=lam)
    expected = np.linalg.solve(damped, -a.T @ f)
    got = np.concatenate([sol.unit_step.ravel(), sol.point_step.ravel()])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="damped"):
        sol.cofactors()


def test_singular_point_is_named() -> None:
    prob = make_problem(point_rows=False)
    # the last point: seen by one unit only (2 rows for 3 unknowns)
    rows = prob.upr[1]
    last = rows.point == prob.p - 1
    keep = ~last
    keep[np.flatnonzero(last)[0]] = True
    prob.upr[1] = UnitPointRows(
        rows.unit[keep], rows.point[keep], rows.unit_jacobian[keep],
        rows.point_jacobian[keep], rows.residual[keep], rows.weight[keep],  # type: ignore[index]
    )
    st = NormalStructure(
        prob.n, prob.d, prob.p, prob.upr, prob.ur,
        point_names=[f"P{i}" for i in range(prob.p)],
    )
    with pytest.raises(SingularNormalsError, match=f"'P{prob.p - 1}'") as info:
        st.solve(prob.upr, prob.ur, prob.pr)
    assert info.value.kind == "point" and info.value.index == prob.p - 1


def test_singular_unit_is_named() -> None:
    prob = make_problem(unit_rows=False, point_rows=False)
    # unit 5 loses its rows' dependence on its last parameter
    for rows in prob.upr:
        rows.unit_jacobian[rows.unit == 5, :, prob.d - 1] = 0.0
    st = NormalStructure(
        prob.n, prob.d, prob.p, prob.upr, unit_names=[f"photo{i}" for i in range(prob.n)],
        parameter_names=["a", "b", "c", "d", "e", "kappa"],
    )
    with pytest.raises(SingularNormalsError, match="kappa of 'photo5'") as info:
        st.solve(prob.upr)
    assert info.value.kind == "unit" and info.value.index == 5 and info.value.parameter == 5


def test_bad_shapes_are_refused() -> None:
    prob = make_problem()
    st = _structure(prob)
    bad = UnitPointRows(
        prob.upr[0].unit, prob.upr[0].point, prob.upr[0].unit_jacobian[:, :, :3],
        prob.upr[0].point_jacobian, prob.upr[0].residual,
    )
    with pytest.raises(ValueError, match="unit_jacobian"):
        st.solve([bad, prob.upr[1]])
    with pytest.raises(ValueError, match="order"):
        _structure(prob, "nested")


def test_rows_in_another_order_than_the_structure_give_the_same_solution() -> None:
    """The structure's own rows take the fast path (unit blocks by stacked
    products); rows in another order or split otherwise take the general
    one (sums by index): both equal the dense solution."""
    prob = make_problem(k=2)
    a, f, _ = dense(prob)
    expected = np.linalg.solve(a.T @ a, -a.T @ f)
    st = _structure(prob)
    rows = prob.upr[0]
    flip = np.arange(rows.unit.size)[::-1]
    flipped = UnitPointRows(
        rows.unit[flip], rows.point[flip], rows.unit_jacobian[flip], rows.point_jacobian[flip],
        rows.residual[flip], rows.weight[flip], rows.border_jacobian[flip],  # type: ignore[index]
    )
    for upr in (prob.upr, [flipped, prob.upr[1]], [prob.upr[1], prob.upr[0]]):
        sol = st.solve(upr, prob.ur, prob.pr, prob.br)
        got = np.concatenate(
            [sol.unit_step.ravel(), sol.point_step.ravel(), sol.border_step.ravel()]
        )
        assert np.linalg.norm(got - expected) <= 1e-10 * np.linalg.norm(expected)


def test_predicted_cost_and_from_indices() -> None:
    prob = make_problem()
    a, f, _ = dense(prob)
    unit = np.concatenate([r.unit for r in prob.upr])
    point = np.concatenate([r.point for r in prob.upr])
    st = NormalStructure.from_indices(
        prob.n, prob.d, prob.p, unit, point, [u.units for u in prob.ur]
    )
    assert st.width == _structure(prob).width
    formed = st.form(prob.upr, prob.ur, prob.pr)
    sol = formed.solve()
    step = np.concatenate([sol.unit_step.ravel(), sol.point_step.ravel()])
    assert sol.predicted_cost == pytest.approx(float(np.sum((f + a @ step) ** 2)), rel=1e-9)
    # the least-squares step: the predicted cost is the minimum of the linear problem
    assert sol.predicted_cost <= formed.solve(damping=0.1).predicted_cost


def test_a_condition_between_distant_units_widens_the_band() -> None:
    """A unit row linking the first and the last unit couples them: the band
    (in the given order) spans the whole strip and the solution stays exact."""
    prob = make_problem(unit_rows=False, n=10)
    rng = np.random.default_rng(7)
    link = UnitRows(
        np.array([[0, prob.n - 1]]), rng.normal(size=(1, 3, 2, prob.d)), rng.normal(size=(1, 3))
    )
    prob.ur.append(link)
    assert _structure(prob, "given").width == prob.n - 1
    a, f, sizes = dense(prob)
    _, sol = _solve(prob, "given")
    expected = np.linalg.solve(a.T @ a, -a.T @ f)
    got = np.concatenate([sol.unit_step.ravel(), sol.point_step.ravel()])
    assert np.linalg.norm(got - expected) <= 1e-10 * np.linalg.norm(expected)
    r = sol.cofactors().redundancy(link)
    q = np.linalg.inv(a.T @ a)
    start = sum(g * r for g, r in sizes[: len(prob.upr) + len(prob.ur) - 1])  # the link's rows
    rows = a[start : start + 3]
    np.testing.assert_allclose(r[0], 1.0 - np.einsum("ij,jk,ik->i", rows, q, rows), atol=1e-10)


def test_zero_weight_rows_leave_the_adjustment() -> None:
    """Weight 0 drops a row (a rejected observation): the same solution as
    without it, and its redundancy number is 1."""
    prob = make_problem()
    rows = prob.upr[0]
    weight = np.array(rows.weight)
    weight[3] = 0.0
    zeroed = UnitPointRows(rows.unit, rows.point, rows.unit_jacobian, rows.point_jacobian,
                           rows.residual, weight)
    keep = np.arange(rows.unit.size) != 3
    dropped = UnitPointRows(rows.unit[keep], rows.point[keep], rows.unit_jacobian[keep],
                            rows.point_jacobian[keep], rows.residual[keep], weight[keep])
    st = _structure(prob)
    a_sol = st.solve([zeroed, prob.upr[1]], prob.ur, prob.pr)
    b_sol = st.solve([dropped, prob.upr[1]], prob.ur, prob.pr)
    np.testing.assert_allclose(a_sol.unit_step, b_sol.unit_step, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a_sol.cofactors().redundancy(zeroed)[3], 1.0, atol=1e-12)


def test_singular_border_is_named() -> None:
    """A border parameter no row depends on is reported, not a LinAlgError."""
    prob = make_problem(k=2)
    for rows in [*prob.upr, *prob.ur, *prob.pr]:
        if rows.border_jacobian is not None:
            rows.border_jacobian[:, :, 1] = 0.0
    prob.br.clear()
    st = _structure(prob)
    with pytest.raises(SingularNormalsError, match="border parameter 1") as info:
        st.solve(prob.upr, prob.ur, prob.pr)
    assert info.value.kind == "border" and info.value.index == 1


@pytest.mark.parametrize("seed", range(12))
def test_random_shapes_equal_the_dense_solution(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Random sizes, block shapes, borders and weights; the pattern's chunks
    made small (every chunk a few groups) so that the split paths run."""
    from strip_aerotri.geometry import _normal_pattern

    rng = np.random.default_rng(100 + seed)
    if seed % 2:
        monkeypatch.setattr(_normal_pattern, "CHUNK_ENTRIES", int(rng.integers(1, 3000)))
    strips = int(rng.integers(1, 4))
    prob = make_problem(
        seed,
        n=strips * int(rng.integers(4, 9)),
        d=int(rng.integers(1, 9)),
        strips=strips,
        window=int(rng.integers(2, 6)),
        k=int(rng.integers(0, 4)),
        full_weights=bool(rng.integers(0, 2)),
        shuffle_units=bool(rng.integers(0, 2)),
        per_window=int(rng.integers(4, 9)),
    )
    a, f, _ = dense(prob)
    n_mat = a.T @ a
    if np.linalg.cond(n_mat) > 1e10:
        pytest.skip("this draw is not well determined")
    expected = np.linalg.solve(n_mat, -a.T @ f)
    q = np.linalg.inv(n_mat)
    st, sol = _solve(prob)
    got = np.concatenate([sol.unit_step.ravel(), sol.point_step.ravel(), sol.border_step.ravel()])
    assert np.linalg.norm(got - expected) <= 1e-9 * np.linalg.norm(expected)
    cof = sol.cofactors()
    o = prob.n * prob.d
    scale = np.abs(q).max()
    point_q = np.stack(
        [q[o + 3 * j : o + 3 * j + 3, o + 3 * j : o + 3 * j + 3] for j in range(prob.p)]
    )
    np.testing.assert_allclose(cof.point, point_q, atol=1e-9 * scale)
    all_rows = [*prob.upr, *prob.ur, *prob.pr, *prob.br]
    r = np.concatenate([cof.redundancy(rows).ravel() for rows in all_rows])
    np.testing.assert_allclose(r, 1.0 - np.einsum("ij,jk,ik->i", a, q, a), atol=1e-9)


@pytest.mark.parametrize(
    "n, d, w",
    [(1, 6, 0), (5, 6, 1), (14, 6, 6), (23, 7, 4), (40, 1, 9), (9, 36, 2), (50, 6, 13), (8, 6, 7)],
)
def test_selected_inverse_of_a_block_band_is_the_dense_inverse(n: int, d: int, w: int) -> None:
    # S = L Lᵀ with L lower within the block band: the band of
    # S⁻¹ from Takahashi's recursion (run on blocks of several units) against
    # the dense inverse, every block within w of the diagonal and zero beyond
    from strip_aerotri.geometry._blockband import factor_band, selected_inverse

    rng = np.random.default_rng(n * 100 + d * 10 + w)
    size = n * d
    i, j = np.indices((size, size))
    inside = (i >= j) & (i // d - j // d <= w)
    lower = rng.normal(size=(size, size)) * inside / np.sqrt((w + 1) * d)
    lower[np.arange(size), np.arange(size)] = rng.uniform(2.0, 4.0, size)
    s = lower @ lower.T
    band = np.zeros((n, w + 1, d, d))
    for jj in range(n):
        for o in range(min(w + 1, n - jj)):
            band[jj, o] = s[(jj + o) * d : (jj + o + 1) * d, jj * d : (jj + 1) * d]
    z = selected_inverse(factor_band(band))
    q = np.linalg.inv(s)
    for jj in range(n):
        for o in range(w + 1):
            expected = (
                q[(jj + o) * d : (jj + o + 1) * d, jj * d : (jj + 1) * d]
                if jj + o < n
                else np.zeros((d, d))
            )
            np.testing.assert_allclose(z[jj, o], expected, atol=1e-10 * np.abs(q).max())


@pytest.mark.parametrize("kind", ["sorted", "contiguous", "scattered", "one"])
def test_run_sums_and_blocks_equal_a_plain_scatter(
    kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the entry-major sums per unit or point (runs of an index, in its own
    # order, in contiguous runs out of order, or scattered) against np.add.at;
    # the blocks of the blocked products cover every place once, cut between runs
    from strip_aerotri.geometry import _normal_entries as ne
    from strip_aerotri.geometry._normal_pattern import runs_of

    rng = np.random.default_rng(7)
    n = 40
    index = np.sort(rng.integers(0, n, 3000))
    if kind == "contiguous":  # runs kept together, their values shuffled
        values = np.unique(index)
        index = np.repeat(rng.permutation(values), rng.integers(1, 9, values.size))
    elif kind == "scattered":
        index = rng.permutation(index)
    elif kind == "one":
        index = np.full(3000, 5)
    runs = runs_of(index)
    assert (runs[0] is None) == (kind != "scattered")
    x = rng.normal(size=(2, 3, index.size))
    expected = np.zeros((n, 2, 3))
    np.add.at(expected, index, np.moveaxis(x, -1, 0))
    np.testing.assert_allclose(ne.run_sums(x, runs, n), expected, atol=1e-12)
    monkeypatch.setattr(ne, "BLOCK", 100)
    blocks = ne.blocks_of(runs, index.size)
    assert len(blocks) > 1 or kind == "one"
    got = np.zeros((n, 2, 3))
    covered = np.zeros(index.size, int)
    for span, places, starts, seen in blocks:
        part = x[..., places]
        covered[np.arange(index.size)[places]] += 1
        got[seen] += np.moveaxis(np.add.reduceat(part, starts, axis=-1), -1, 0)
        ordered = index if runs[0] is None else index[runs[0]]
        assert np.all(ordered[span][starts] == seen)
    assert np.all(covered == 1)
    np.testing.assert_allclose(got, expected, atol=1e-12)


@pytest.mark.parametrize("d", [1, 3, 6, 7])
def test_gram_sums_from_the_lower_triangle_equal_the_full_products_to_the_bit(d: int) -> None:
    # U = Σ aᵀ a per unit and V per point from the d (d + 1) / 2 lower entries:
    # the same bits as the full einsum, and symmetric
    from strip_aerotri.geometry import _normal_entries as ne

    rng = np.random.default_rng(d)
    x = rng.normal(size=(2, d, 500)) * np.exp(rng.normal(size=(1, d, 500)) * 3.0)
    starts = np.r_[0, np.sort(rng.choice(np.arange(1, 500), 40, replace=False))]
    full = ne._summed(np.einsum("rak,rbk->abk", x, x), starts)
    got = ne._gram_summed(x, starts)
    assert got.shape == (41, d, d)
    np.testing.assert_array_equal(got, full)
    np.testing.assert_array_equal(got, np.swapaxes(got, 1, 2))
    expected = np.zeros((41, d, d))
    np.add.at(expected, np.searchsorted(starts, np.arange(500), side="right") - 1,
              np.einsum("rak,rbk->kab", x, x))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("case", ["strip", "strip-border", "block-border"])
def test_a_solve_without_its_step_gives_the_same_cofactors(case: str) -> None:
    # the factor and the cofactors alone (the bundle's precision): every block
    # the bits of a full solve's, the steps NaN, the pivots the same
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    st = _structure(prob)
    formed = st.form(prob.upr, prob.ur, prob.pr, prob.br)
    full, bare = formed.solve(), formed.solve(step=False)
    assert np.all(np.isnan(bare.unit_step)) and np.all(np.isnan(bare.point_step))
    assert np.all(np.isnan(bare.border_step)) and bare.border_step.shape == (prob.k,)
    assert bare.min_pivot == full.min_pivot
    np.testing.assert_array_equal(bare.border_cofactor, full.border_cofactor)
    a, b = full.cofactors(), bare.cofactors()
    for name in ("unit", "point", "border", "unit_border", "point_border", "band", "pair"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
    np.testing.assert_array_equal(b.redundancy(prob.upr[0]), a.redundancy(prob.upr[0]))


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_the_cofactors_of_some_points_equal_the_dense_inverse(case: str) -> None:
    # a few points' blocks from the band of the selected inverse alone (every
    # point's block through cofactors() where there is a border), in any
    # order and repeated, equal to the dense inverse and to cofactors()' blocks
    prob = make_problem(**CASES[case])  # type: ignore[arg-type]
    a, _, _ = dense(prob)
    q = np.linalg.inv(a.T @ a)
    o, scale = prob.n * prob.d, np.abs(q).max()
    _, sol = _solve(prob)
    chosen = np.array([prob.p - 1, 0, 3, 3, prob.p // 2])
    got = sol.point_cofactors(chosen)
    assert sol._cofactors is None or prob.k  # no selected inverse of every point without a border
    expected = np.stack([q[o + 3 * j : o + 3 * j + 3, o + 3 * j : o + 3 * j + 3] for j in chosen])
    np.testing.assert_allclose(got, expected, atol=1e-10 * scale)
    np.testing.assert_allclose(got, sol.cofactors().point[chosen], atol=1e-12 * scale)
    assert sol.point_cofactors(np.zeros(0, np.intp)).shape == (0, 3, 3)


def _shift_problem(case: dict[str, object], *, shuffle_rows: bool, flag: bool = True) -> Problem:
    """The case's rows as one group whose unit's first three columns are the
    point's negated (a projection centre against its image points), marked
    `unit_shift`, sorted by unit or shuffled; without a border (the kernel's
    case)."""
    prob = make_problem(**case)  # type: ignore[arg-type]
    a, b = prob.upr
    unit, point = np.r_[a.unit, b.unit], np.r_[a.point, b.point]
    au = np.concatenate([a.unit_jacobian, b.unit_jacobian])
    ap = np.concatenate([a.point_jacobian, b.point_jacobian])
    f = np.concatenate([a.residual, b.residual])
    assert a.weight is not None and b.weight is not None
    w = np.concatenate([a.weight, b.weight])
    au[..., :3] = -ap
    # rows sorted by unit (the units' sums by their runs) or at random (by bincount)
    perm = (
        np.random.default_rng(5).permutation(unit.size) if shuffle_rows
        else np.argsort(unit, kind="stable")
    )
    unit, point, au, ap, f, w = unit[perm], point[perm], au[perm], ap[perm], f[perm], w[perm]
    rows = UnitPointRows(unit, point, au, ap, f, w, unit_shift=flag)
    return Problem(prob.n, prob.d, prob.p, 0, [rows], prob.ur, prob.pr, [])


SHIFT_CASES = {
    "strip": {},
    "strip-d7": {"d": 7},
    "block-shuffled": {"strips": 2, "n": 16, "shuffle_units": True},
    "strip-full-weights": {"full_weights": True},
}


@pytest.mark.parametrize("case", list(SHIFT_CASES), ids=list(SHIFT_CASES))
@pytest.mark.parametrize("shuffle_rows", [False, True], ids=["by-unit", "shuffled"])
def test_unit_shift_rows_in_either_order_equal_the_dense_solution(
    case: str, shuffle_rows: bool
) -> None:
    """Rows marked `unit_shift` (their blocks from the distinct products), as
    given and in the pairs' order of :meth:`NormalStructure.in_pair_order`,
    give the dense solution, cofactors and redundancy numbers, and the
    general kernel's blocks to rounding."""
    prob = _shift_problem(SHIFT_CASES[case], shuffle_rows=shuffle_rows)
    plain = _shift_problem(SHIFT_CASES[case], shuffle_rows=shuffle_rows, flag=False)
    a, f, _ = dense(prob)
    expected = np.linalg.solve(a.T @ a, -a.T @ f)
    q_dense = np.linalg.inv(a.T @ a)
    st = _structure(prob)
    ordered = st.in_pair_order()
    assert ordered is not None
    st_pairs, places = ordered
    (rows,) = prob.upr
    in_pairs = UnitPointRows(
        rows.unit[places], rows.point[places], rows.unit_jacobian[places],
        rows.point_jacobian[places], rows.residual[places],
        None if rows.weight is None else rows.weight[places], unit_shift=True,
    )
    assert st_pairs.pattern.rows_in_pair_order and not st.pattern.rows_in_pair_order
    general = st.form(plain.upr, prob.ur, prob.pr).unit_blocks
    for structure, upr in ((st, prob.upr), (st_pairs, [in_pairs])):
        formed = structure.form(upr, prob.ur, prob.pr)
        np.testing.assert_allclose(formed.unit_blocks, general, rtol=1e-13, atol=1e-12)
        sol = formed.solve()
        got = np.concatenate([sol.unit_step.ravel(), sol.point_step.ravel()])
        assert np.linalg.norm(got - expected) <= 1e-10 * np.linalg.norm(expected)
        assert sol.cost == pytest.approx(float(f @ f), rel=1e-12)
        cof = sol.cofactors()
        n_d = prob.n * prob.d
        q_units = q_dense[:n_d, :n_d].reshape(prob.n, prob.d, prob.n, prob.d)
        idx = np.arange(prob.n)
        np.testing.assert_allclose(cof.unit, q_units[idx, :, idx, :], rtol=1e-9, atol=1e-12)
        h = cof.redundancy(upr[0])
        plain_h = _structure(plain).solve(plain.upr, prob.ur, prob.pr).cofactors().redundancy(
            plain.upr[0]
        )
        if upr[0] is in_pairs:
            plain_h = plain_h[places]
        np.testing.assert_allclose(h, plain_h, rtol=1e-9, atol=1e-12)


def test_unit_shift_rows_must_have_the_opposite_columns() -> None:
    prob = _shift_problem({}, shuffle_rows=False)
    (rows,) = prob.upr
    au = rows.unit_jacobian.copy()
    au[3, 1, 2] += 1e-9
    bad = UnitPointRows(rows.unit, rows.point, au, rows.point_jacobian, rows.residual,
                        rows.weight, unit_shift=True)
    with pytest.raises(ValueError, match="unit_shift"):
        _structure(prob).form([bad], prob.ur, prob.pr)
    cof = _structure(prob).solve(prob.upr, prob.ur, prob.pr).cofactors()
    with pytest.raises(ValueError, match="unit_shift"):
        cof.redundancy(bad)


def test_group_q_reads_any_block_within_the_band_as_it_stands() -> None:
    """``Q[a, b]`` of groups of units read from the band laid out on both
    sides equals the dense symmetric matrix's blocks to the bit, whichever
    of a, b comes first."""
    from strip_aerotri.geometry._normal_assembly import _both_sides, _group_q

    rng = np.random.default_rng(8)
    n, w, d = 7, 2, 3
    dense = rng.normal(size=(n * d, n * d))
    dense = dense + dense.T
    blocks = dense.reshape(n, d, n, d).transpose(0, 2, 1, 3)  # [a, b] -> Q[a, b]
    band = np.zeros((n, w + 1, d, d))
    for o in range(w + 1):
        band[: n - o, o] = blocks[np.arange(o, n), np.arange(n - o)]  # Q[J + o, J]
    units = np.array([[0, 2, 1], [4, 6, 5], [3, 3, 2]])  # (G, q), all within the band
    a, b = units[:, :, None], units[:, None, :]
    gather = np.minimum(a, b) * (w + 1) + np.abs(a - b)
    got = _group_q(_both_sides(band), gather, a < b)
    expected = blocks[a, b].transpose(0, 1, 3, 2, 4).reshape(3, 3 * d, 3 * d)
    np.testing.assert_array_equal(got, expected)
