"""Relative orientation by the y-parallax equation (method.md §3, J(5)-(10), B(125)-(136))."""

import numpy as np
import pytest

from _synthetic import make_strip
from strip_aerotri.errors import GeometryError
from strip_aerotri.strip import relative as rel_module
from strip_aerotri.strip import relative_iterate as rel_iterate
from strip_aerotri.strip import relative_state
from strip_aerotri.strip.chaining import pair_rows
from strip_aerotri.strip.relative import chain_rotations, essential_start, relative_orientation


def _pairs(syn):
    obs = syn.observations
    model, _, row_l, row_r = pair_rows(obs, np.arange(obs.n_photos))
    vec = obs.image_vectors()
    return vec[row_l], vec[row_r], model, obs.n_photos - 1


def _relative_truth(syn):
    r = syn.rotations
    q = np.swapaxes(r[:-1], 1, 2) @ r[1:]
    b = syn.centres[1:] - syn.centres[:-1]
    return q, b


@pytest.mark.parametrize("method", ["dependent", "base"])
def test_noise_free_converges_quadratically_to_truth(method):
    syn = make_strip(8)
    left, right, pair, n = _pairs(syn)
    res = relative_orientation(
        left, right, pair, n, method=method, rotation_first=syn.rotations[0]
    )
    # converged: the next corrections are below the tolerance, 1e-11 (rad and
    # base units), i.e. y-parallaxes below about 1e-11 × c = 1.5e-9 mm
    assert res.history[-1] < 1e-6
    assert np.all(res.max_parallax_um < 1e-6)
    # quadratic: q_{k+1} / q_k^2 is one constant (measured 5e-5 to 1.2e-4)
    # while the digits double; a linear rate r would make it grow as r / q_k
    h = res.history
    ratios = np.array(
        [h[k + 1] / h[k] ** 2 for k in range(len(h) - 1) if 1e-12 < h[k + 1] and h[k] < 1e3]
    )
    assert ratios.size >= 3, h
    assert ratios.max() < 1e-3 and ratios.max() < 10 * ratios.min(), (h, ratios)
    q_true, b_true = _relative_truth(syn)
    np.testing.assert_allclose(res.relative_rotation, q_true, atol=1e-10)
    b_dir = res.base / np.linalg.norm(res.base, axis=1, keepdims=True)
    b_true_dir = b_true / np.linalg.norm(b_true, axis=1, keepdims=True)
    np.testing.assert_allclose(b_dir, b_true_dir, atol=1e-10)
    np.testing.assert_allclose(res.rotation_left[1:], res.rotation_right[:-1], atol=1e-15)
    assert res.iterations.max() <= 8


def test_both_formulations_agree_on_noise_free_data():
    syn = make_strip(10, seed=4)
    left, right, pair, n = _pairs(syn)
    dep = relative_orientation(left, right, pair, n, method="dependent")
    base = relative_orientation(left, right, pair, n, method="base")
    np.testing.assert_allclose(dep.rotation_right, base.rotation_right, atol=1e-9)
    np.testing.assert_allclose(dep.base, base.base, atol=1e-9)


def test_both_formulations_agree_within_noise():
    syn = make_strip(10, seed=5, noise_mm=0.005)
    left, right, pair, n = _pairs(syn)
    dep = relative_orientation(left, right, pair, n, method="dependent")
    base = relative_orientation(left, right, pair, n, method="base")
    # relative rotation angles differ by far less than their precision (~1e-4 rad)
    diff = np.swapaxes(dep.relative_rotation, 1, 2) @ base.relative_rotation
    angle = np.arccos(np.clip((np.trace(diff, axis1=1, axis2=2) - 1) / 2, -1, 1))
    assert angle.max() < 2e-5
    np.testing.assert_allclose(dep.sigma0_um, base.sigma0_um, rtol=0.02)


def test_sigma0_recovers_image_noise():
    """With 5 µm noise on every coordinate σ0 of one image coordinate comes out near 5 µm."""
    sig = []
    for seed in range(4):
        syn = make_strip(12, seed=seed, noise_mm=0.005)
        left, right, pair, n = _pairs(syn)
        res = relative_orientation(left, right, pair, n, sigma_left=0.005, sigma_right=0.005)
        sig.append(res.sigma0_um)
        # the RMS y-parallax combines two coordinates
        np.testing.assert_allclose(res.rms_parallax_um.mean(), np.sqrt(2) * 5, rtol=0.2)
    pooled = np.sqrt(np.mean(np.square(np.concatenate(sig))))
    assert 4.5 < pooled < 5.5, pooled


def _first_pass_history(syn, factor, monkeypatch, iterations=30):
    """Max |q| (µm) per Gauss-Newton step from the near-vertical start."""
    left, right, pair, n = _pairs(syn)
    monkeypatch.setattr(relative_state, "_SCHUT_FACTOR", factor)
    state = rel_module._DependentState(n, np.eye(3))
    starts = rel_module._segment_starts(pair, n)
    counts = np.bincount(pair, minlength=n)
    blocks = rel_iterate._Blocks(left.T.copy(), right.T.copy(), starts, counts, np.arange(n))
    history = []
    for _ in range(iterations + 1):
        ev = rel_iterate._evaluate(state, blocks, np.ones(pair.size))
        history.append(1000.0 * ev.max_parallax_mm.max())
        corr, *_ = rel_iterate._solve_normals(ev.normal, ev.gradient)
        state.update(corr)
    return np.array(history)


@pytest.mark.parametrize("attitude_sd_deg", [0.1, 1.5])
def test_printed_schut_factor_converges_only_linearly(monkeypatch, attitude_sd_deg):
    """J(9) as printed takes the Schut parameters equal to the rotation vector
    a, not a/2: the rotation part of every step is doubled, the error changes
    sign each step and shrinks by a factor close to 1 (linear, oscillating),
    while the fixed form converges quadratically."""
    syn = make_strip(3, seed=2, attitude_sd_deg=attitude_sd_deg)
    fixed = _first_pass_history(syn, 0.5, monkeypatch)
    printed = _first_pass_history(syn, 1.0, monkeypatch)
    assert fixed[6] < 1e-6
    assert printed[30] > 100.0  # still hundreds of µm after 30 steps
    assert printed[30] < printed[0]  # it does creep towards the solution


@pytest.mark.parametrize("method", ["dependent", "base"])
def test_large_relative_rotations_converge(method):
    """Drone-like pairs: relative rotations of tens of degrees."""
    for seed in range(6):
        syn = make_strip(
            5, seed=seed, relative_rotation_deg=25.0, c=100.0, height=800.0, base=300.0
        )
        left, right, pair, n = _pairs(syn)
        res = relative_orientation(
            left, right, pair, n, method=method, rotation_first=syn.rotations[0]
        )
        q_true, _ = _relative_truth(syn)
        np.testing.assert_allclose(res.relative_rotation, q_true, atol=1e-9)


def test_essential_start_is_close_to_truth():
    syn = make_strip(5, seed=3, relative_rotation_deg=20.0, c=100.0, height=800.0, base=300.0)
    left, right, pair, n = _pairs(syn)
    q, b = essential_start(left, right, pair, n)
    q_true, b_true = _relative_truth(syn)
    b_true_left = np.einsum("mji,mj->mi", syn.rotations[:-1], b_true)
    b_true_left /= np.linalg.norm(b_true_left, axis=1, keepdims=True)
    np.testing.assert_allclose(q, q_true, atol=1e-8)
    np.testing.assert_allclose(b, b_true_left, atol=1e-8)


def test_weights_reduce_the_influence_of_a_poor_observation():
    syn = make_strip(3, seed=7)
    left, right, pair, n = _pairs(syn)
    right = right.copy()
    right[3, 1] += 0.05  # 50 µm off in y
    sigma = np.full(pair.shape, 0.005)
    equal = relative_orientation(left, right, pair, n, sigma_right=sigma)
    sigma[3] = 0.5
    weighted = relative_orientation(left, right, pair, n, sigma_right=sigma)
    q_true, _ = _relative_truth(syn)

    def err(res):
        return np.abs(res.relative_rotation - q_true).max()

    assert err(weighted) < 0.05 * err(equal)


def test_too_few_points_names_the_pair():
    syn = make_strip(3)
    left, right, pair, n = _pairs(syn)
    keep = (pair == 0) | (np.arange(pair.size) < np.searchsorted(pair, 1) + 4)
    with pytest.raises(GeometryError, match=r"pair B: 4 point\(s\).*at least 5"):
        relative_orientation(left[keep], right[keep], pair[keep], n, labels=["pair A", "pair B"])


def test_collinear_points_are_degenerate():
    rng = np.random.default_rng(0)
    t = rng.uniform(-50, 50, 8)
    left = np.column_stack([t, 0.5 * t, np.full(8, -152.0)])
    right = left + np.array([-90.0, 0.0, 0.0])
    with pytest.raises(GeometryError, match="do not determine the relative orientation"):
        relative_orientation(left, right, np.zeros(8, int), 1, labels=["pair 1-2"])


def test_chain_rotations_composes_in_order():
    rng = np.random.default_rng(3)
    from scipy.spatial.transform import Rotation

    rel = Rotation.random(4, random_state=rng).as_matrix()
    first = Rotation.random(random_state=rng).as_matrix()
    chain = chain_rotations(first, rel)
    np.testing.assert_allclose(chain[3], first @ rel[0] @ rel[1] @ rel[2], atol=1e-14)


def test_batched_normal_solve_agrees_with_lapack_and_flags_singular_matrices():
    rng = np.random.default_rng(11)
    design = rng.normal(size=(60, 40, 5)) * np.array([1.0, 1.0, 30.0, 30.0, 1e3])
    normal = np.swapaxes(design, 1, 2) @ design
    gradient = rng.normal(size=(60, 5))
    # singular: no rows, a zero column, a rank-deficient design, NaN
    normal[3] = 0.0
    normal[5, 2, :] = normal[5, :, 2] = 0.0
    tied = design[9].copy()
    tied[:, 4] = 2.0 * tied[:, 3] + 1e-12 * rng.normal(size=40)
    normal[9] = tied.T @ tied
    normal[12, 0, 0] = np.nan
    corr, singular, inverse = rel_iterate._solve_normals(normal, gradient)
    bad = [3, 5, 9, 12]
    assert np.flatnonzero(singular).tolist() == bad
    assert np.all(corr[bad] == 0.0)
    good = np.setdiff1d(np.arange(60), bad)
    expected_inverse = np.linalg.inv(normal[good])
    np.testing.assert_allclose(inverse[good], expected_inverse, rtol=1e-9, atol=0)
    np.testing.assert_allclose(
        corr[good], np.linalg.solve(normal[good], gradient[good][:, :, None])[:, :, 0], rtol=1e-9
    )


def test_rays_of_any_length_give_the_same_orientation():
    """The y-parallax equation is homogeneous in each ray, so image vectors
    scaled row by row (their z no longer the one constant -c, which the
    blocks otherwise keep as a number) give the same orientation."""
    syn = make_strip(8, seed=3, noise_mm=0.005)
    left, right, pair, n = _pairs(syn)
    rng = np.random.default_rng(0)
    ref = relative_orientation(left, right, pair, n)
    scaled = relative_orientation(
        left * rng.uniform(0.5, 2.0, (left.shape[0], 1)),
        right * rng.uniform(0.5, 2.0, (left.shape[0], 1)),
        pair,
        n,
    )
    np.testing.assert_allclose(scaled.elements, ref.elements, rtol=0, atol=1e-9)
    np.testing.assert_allclose(scaled.relative_rotation, ref.relative_rotation, atol=1e-9)
