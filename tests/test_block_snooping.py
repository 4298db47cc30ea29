"""Data snooping of a block's transformation in few rounds.

Each round rejects every failing point determination that is the largest of
its point and of its unit (a model, or a strip with ``block = "strips"``)
instead of the single largest.  Errors are planted in the determinations of
the formed strips (after their own tie tests, so that only the block's test
can find them) and the block is compared with one rejection per round,
emulated by letting only the first leader go.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import strip_aerotri.block.snooping as block_snooping
import strip_aerotri.block.strips as block_strips
from strip_aerotri._stats import leading_failures
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.observations import StripSpec
from strip_aerotri.simulate import simulate_block


@pytest.fixture(scope="module")
def drone():
    return simulate_block(3, 16, preset="drone", side_overlap=0.4, seed=2)


def _planting(n_errors: int, size: float, control: set[str], planted: set[tuple[str, str]]):
    """A `_form` that moves ``n_errors`` determinations of tie points (not
    control), each in another model, in height by ``size`` times the base."""
    form = block_strips._form

    def planting(observations, spec, options, blunders):
        strip = form(observations, spec, options, blunders)
        rng = np.random.default_rng(len(spec.photo_ids) + len(spec.name))
        ids = strip.observations.point_ids
        on_photos = np.bincount(strip.model_point, minlength=len(ids))
        tie = (on_photos >= 3) & ~np.isin(ids, sorted(control))
        rows = []
        for m in rng.choice(strip.n_models, size=n_errors, replace=False):
            here = (strip.model == m) & tie[strip.model_point] & strip.kept_determinations
            rows.append(int(rng.choice(np.flatnonzero(here))))
        base = float(np.median(np.linalg.norm(np.diff(strip.centres, axis=0), axis=1)))
        moved = strip.model_points.copy()
        moved[rows, 2] += size * base * rng.choice([-1.0, 1.0], len(rows))
        planted.update((f"strip {spec.name}", ids[int(strip.model_point[r])]) for r in rows)
        return dataclasses.replace(strip, model_points=moved)

    return planting


def _block(monkeypatch, sim, construction: str, one_at_a_time: bool, n_errors: int):
    solves: list[int] = []
    planted: set[tuple[str, str]] = set()
    solve = block_snooping._solve

    def counted(*args, **kwargs):
        solves.append(1)
        return solve(*args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(block_snooping, "_solve", counted)
        m.setattr(
            block_strips, "_form", _planting(n_errors, 0.05, set(sim.control.point_ids), planted)
        )
        if one_at_a_time:
            m.setattr(
                block_snooping, "leading_failures", lambda *args: leading_failures(*args)[:1]
            )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StripAerotriWarning)
            result = block_strips.adjust_block(
                sim.observations,
                sim.control,
                sim.crs,
                [StripSpec(s.name, s.photo_ids) for s in sim.strips],
                construction=construction,
            )
    return result, len(solves), planted


def test_planted_errors_in_a_block_of_models_go_in_few_rounds(monkeypatch, drone):
    few, rounds, planted = _block(monkeypatch, drone, "models", False, 4)
    single, single_rounds, _ = _block(monkeypatch, drone, "models", True, 4)

    def rejected(result):
        return {(r.photos[0], r.point) for r in result.rejections if r.stage == "models"}

    assert len(planted) == 12
    assert planted <= rejected(few)
    assert rejected(few) == rejected(single)
    assert [r.point for r in few.rejections if r.stage == "control"] == [
        r.point for r in single.rejections if r.stage == "control"
    ]
    assert single_rounds >= len(rejected(single)) + 1
    # measured: 3 rounds against 14, one control point rejected by both
    assert rounds <= single_rounds / 2
    np.testing.assert_allclose(few.points, single.points, rtol=0, atol=1e-6)


def test_a_clean_block_loses_nothing(monkeypatch, drone):
    result, rounds, _ = _block(monkeypatch, drone, "models", False, 0)
    assert not [r for r in result.rejections if r.stage == "models"]
