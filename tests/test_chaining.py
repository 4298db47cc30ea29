"""Strip formation on the package's simulator (method.md §1-5, J §2.1, B(125)-(141)).

Acceptance tests of :func:`strip_aerotri.strip.chaining.form_strip`: the strip model
of a noise-free simulated strip is the truth up to one 3D similarity for every
combination of the formulations, the strip system is defined as J or B say,
points are averaged over their models, failures name the photos, and random
errors grow with the strip length as the theory of the random walk of the
scale and rotation transfer expects (see docs/strip-formation.md).
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from strip_aerotri.errors import GeometryError
from strip_aerotri.observations import ImageObservations
from strip_aerotri.simulate import simulate_strip
from strip_aerotri.strip import relative as rel_module
from strip_aerotri.strip import relative_iterate as rel_iterate
from strip_aerotri.strip.chaining import StripOptions, form_strip, pair_rows, tie_rows

# ----------------------------------------------------------------------------
# helpers


def similarity(source: np.ndarray, target: np.ndarray):
    """Least-squares 3D similarity source -> target (Umeyama 1991, IEEE PAMI 13(4)).

    Returns (scale, rotation (3, 3), translation (3,)) with
    ``target ≈ scale * source @ rotation.T + translation``.
    """
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    a, b = source - cs, target - ct
    u, s, vt = np.linalg.svd(b.T @ a)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    rotation = u @ d @ vt
    scale = np.trace(np.diag(s) @ d) / np.sum(a * a)
    return scale, rotation, ct - scale * cs @ rotation.T


def strip_vs_truth(strip, sim, *, centres: bool = True):
    """Similarity of the strip's points (and centres) onto the truth, and the residuals (m)."""
    ok = strip.triangulated
    source, target = strip.points[ok], sim.truth.points_local[ok]
    if centres:
        source = np.vstack([source, strip.centres])
        target = np.vstack([target, sim.truth.photo_centres_local[strip.photo_index]])
    scale, rotation, shift = similarity(source, target)
    resid = scale * source @ rotation.T + shift - target
    return scale, rotation, resid, target


def drop_observations(obs: ImageObservations, drop: np.ndarray) -> ImageObservations:
    """The same observations without the rows where ``drop`` is True."""
    keep = ~np.asarray(drop, dtype=bool)
    return dataclasses.replace(
        obs,
        photo=obs.photo[keep],
        point=obs.point[keep],
        xy=obs.xy[keep],
        sigma=obs.sigma[keep],
        source_line=obs.source_line[keep] if obs.source_line.size else obs.source_line,
    )


def photos_seeing(obs: ImageObservations) -> np.ndarray:
    """Boolean (n_photos, n_points): which photo sees which point."""
    seen = np.zeros((obs.n_photos, obs.n_points), dtype=bool)
    seen[obs.photo, obs.point] = True
    return seen


COMBINATIONS = list(
    itertools.product(["dependent", "base"], ["midpoint", "normal"], ["z", "distance"])
)
COMBINATION_IDS = ["-".join(c) for c in COMBINATIONS]

# Noise-free strips: film 1:8000 (5 and 50 photos), a strip flown at 200°
# (south-south-west: an absolute heading near 180° that Schut's parameters
# could not represent), and the drone preset (relative rotations of degrees,
# 80 % overlap, c = 8.8 mm).
STRIPS = {
    "film5": {"n_photos": 5, "seed": 11},
    "film50": {"n_photos": 50, "seed": 12},
    "heading200": {"n_photos": 9, "seed": 13, "heading_deg": 200.0},
    "drone": {"n_photos": 12, "seed": 14, "preset": "drone"},
}
_CACHE: dict[str, object] = {}


def noise_free(name: str):
    if name not in _CACHE:
        _CACHE[name] = simulate_strip(image_noise_mm=0.0, **STRIPS[name])
    return _CACHE[name]


# ----------------------------------------------------------------------------
# noise-free strips equal the truth up to one similarity


@pytest.mark.parametrize("strip_name", list(STRIPS))
@pytest.mark.parametrize(
    ("ro", "intersection", "scale_transfer"), COMBINATIONS, ids=COMBINATION_IDS
)
def test_noise_free_strip_is_the_truth_up_to_a_similarity(
    strip_name, ro, intersection, scale_transfer
):
    sim = noise_free(strip_name)
    options = StripOptions(
        relative_orientation=ro, intersection=intersection, scale_transfer=scale_transfer
    )
    strip = form_strip(sim.observations, options)
    assert strip.triangulated.all()  # the simulator keeps points seen on two photos
    scale, rotation, resid, target = strip_vs_truth(strip, sim)
    extent = np.ptp(target, axis=0).max()
    assert np.abs(resid).max() / extent < 1e-9, np.abs(resid).max() / extent
    # photo rotations: image -> truth = similarity rotation @ (image -> strip)
    mapped = rotation @ strip.rotations
    np.testing.assert_allclose(
        mapped, sim.truth.photo_rotations_local[strip.photo_index], atol=1e-9
    )
    # the default strip system is J's: its first base has b_x = 1
    assert scale == pytest.approx(
        np.linalg.norm(np.diff(sim.truth.photo_centres_local[:2], axis=0))
        / np.linalg.norm(strip.centres[1] - strip.centres[0]),
        rel=1e-9,
    )


@pytest.mark.parametrize("method", ["dependent", "base"])
def test_relative_orientation_converges_quadratically_on_the_simulator(method):
    """Largest y-parallax of all pairs per Gauss-Newton iteration (µm at image scale).

    Noise-free film strip of 50 photos from the near-vertical start: the
    number of correct digits roughly doubles per iteration (J(7), J(9) fixed).
    """
    sim = noise_free("film50")
    strip = form_strip(sim.observations, StripOptions(relative_orientation=method))
    h = strip.relative.history
    assert h[0] > 100.0  # tilts of 1.5° leave hundreds of µm of y-parallax at the start
    assert h[-1] < 1e-6
    assert len(h) <= 7
    # quadratic: from 1e3 µm down, each step squares the relative error
    scale = h[0]
    for before, after in itertools.pairwise(h / scale):
        if after > 1e-12:
            assert after < 10.0 * before**2, h


# ----------------------------------------------------------------------------
# the formulations agree within the noise


def test_formulations_agree_within_the_noise():
    """Both relative orientations × both intersections on one 5 µm strip.

    Bound: the points of any two of the four combinations differ (RMS, 3D) by
    less than a quarter of their RMS error against the truth after a
    similarity, and by less than the image noise at image scale (5 µm × 8000
    = 4 cm).  Measured on seeds 1-3: 0.05-0.20 of the error against
    the truth (0.11-0.23 m), 0.8-2.1 cm.
    """
    sim = simulate_strip(12, image_noise_mm=0.005, seed=2)
    strips = {
        (ro, it): form_strip(
            sim.observations, StripOptions(relative_orientation=ro, intersection=it)
        )
        for ro, it in itertools.product(["dependent", "base"], ["midpoint", "normal"])
    }
    reference = strips["dependent", "midpoint"]
    scale, _, resid, _ = strip_vs_truth(reference, sim)
    rmse_truth = np.sqrt(np.mean(np.sum(resid**2, axis=1)))
    assert 0.05 < rmse_truth < 1.0  # sanity: the noise shows
    ok = reference.triangulated
    ground_per_image_mm = sim.preset.scale_m_per_mm
    for a, b in itertools.combinations(strips, 2):
        both = ok & strips[a].triangulated & strips[b].triangulated
        diff = scale * (strips[a].points[both] - strips[b].points[both])
        rms = np.sqrt(np.mean(np.sum(diff**2, axis=1)))
        assert rms < 0.25 * rmse_truth, (a, b, rms, rmse_truth)
        assert rms < 0.005 * ground_per_image_mm, (a, b, rms)
    # the relative orientation does not depend on the intersection formula
    for ro in ("dependent", "base"):
        np.testing.assert_array_equal(
            strips[ro, "midpoint"].rotations, strips[ro, "normal"].rotations
        )


# ----------------------------------------------------------------------------
# strip system definition (J default, B given)


def test_default_strip_system_is_janiszewskis():
    """J §2.1: s_1 = 0, R_1 = I, the first base has b_x = 1."""
    sim = simulate_strip(6, image_noise_mm=0.005, seed=3)
    for ro in ("dependent", "base"):
        strip = form_strip(sim.observations, StripOptions(relative_orientation=ro))
        np.testing.assert_array_equal(strip.centres[0], np.zeros(3))
        np.testing.assert_allclose(strip.rotations[0], np.eye(3), atol=1e-15)
        assert strip.centres[1, 0] - strip.centres[0, 0] == pytest.approx(1.0, abs=1e-14)
        assert strip.scale[0] == 1.0


@pytest.mark.parametrize("ro", ["dependent", "base"])
@pytest.mark.parametrize(
    "heading_deg",
    [
        75.0,
        200.0,
        0.0,
    ],
)
def test_given_first_orientation_and_base_length_are_honoured(ro, heading_deg):
    """B: an arbitrary first exterior orientation and base length.

    Given the true first rotation and centre (local east-north-up frame) and
    the true length of the first base (B's base length, the documented meaning
    of ``first_base_length``), the noise-free strip model is the truth itself,
    without any similarity.  At heading 75° the flight runs towards +X
    (east-north-east); at 200° towards -X, at 0° along +Y.
    """
    sim = simulate_strip(6, image_noise_mm=0.0, seed=13, heading_deg=heading_deg)
    truth_c = sim.truth.photo_centres_local
    options = StripOptions(
        relative_orientation=ro,
        first_rotation=np.array(sim.truth.photo_rotations_local[0]),
        first_position=np.array(truth_c[0]),
        first_base_length=float(np.linalg.norm(truth_c[1] - truth_c[0])),
    )
    strip = form_strip(sim.observations, options)
    np.testing.assert_array_equal(strip.centres[0], truth_c[0])
    np.testing.assert_array_equal(strip.rotations[0], sim.truth.photo_rotations_local[0])
    extent = np.ptp(truth_c, axis=0).max()
    assert np.abs(strip.centres - truth_c).max() < 1e-9 * extent
    assert np.abs(strip.points - sim.truth.points_local).max() < 1e-9 * extent
    np.testing.assert_allclose(strip.rotations, sim.truth.photo_rotations_local, atol=1e-9)
    assert np.linalg.norm(strip.centres[1] - strip.centres[0]) == pytest.approx(
        options.first_base_length, rel=1e-12
    )


def test_bad_first_base_length_is_refused():
    with pytest.raises(ValueError, match="first_base_length"):
        StripOptions(first_base_length=0.0)


# ----------------------------------------------------------------------------
# averaging and tie points


def test_points_are_the_mean_of_their_determinations():
    sim = simulate_strip(8, image_noise_mm=0.005, seed=4)
    obs = sim.observations
    strip = form_strip(obs)
    seen = photos_seeing(obs)
    # a point is determined in model m when photos m and m + 1 both see it
    expected_n = np.sum(seen[:-1] & seen[1:], axis=0)
    np.testing.assert_array_equal(strip.n_determinations, expected_n)
    assert expected_n.max() == 2  # 60 % overlap: at most three photos, two models
    assert (expected_n == 2).sum() > 20
    for p in np.flatnonzero(expected_n >= 1):
        rows = strip.model_point == p
        np.testing.assert_allclose(
            strip.points[p], strip.model_points[rows].mean(axis=0), rtol=0, atol=1e-13
        )
    # with noise the two determinations differ, so the mean is not either of them
    two = np.flatnonzero(expected_n == 2)
    first = np.array([strip.model_points[strip.model_point == p][0] for p in two])
    assert np.all(np.abs(strip.points[two] - first).max(axis=1) > 0)


def test_tie_points_are_the_triple_overlap():
    sim = noise_free("film5")
    strip = form_strip(sim.observations)
    seen = photos_seeing(sim.observations)
    triple = seen[:-2] & seen[1:-1] & seen[2:]  # (n_models - 1, P)
    np.testing.assert_array_equal(strip.tie_count[1:], triple.sum(axis=1))
    assert strip.tie_count[0] == 0
    assert np.all(strip.tie_count[1:] >= 1)
    assert np.all(np.isnan(strip.tie_rms[0]))


@pytest.mark.parametrize("first", [0, 3])
def test_tie_rows_are_the_points_of_the_model_before(first):
    # a sequence of some of the photos too, and rows left out as by a rejection
    sim = noise_free("film50")
    obs = sim.observations
    seq = np.arange(first, obs.n_photos)
    model, point, row_l, row_r = pair_rows(obs, seq)
    kept = np.random.default_rng(1).random(model.shape[0]) > 0.1
    model, point, row_l, row_r = model[kept], point[kept], row_l[kept], row_r[kept]
    i_now, i_prev = tie_rows(row_l, row_r, obs.photo.shape[0])
    # by definition: the rows whose (model - 1, point) is a row too
    rows_of = {(int(m), int(p)): r for r, (m, p) in enumerate(zip(model, point, strict=True))}
    expected = [(r, rows_of[m - 1, p]) for (m, p), r in rows_of.items() if (m - 1, p) in rows_of]
    assert len(expected) > 100
    np.testing.assert_array_equal(np.column_stack([i_now, i_prev]), sorted(expected))


def test_tie_differences_vanish_noise_free():
    sim = noise_free("film50")
    strip = form_strip(sim.observations)
    extent = np.ptp(strip.points, axis=0).max()
    assert strip.tie_count[1:].min() >= 1
    assert np.abs(strip.tie_difference).max() < 1e-11 * extent


def test_tie_differences_have_the_expected_size_with_noise():
    """Tie differences (model m minus model m-1) with 5 and 10 µm image noise.

    Expected height difference: a model height has σ_Z ≈ (H/B) · m_b · σ_px
    with σ_px = √2 · σ the x-parallax noise (H = 1223 m, B = 736 m, m_b =
    8000): 0.094 m for σ = 5 µm; two models differ by about √2 of that,
    0.133 m.  X is much smaller (the common ray of the shared photo carries
    both determinations near its nadir).  First-order error propagation:
    doubling the noise (same random draws) doubles the differences.
    """
    pre = simulate_strip(2).preset
    h_over_b = pre.flying_height_m / pre.base_m
    rms = {}
    for noise in (0.005, 0.010):
        sim = simulate_strip(12, image_noise_mm=noise, seed=5)
        strip = form_strip(sim.observations)
        scale, _, _, _ = strip_vs_truth(strip, sim)
        rms[noise] = np.sqrt(np.mean((scale * strip.tie_difference) ** 2, axis=0))
    expected_z = np.sqrt(2.0) * h_over_b * pre.scale_m_per_mm * np.sqrt(2.0) * 0.005
    assert 0.5 * expected_z < rms[0.005][2] < 2.0 * expected_z, (rms[0.005], expected_z)
    assert rms[0.005][0] < 0.5 * rms[0.005][2]
    np.testing.assert_allclose(rms[0.010] / rms[0.005], 2.0, rtol=0.02)


# ----------------------------------------------------------------------------
# errors name the photos


def test_model_without_tie_points_names_the_photos():
    """Delete the observations of the triple-overlap points (1002, 1003, 1004) on 1004."""
    sim = noise_free("film5")
    obs = sim.observations
    seen = photos_seeing(obs)
    triple = np.flatnonzero(seen[1] & seen[2] & seen[3])
    assert triple.size >= 5
    drop = (obs.photo == 3) & np.isin(obs.point, triple)
    with pytest.raises(
        GeometryError, match=r"pair 1003-1004 shares no tie point.*1002, 1003, 1004"
    ):
        form_strip(drop_observations(obs, drop))


def test_pair_with_fewer_than_five_points_names_the_pair():
    sim = noise_free("film5")
    obs = sim.observations
    seen = photos_seeing(obs)
    common = np.flatnonzero(seen[2] & seen[3])
    drop = (obs.photo == 3) & np.isin(obs.point, common[4:])
    with pytest.raises(
        GeometryError, match=r"pair 1003-1004: 4 point\(s\) measured on both photos.*at least 5"
    ):
        form_strip(drop_observations(obs, drop))


def test_single_photo_is_refused():
    sim = noise_free("film5")
    with pytest.raises(GeometryError, match="at least two photos"):
        form_strip(sim.observations, photo_index=[2])


# ----------------------------------------------------------------------------
# J(7) fixed: the linearisation is the derivative of J(5)


def test_j7_fixed_linearisation_is_the_derivative_of_j5():
    """The design rows of the dependent relative orientation against central
    differences of J(5), q = b·(l × p)/(j·(l × p)), at a state with q0 ≠ 0.

    The printed J(7) ``[p0/D × (b0 × l) − q0 (j × l)]·a`` differs from the
    derivative wherever q0 ≠ 0 (it lost the ``p0 ×`` and the ``/D`` of the
    q0 term): it would converge to another point than the least-squares
    minimum of J(6) on noisy data.
    """
    sim = simulate_strip(3, image_noise_mm=0.005, seed=6)
    obs = sim.observations
    model, _, row_l, row_r = pair_rows(obs, np.arange(obs.n_photos))
    vec = obs.image_vectors()
    # a first rotation off the identity (heading 75°): strip and image axes differ
    first = Rotation.from_euler("z", 75.0, degrees=True).as_matrix()
    left, right = vec[row_l], vec[row_r]
    state = rel_module._DependentState(2, first)
    # The state holds the unknowns in the left photo's image frame; the design
    # rows are the derivatives with respect to base steps along the left
    # image's y and z axes and a small rotation a of the right bundle given in
    # the left image frame.
    counts = np.bincount(model, minlength=2)
    starts = rel_module._segment_starts(model, 2)
    blocks = rel_iterate._Blocks(left.T.copy(), right.T.copy(), starts, counts, np.arange(2))
    rows = np.empty((model.size, 5))
    q0 = np.empty(model.size)
    for block in blocks.items:
        m = np.empty((block.rows.shape[0], 6, block.rows.shape[1]))
        state.terms(block.pairs, block, m)
        rows[block.rows[block.valid]] = np.moveaxis(m[:, :5], 1, 2)[block.valid]
        q0[block.rows[block.valid]] = m[:, 5][block.valid]
    assert np.abs(q0).max() > 1e-4  # start state: large y-parallaxes

    # J(5) evaluated independently in the strip frame, with the y-parallax
    # along the left photo's image y axis (J's strip y for R_l = I)
    r_left, r_right, _ = state.rotations()
    r_left, r_right = r_left[model], r_right[model]
    b = state.base_strip(state.rotations()[0])[model]
    l = np.einsum("nij,nj->ni", r_left, left)
    p0 = np.einsum("nij,nj->ni", r_right, right)
    j = r_left[:, :, 1]

    def parallax(b_, p_):
        lxp = np.cross(l, p_)
        return np.einsum("ij,ij->i", b_, lxp) / np.einsum("ij,ij->i", j, lxp)

    np.testing.assert_allclose(q0, parallax(b, p0), rtol=1e-12, atol=1e-15)
    eps = 1e-7
    numeric = np.empty_like(rows)
    for k in range(2):  # base corrections along the left photo's image y and z axes
        step = eps * r_left[:, :, k + 1]
        numeric[:, k] = (parallax(b + step, p0) - parallax(b - step, p0)) / (2 * eps)
    for k in range(3):  # small rotation a (left image frame) of the right bundle
        a = eps * r_left[:, :, k]  # the same rotation in the strip frame
        numeric[:, 2 + k] = (
            parallax(b, p0 + np.cross(a, p0)) - parallax(b, p0 - np.cross(a, p0))
        ) / (2 * eps)
    np.testing.assert_allclose(rows, numeric, rtol=1e-6, atol=1e-9 * np.abs(numeric).max())

    d = np.cross(l, p0)[:, 1]
    printed = np.cross(p0, np.cross(b, l)) / d[:, None] - q0[:, None] * np.cross(j, l)
    error = np.abs(printed - numeric[:, 2:]).max() / np.abs(numeric[:, 2:]).max()
    assert error > 1e-3, error


# ----------------------------------------------------------------------------
# random errors grow with the strip length like n^(3/2)


def _free_exponent(n: np.ndarray, e2: np.ndarray) -> float:
    """γ of e² = a² + b² n^γ fitted to log e² (least squares)."""

    def resid(p):
        return np.log(np.exp(p[0]) + np.exp(p[1]) * n ** p[2]) - np.log(e2)

    return float(
        least_squares(resid, [np.log(e2[0]), np.log(e2[-1]) - 3 * np.log(n[-1]), 3.0]).x[2]
    )


def test_random_errors_grow_like_n_to_the_three_halves():
    """5 µm image noise, film strips of 6, 12, 24, 48 photos, 16 strips each.

    Theory (docs/strip-formation.md): the random errors of the scale and
    rotation transfer accumulate as a random walk from model to model; after
    a best-fit similarity the position error grows like n^(3/2), plus a
    constant from the single-model noise: e(n)² = a² + b² n³.

    Measured with examples/accuracy_vs_length.py (100 strips per length,
    n = 6..100): γ = 2.91 (bootstrap 95 %: 2.83-3.02).  With 16 strips per
    length at these four lengths, γ over ten seed sets was 2.65-3.16 and
    e(48)/e(12) was 6.0-7.5, so the band 2.3 < γ < 3.7 is about ±4 standard
    deviations of γ around 3, and e(48)/e(12) > 4.5 excludes a linear growth
    (4) as well as the n^(1/2) of a random walk of positions (2).
    """
    lengths = np.array([6, 12, 24, 48])
    replicas = 16
    e2 = np.empty(lengths.size)
    for i, n in enumerate(lengths):
        sq = []
        for r in range(replicas):
            sim = simulate_strip(int(n), image_noise_mm=0.005, seed=7000 + 100 * i + r)
            strip = form_strip(sim.observations)
            _, _, resid, _ = strip_vs_truth(strip, sim, centres=False)
            sq.append(np.mean(np.sum(resid**2, axis=1)))
        e2[i] = np.mean(sq)
    e = np.sqrt(e2)
    assert np.all(np.diff(e) > 0), e
    assert e[3] / e[1] > 4.5, e
    gamma = _free_exponent(lengths.astype(float), e2)
    assert 2.3 < gamma < 3.7, (gamma, e)


@pytest.mark.parametrize("chunk", [None, 5])
@pytest.mark.parametrize("seed", range(6))
def test_pair_rows_finds_every_common_point_in_any_row_order(seed, chunk, monkeypatch):
    # Reference by sets over the photos; rows shuffled, photo sequences that
    # skip, reverse or take part of the photos, point indices renumbered at
    # random (ids that do not follow the flight), and the binary search over
    # many chunks of rows.
    from strip_aerotri.strip import chaining

    if chunk is not None:
        monkeypatch.setattr(chaining, "_CHUNK_ROWS", chunk)
    rng = np.random.default_rng(seed)
    obs = simulate_strip(7, seed=seed).observations
    perm = rng.permutation(obs.photo.size) if seed % 2 else np.arange(obs.photo.size)
    renumber = rng.permutation(obs.n_points) if seed % 3 else np.arange(obs.n_points)
    obs = dataclasses.replace(
        obs,
        photo=obs.photo[perm],
        point=renumber[obs.point[perm]],
        xy=obs.xy[perm],
        sigma=obs.sigma[perm],
        source_line=obs.source_line[perm],
    )
    seq = [np.arange(7), np.arange(7)[::-1], np.array([0, 2, 3, 5]), np.array([6, 4, 1])][seed % 4]
    pairs_of_rows = enumerate(zip(obs.photo, obs.point, strict=True))
    rows_of = {(int(ph), int(pt)): r for r, (ph, pt) in pairs_of_rows}
    expected = [
        (m, pt, rows_of[(seq[m], pt)], rows_of[(seq[m + 1], pt)])
        for m in range(len(seq) - 1)
        for pt in sorted(
            {p for (ph, p) in rows_of if ph == seq[m]}
            & {p for (ph, p) in rows_of if ph == seq[m + 1]}
        )
    ]
    got = np.column_stack(pair_rows(obs, seq.astype(np.intp)))
    np.testing.assert_array_equal(got, np.array(expected).reshape(-1, 4))


def test_rotate_rows_matches_a_stack_of_matrices_across_chunks() -> None:
    """_rotate_rows works in chunks of rows: over several chunks, with an
    unsorted matrix index and a partial last chunk, it equals the (n, 3, 3) stack."""
    from strip_aerotri.strip import chaining

    rng = np.random.default_rng(5)
    matrices = Rotation.random(7, random_state=6).as_matrix()
    n = 2 * chaining._CHUNK_ROWS + 123
    index = rng.integers(0, 7, n)
    vectors = rng.normal(size=(n, 3))
    expected = np.einsum("nij,nj->ni", matrices[index], vectors)
    got = chaining._rotate_rows(matrices, index, vectors)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)
    assert got.flags.c_contiguous and got.shape == (n, 3)
