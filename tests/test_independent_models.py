"""A strip of independent models (R4 2.2, strip/independent.py).

Reference figures are measured on strips from :func:`simulate_strip` against
the simulator's truth and against the dependent chain on the same
observations.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError, GeometryError, StripAerotriWarning
from strip_aerotri.options import BlunderOptions, ModelFormation, StripOptions
from strip_aerotri.pipeline import triangulate
from strip_aerotri.project import load_project
from strip_aerotri.report.record import build_report
from strip_aerotri.simulate import simulate_strip
from strip_aerotri.strip.chaining import form_strip
from strip_aerotri.strip.independent import form_strip_independent

INDEPENDENT = StripOptions(models="independent")


def run(sim, options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        return triangulate(sim.observations, sim.control, sim.crs, strip_options=options)


@pytest.mark.parametrize(("preset", "n_photos", "seed"), [("film", 12, 1), ("drone", 20, 3)])
def test_both_constructions_agree_on_a_clean_strip(preset, n_photos, seed):
    """The two constructions see the same observations: against the
    simulator's truth, over every triangulated point, their errors agree
    within 5 % (measured within 1 %), and the points themselves lie within
    0.3 times that error of each other (measured 0.13 film, 0.23 drone)."""
    sim = simulate_strip(n_photos, seed=seed, preset=preset)
    dependent, independent = run(sim, StripOptions()), run(sim, INDEPENDENT)
    assert independent.strip.options.models is ModelFormation.INDEPENDENT

    def truth_rmse(result) -> np.ndarray:
        error = result.points - sim.truth.points_crs
        error = error[np.isfinite(error).all(axis=1)]
        assert error.shape[0] >= 0.9 * error.shape[0] + 0.1 * sim.observations.n_points
        plan = np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1)))
        return np.array([plan, np.sqrt(np.mean(error[:, 2] ** 2))])

    d, i = truth_rmse(dependent), truth_rmse(independent)
    np.testing.assert_allclose(i, d, rtol=0.05)
    # both near the check points' figures, which are computed from the control
    np.testing.assert_allclose(
        [dependent.check_statistics.rmse_plan, dependent.check_statistics.rmse[2]], d, rtol=0.25
    )
    gap = np.nanmax(np.linalg.norm(independent.points - dependent.points, axis=1))
    assert gap < 0.3 * d.max()
    assert independent.strip.rejections == ()


def test_models_are_independent_and_joined_on_their_centres():
    """Each photo shared by two models gets two rotations, one from each model:
    they differ by the noise of the two orientations (not zero, as in the
    chain where the right photo of one pair is the left of the next), and
    the strip takes their mean."""
    sim = simulate_strip(10, seed=2)
    strip = form_strip_independent(sim.observations, INDEPENDENT)
    chain = form_strip(sim.observations)
    assert strip.n_models == chain.n_models == 9
    assert strip.breaks.size == 0
    assert np.all(strip.tie_count[1:] >= 2)
    # the strip system: first photo as given (identity), first base of length 1
    np.testing.assert_allclose(strip.rotations[0], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(strip.centres[0], 0.0, atol=1e-12)
    assert np.linalg.norm(strip.centres[1] - strip.centres[0]) == pytest.approx(1.0, abs=1e-3)
    # rotations proper
    np.testing.assert_allclose(
        strip.rotations @ np.swapaxes(strip.rotations, 1, 2),
        np.broadcast_to(np.eye(3), (10, 3, 3)),
        atol=1e-12,
    )


def test_double_determinations_scale_with_the_image_noise():
    """The tie points' differences between the two models that determine them
    are the R4 criterion of the join: doubling the image noise about doubles
    their RMS (the ratio of noise-driven quantities, within sampling)."""
    rms = []
    for noise_um in (3.0, 6.0):
        sim = simulate_strip(20, seed=5, image_noise_mm=noise_um / 1000.0)
        strip = form_strip_independent(sim.observations, INDEPENDENT)
        rms.append(np.sqrt(np.nanmean(strip.tie_rms[1:] ** 2, axis=0)))
    ratio = rms[1] / rms[0]
    assert np.all((ratio[1:] > 1.6) & (ratio[1:] < 2.5)), ratio


def test_a_tie_point_blunder_is_found_and_left_out():
    """A tie point whose image coordinate on the shared photo is off by 40 µm
    along the flight (an x-parallax error: a height error in both models, of
    opposite effect) fails the height test of the double determinations."""
    sim = simulate_strip(12, seed=4)
    obs = sim.observations
    clean = form_strip_independent(obs, INDEPENDENT)
    # a tie of model 5 measured on its left photo (the photo model 4 shares)
    row_l = clean.model_rows[:, 0]
    target_point = clean.tie_point[clean.tie_model == 5][0]
    row = row_l[(clean.model == 5) & (clean.model_point == target_point)][0]
    xy = obs.xy.copy()
    xy[row, 0] += 0.040
    bad = dataclasses.replace(obs, xy=xy)
    # the y-parallax test cannot see it (along the base), the tie test must
    strip = form_strip_independent(bad, INDEPENDENT)
    named = [r for r in strip.rejections if r.stage == "tie_points"]
    assert [r.point for r in named] == [obs.point_ids[target_point]]
    assert named[0].component == "Z" and abs(named[0].w) > named[0].critical
    assert obs.point_ids[target_point] in strip.rejected_points
    # only reporting: found, nothing left out
    reported = form_strip_independent(bad, INDEPENDENT, blunders=BlunderOptions(action="report"))
    assert [r.point for r in reported.rejections if r.stage == "tie_points"] == [
        obs.point_ids[target_point]
    ]
    assert reported.rejected_points == ()


def test_a_model_with_too_few_ties_is_named():
    sim = simulate_strip(8, seed=1)
    obs = sim.observations
    strip = form_strip(obs)
    ties = set(strip.tie_point[strip.tie_model == 3].tolist())
    # keep one tie of model 3 on photo 4 (the shared one); drop the others there
    keep = ~(np.isin(obs.point, list(ties)[1:]) & (obs.photo == 3))
    thin = dataclasses.replace(
        obs, xy=obs.xy[keep], photo=obs.photo[keep], point=obs.point[keep], sigma=obs.sigma[keep]
    )
    with pytest.raises(GeometryError, match=r"pair .*-.* shares 1 usable tie point.*at least 2"):
        form_strip_independent(thin, INDEPENDENT)


def test_project_key_and_report(tmp_path):
    sim = simulate_strip(10, seed=6)
    toml = sim.write_project(tmp_path / "p")
    text = toml.read_text()
    toml.write_text(text.replace("[adjustment]", '[adjustment]\nmodels = "independent"'))
    project = load_project(toml)
    assert project.adjustment.models is ModelFormation.INDEPENDENT
    from strip_aerotri.project import run_project

    result = run_project(project)
    report = json.loads(json.dumps(build_report(result, project=project)))
    assert report["options"]["models"] == "independent"
    assert all(m["tie_rms_m"][2] is not None for m in report["models"][1:])
    toml.write_text(
        text.replace(
            "[adjustment]",
            '[adjustment]\nmodels = "independent"\nrelative_orientation = "dependent"',
        )
    )
    with pytest.raises(ConfigError, match=r"relative_orientation.*independent"):
        load_project(toml)
