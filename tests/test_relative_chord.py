"""The chord check that confirms the convergence of the relative orientation
(relative_iterate._chord): once a step is small, the y-parallaxes at the new state
with the previous design rows decide whether the pairs have converged,
instead of a full evaluation."""

import numpy as np
import pytest

from _synthetic import make_strip
from strip_aerotri.strip import relative as rel_module
from strip_aerotri.strip import relative_iterate as rel_iterate
from strip_aerotri.strip.chaining import pair_rows
from strip_aerotri.strip.relative import relative_orientation


def _pairs(syn):
    obs = syn.observations
    model, _, row_l, row_r = pair_rows(obs, np.arange(obs.n_photos))
    vec = obs.image_vectors()
    return vec[row_l], vec[row_r], model, obs.n_photos - 1


def _run(monkeypatch, syn, *, chord: bool, method: str = "dependent"):
    """The orientation, the number of chord checks and of rows evaluated in full."""
    calls = {"chord": 0, "rows": 0}
    evaluate, real_chord = rel_iterate._evaluate, rel_iterate._chord

    def counting_evaluate(state, blocks, weight, robust=False):
        calls["rows"] += blocks.n_rows
        return evaluate(state, blocks, weight, robust)

    def counting_chord(state, ev, weight, n_inv):
        calls["chord"] += 1
        out, corr = real_chord(state, ev, weight, n_inv)
        # without the chord: a correction that is never negligible, so every
        # pair goes on to the full evaluation as before
        return out, corr if chord else np.full_like(corr, np.nan)

    monkeypatch.setattr(rel_iterate, "_evaluate", counting_evaluate)
    monkeypatch.setattr(rel_iterate, "_chord", counting_chord)
    left, right, pair, n = _pairs(syn)
    res = relative_orientation(left, right, pair, n, method=method)
    monkeypatch.undo()
    return res, calls


@pytest.mark.parametrize("method", ["dependent", "base"])
@pytest.mark.parametrize("subsample", [False, True])
def test_chord_confirms_the_least_squares_solution(monkeypatch, method, subsample):
    """With 5 µm noise the chord check replaces the last full evaluation: the
    orientation and the residuals are those of the full evaluations, the
    redundancy numbers differ by the size of the last step (relative)."""
    syn = make_strip(12, seed=7, noise_mm=0.005)
    if subsample:  # the first steps on every 8th point, as for pairs of hundreds of points
        monkeypatch.setattr(rel_module, "_SUBSAMPLE_POINTS", 8)
    with_chord, c1 = _run(monkeypatch, syn, chord=True, method=method)
    if subsample:
        monkeypatch.setattr(rel_module, "_SUBSAMPLE_POINTS", 8)
    full, c0 = _run(monkeypatch, syn, chord=False, method=method)
    assert c1["chord"] >= 1
    assert c1["rows"] < c0["rows"]  # the chord saved full evaluations
    # the same state: a pair the chord accepts takes no further step, nor does
    # it after the full evaluation that finds the same correction negligible
    # (measured: equal to the last digit; redundancy numbers 0.5-1.2e-4 apart)
    np.testing.assert_allclose(with_chord.elements, full.elements, rtol=0, atol=1e-12)
    np.testing.assert_allclose(with_chord.parallax_um, full.parallax_um, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        with_chord.redundancy_numbers, full.redundancy_numbers, rtol=0, atol=5e-4
    )
    assert not np.array_equal(with_chord.redundancy_numbers, full.redundancy_numbers)
    # least squares: the redundancy numbers of a pair add up to n − 5 (the
    # trace of the hat matrix), also with the design of the previous step
    starts = np.flatnonzero(np.r_[True, np.diff(with_chord.pair) > 0])
    for res in (with_chord, full):
        sums = np.add.reduceat(res.redundancy_numbers, starts)
        np.testing.assert_allclose(sums, res.n_points - 5, rtol=1e-9)
    np.testing.assert_allclose(with_chord.sigma0_um, full.sigma0_um, rtol=1e-12)


def test_no_chord_check_while_the_orientation_is_still_found(monkeypatch):
    """Noise-free data: every step removes nearly all of Σ w q² (the residuals
    are orientation still to be found, not noise), so no chord check is made
    and the history is the plain Gauss-Newton one, quadratic to the end."""
    syn = make_strip(8)
    res, calls = _run(monkeypatch, syn, chord=True)
    assert calls["chord"] == 0
    assert res.history[-1] < 1e-6
