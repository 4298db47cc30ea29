"""Every strip's own deformation polynomial in a block of independent strips
(``block = "strips"``, R4 3) and the transfer errors of the free block
(R4 1.7.7.3)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.block.strips import adjust_block
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.geometry.simultaneous import (
    UnitObservations,
    UnitPolynomial,
    UnitTransforms,
    adjust_units,
)
from strip_aerotri.observations import StripSpec
from strip_aerotri.options import BlunderOptions
from strip_aerotri.simulate import simulate_block


def test_basis_and_jacobian_agree_with_finite_differences():
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-100, 100, (40, 3))
    unit = np.repeat([0, 1], 20)
    poly = UnitPolynomial.fit(unit, xyz, 2, 3)
    a = rng.normal(0, 1e-3, (2, poly.n_terms))

    def corr(x: np.ndarray) -> np.ndarray:
        return np.einsum("nik,nk->ni", poly.basis(unit, x), a[unit])

    jac = poly.jacobian(unit, xyz, a)
    h = 1e-3
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        numeric = (corr(xyz + step) - corr(xyz - step)) / (2 * h)
        np.testing.assert_allclose(jac[:, :, k], numeric, atol=1e-9)
    # the terms: uv, u², u³ along each of the unit's axes, times its half length
    local = np.einsum("nji,nj->ni", poly.axes[unit], xyz - poly.origin[unit])
    u = local[:, 0] / poly.half_length[unit]
    assert np.abs(u).max() == pytest.approx(1.0)
    b = poly.basis(unit, xyz)
    np.testing.assert_allclose(
        np.einsum("nji,nj->ni", poly.axes[unit], b[:, :, 3]),
        np.outer(poly.half_length[unit] * u**2, [1.0, 0.0, 0.0]),
        atol=1e-9,
    )


def test_a_bent_strip_is_recovered():
    """Two strips side by side, the second bent by known twist and quadratic
    terms: adjusting both with their polynomials onto control on the first
    strip and at one end of the second recovers the bending (exact data: to
    the prior's pull) and every point to a millimetre; similarities alone
    miss by decimetres."""
    rng = np.random.default_rng(7)
    n_points = 150
    ground = np.column_stack(
        [
            rng.uniform(0.0, 1000.0, n_points),
            rng.uniform(-150.0, 150.0, n_points),
            rng.normal(300.0, 5.0, n_points),
        ]
    )
    seen = [np.flatnonzero(ground[:, 1] < 40.0), np.flatnonzero(ground[:, 1] > -40.0)]
    scale = np.array([1.0, 1.02])
    rotation = np.stack([np.eye(3), matrix_from_rotvec(np.array([0.002, -0.001, 0.03]))])
    translation = np.array([[500.0, -50.0, 300.0], [500.0, 50.0, 300.0]])
    centroid = np.zeros((2, 3))
    # unit coordinates by the inverse similarity, then the polynomial's
    # inverse by fixed-point iteration: x = c + Rᵀ (X − t) / s − B(x) a
    unit = np.concatenate([np.full(p.size, k) for k, p in enumerate(seen)])
    point = np.concatenate(seen)
    flat = (
        np.einsum("nji,nj->ni", rotation[unit], ground[point] - translation[unit])
        / scale[unit, None]
    )
    poly = UnitPolynomial.fit(unit, flat, 2, 2)
    coefficients = np.zeros((2, poly.n_terms))
    coefficients[1] = [0.0, 0.0, 2e-4, 1e-3, -5e-4, 8e-4]  # twist in height; u² bends
    xyz = flat.copy()
    for _ in range(50):
        xyz = flat - np.einsum("nik,nk->ni", poly.basis(unit, xyz), coefficients[unit])
    truth = UnitTransforms(scale, rotation, translation, centroid, poly, coefficients)
    np.testing.assert_allclose(truth.apply(unit, xyz), ground[point], atol=1e-9)
    rows = UnitObservations(unit, point, xyz, np.broadcast_to(np.eye(3) * 1e4, (unit.size, 3, 3)))
    only_1 = np.setdiff1d(seen[1], seen[0])
    ends = only_1[np.argsort(ground[only_1, 0])[:3]]
    control = np.concatenate([seen[0], ends])
    start = UnitTransforms(np.ones(2), np.stack([np.eye(3)] * 2), translation + 1.0, centroid)
    common = {
        "start": start,
        "points0": ground + rng.normal(0, 1.0, ground.shape),
        "control_point": control,
        "control_xyz": ground[control],
        "control_sigma": 0.001,
    }
    res = adjust_units(rows, 2, n_points, polynomial=poly, **common)
    assert res.converged
    np.testing.assert_allclose(res.transforms.coefficients, coefficients, atol=2e-6)
    np.testing.assert_allclose(res.points, ground, atol=1e-3)
    rigid = adjust_units(rows, 2, n_points, **common)
    assert np.max(np.abs(rigid.points - ground)) > 0.1  # 0.29 m


def _specs(sim) -> list[StripSpec]:
    return [StripSpec(s.name, s.photo_ids) for s in sim.strips]


@pytest.fixture(scope="module")
def film2():
    return simulate_block(3, 8, preset="film", side_overlap=0.3, seed=2)


def test_the_strips_polynomials_bring_the_block_of_strips_closer_to_the_truth(film2):
    """On a film block whose strips bend (seed 2: 2.2 / 2.5 times the
    bundle's check-point RMSE with similarities only, docs/block.md), every
    strip's type-2 polynomial takes the check points closer to the truth in
    plan and in height."""
    sim = film2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        rigid = adjust_block(
            sim.observations,
            sim.control,
            sim.crs,
            _specs(sim),
            construction="strips",
            polynomial=0,
        )
        bent = adjust_block(
            sim.observations,
            sim.control,
            sim.crs,
            _specs(sim),
            construction="strips",
        )
    assert bent.polynomial == 2 and rigid.polynomial == 0
    r, b = rigid.check_statistics, bent.check_statistics
    # measured 0.86 / 0.56 of the similarities' (the strips' points weighted
    # by their rays; 0.70 / 0.45 with one sigma per strip)
    assert b.rmse_plan < 0.92 * r.rmse_plan
    assert b.rmse[2] < 0.65 * r.rmse[2]
    assert np.isfinite(bent.photo_opk).all()


def test_transfer_errors_are_those_of_the_free_block(film2):
    """The transfer errors (um in the image) do not see the control: a
    control point moved by a metre changes the joins' discrepancies of the
    block on the control, not those of the free block."""
    sim = film2
    specs = _specs(sim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        base = adjust_block(
            sim.observations,
            sim.control,
            sim.crs,
            specs,
            construction="strips",
            polynomial=0,
            blunders=BlunderOptions(action="off"),
        )
        used = np.flatnonzero(sim.control.uses_xy & ~sim.control.is_check)
        xyz = sim.control.xyz.copy()
        xyz[used[: used.size // 2], 0] += 1.0  # half the plan control shifted east
        shifted = dataclasses.replace(sim.control, xyz=xyz)
        moved = adjust_block(
            sim.observations,
            shifted,
            sim.crs,
            specs,
            construction="strips",
            polynomial=0,
            blunders=BlunderOptions(action="off"),
        )
    for a, b in zip(base.joins, moved.joins, strict=True):
        assert 0.0 < a.mean_transfer_um < 40.0  # clean data: within R4's limit
        assert b.mean_transfer_um == pytest.approx(a.mean_transfer_um, rel=1e-3)
    forced = max(
        b.mean_plan_m / a.mean_plan_m for a, b in zip(base.joins, moved.joins, strict=True)
    )
    assert forced > 1.05  # the control does force the joins of the block itself (+8-12 %)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True)


@pytest.mark.parametrize(
    ("adjustment", "named"),
    [
        ('block = "models"\npolynomial = 2\n', ("polynomial", 'block = "strips"')),
        ('block = "strips"\npolynomial = "auto"\n', ("polynomial", "auto", "0, 1, 2 or 3")),
        ('block = "strips"\nsections = 2\n', ("sections",)),
    ],
    ids=["polynomial with models", "auto", "sections"],
)
def test_block_polynomial_keys_are_checked(tmp_path: Path, film2, adjustment, named):
    toml = film2.write_project(tmp_path / "p")
    text = toml.read_text()
    table = '[adjustment]\nblock = "models"\n'
    assert table in text
    toml.write_text(text.replace(table, "[adjustment]\n" + adjustment))
    run = run_cli("check", str(toml))
    assert run.returncode == 1
    line = run.stderr.strip().splitlines()[-1]
    assert line.startswith("stripaero: error:") and all(n in line for n in named), line


def test_block_of_strips_reports_its_polynomial_and_transfer_errors(tmp_path: Path, film2):
    toml = film2.write_project(tmp_path / "p", block="strips")
    run = run_cli("run", str(toml), "--map-scale", "5000")
    assert run.returncode == 0, run.stderr
    report = json.loads((toml.parent / "out" / "report.json").read_text())
    block = report["block"]
    assert block["construction"] == "strips" and block["polynomial"] == 2  # the default
    assert report["options"]["block"] == "strips" and report["options"]["polynomial"] == 2
    assert report["inputs"]["n_strips"] == 3 and report["inputs"]["n_photos"] == 24
    assert all(0 <= s["polynomial_terms"] <= 6 for s in block["strips"])
    # the strips' own determinations meet the control less closely than the
    # adjusted points, which the control holds
    fit, held = report["control"]["fit_statistics"], report["control"]["statistics"]
    assert fit["n_plan"] == held["n_plan"] and fit["rmse_plan_m"] > held["rmse_plan_m"]
    # R4's check-point criterion at the map scale, as a strip's report has it
    first = report["tolerances"]["criteria"][0]
    assert first["name"] == "check_mean_plan" and first["limit"] == 0.3e-3 * 5000
    assert first["passed"] is (first["value"] <= first["limit"])
    for join in block["joins"]:
        assert join["transfer_limit_um"] == 40.0
        assert join["transfer_passed"] is (join["mean_transfer_um"] <= 40.0)
        assert 0 < join["mean_transfer_um"] <= join["max_transfer_um"]
    page = (toml.parent / "out" / "report.html").read_text()
    assert "mean transfer [µm]" in page and "polynomial of type 2" in page
    assert "Tolerances of the production rules (R4 §1.7.7):" in page
    assert "mean plan error at the check points within 0.3 mm at the map scale" in page


def test_terms_the_control_cannot_determine_are_left_out():
    """Control at the block's corners only cannot see the strips bending
    together: with every term kept, a film block missed its check points by
    3.4 m in plan; the terms whose effect the block determines worse than
    twice a strip point's sigma are held at 0, with a warning naming them."""
    sim = simulate_block(
        3, 10, preset="film", side_overlap=0.43, flight="serpentine", control="corners", seed=500
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = adjust_block(
            sim.observations, sim.control, sim.crs, _specs(sim), construction="strips"
        )
        bundle = adjust_block(sim.observations, sim.control, sim.crs, _specs(sim), refine=True)
    notes = [w for w in result.warnings if "polynomial term(s)" in w]
    assert len(notes) == 3 and all("u² across" in n for n in notes)
    assert result.check_statistics.rmse_plan < 3.0 * bundle.check_statistics.rmse_plan


def test_simulated_block_with_a_polynomial_runs_as_a_block_of_strips(tmp_path: Path):
    """``stripaero simulate --strips N --polynomial P`` writes block = "strips"
    (a polynomial of block = "models" is refused by run); "auto" is refused
    for a block at once; the run prints R4's tolerance line at the map scale."""
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    runner = CliRunner()
    out = tmp_path / "b"
    args = ["simulate", "drone", "--strips", "2", "--photos", "6", "--out", str(out)]
    made = runner.invoke(cli, [*args, "--polynomial", "2"])
    assert made.exit_code == 0, made.output
    text = (out / "strip.toml").read_text()
    assert 'block = "strips"' in text and "polynomial = 2" in text
    ran = runner.invoke(cli, ["run", str(out / "strip.toml"), "--map-scale", "1000"])
    assert ran.exit_code == 0, ran.output
    assert "tolerances (R4 §1.7.7): " in ran.stdout and "at 1:1000" in ran.stdout
    auto = runner.invoke(cli, [*args, "--polynomial", "auto", "--force"])
    assert auto.exit_code == 2 and "auto" in auto.output
