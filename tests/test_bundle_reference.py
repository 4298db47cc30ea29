"""The bundle refinement against an independent reference on the same
observations (benchmarks/bench_reference_bundle.py: scipy finite-difference
Jacobian, Gauss-Newton on the sparse normal equations)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_reference_bundle as reference

from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.observations import StripSpec
from strip_aerotri.pipeline import triangulate_block
from strip_aerotri.simulate import simulate_block


@pytest.fixture(scope="module")
def block():  # type: ignore[no-untyped-def]
    """A simulated 2 x 6 drone block (local site system), refined by the bundle."""
    sim = simulate_block(2, 6, preset="drone", seed=7, crs="local")
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        return triangulate_block(
            sim.observations, sim.control, sim.crs, specs, route="projected", refine="bundle"
        )


def test_refinement_is_the_least_squares_solution_of_its_observations(block) -> None:  # type: ignore[no-untyped-def]
    """Same sigma0, same check points to 0.1 mm: the engine (band, border,
    Schur complement) solves the stated problem."""
    used = reference._used_rays(block)
    ref = reference.from_block(block, used=used).solve()
    assert ref.sigma0 == pytest.approx(block.refined_sigma0, rel=1e-4)
    errors = reference.check_errors(ref, block)
    names = np.array(block.control.point_ids)[block.control_index]
    engine = dict(zip(names[block.is_check], block.control_residuals[block.is_check], strict=True))
    assert len(errors) >= 5 and set(errors) <= set(engine)
    for pid, e in errors.items():
        np.testing.assert_allclose(e, engine[pid], atol=1e-4, err_msg=pid)


def test_the_reference_sees_a_perturbed_solution(block) -> None:  # type: ignore[no-untyped-def]
    """The comparison can fail: the reference's sigma0 at a start moved by
    0.5 m is far above the refinement's (the reference is not a copy)."""
    ref = reference.from_block(block, used=reference._used_rays(block))
    moved = np.zeros(ref.n_unknowns)
    moved[3 * len(ref.centres0) : 6 * len(ref.centres0)] = 0.5
    r = ref.residuals(moved)
    assert np.sqrt(r @ r / (r.size - ref.n_unknowns)) > 5 * block.refined_sigma0
