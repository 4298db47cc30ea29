"""The start of the models' ground stage (ground/polynomials.similarity_start):
its plan/height passes end at a centimetre, not at the 1e-5 m of a ground
stage's own passes, and the models' solution is the same."""

from __future__ import annotations

import warnings

import numpy as np

import strip_aerotri as sa
import strip_aerotri.ground.models as ground_models
import strip_aerotri.ground.polynomials as polynomials


def test_the_start_passes_end_sooner_and_the_models_end_where_they_did(monkeypatch):
    sim = sa.simulate_strip(300, preset="drone", seed=5)
    strip = sa.form_strip(sim.observations)
    starts = []
    real = ground_models.similarity_start

    def recorded(*args, **kwargs):
        starts.append(real(*args, **kwargs))
        return starts[-1]

    monkeypatch.setattr(ground_models, "similarity_start", recorded)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.StripAerotriWarning)
        loose = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
        monkeypatch.setattr(polynomials, "_START_PASS_TOLERANCE_M", 1e-5)
        strict = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
    # height control: the plan positions are guessed, pass after pass
    assert not sim.control.uses_xy.all()
    assert starts[0].passes < starts[1].passes
    np.testing.assert_allclose(loose.points, strict.points, rtol=0, atol=1e-8)
    np.testing.assert_allclose(loose.photo_centres, strict.photo_centres, rtol=0, atol=1e-8)
    assert [r.point for r in loose.rejections] == [r.point for r in strict.rejections]
    np.testing.assert_allclose(
        loose.control_redundancy, strict.control_redundancy, rtol=0, atol=1e-6
    )
