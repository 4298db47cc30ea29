"""Blocks of strips (block/strips.py, R4 3): every strip formed on its own,
then all transformed at once onto the control and onto each other.

Reference figures are measured on blocks from :func:`simulate_block` against
the simulator's truth and against the same strips adjusted one by one with
the same control.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from strip_aerotri.block.strips import adjust_block, strip_observations
from strip_aerotri.errors import GeometryError, StripAerotriWarning
from strip_aerotri.observations import ControlPoints, StripSpec
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_block


def specs(sim) -> list[StripSpec]:
    return [StripSpec(s.name, s.photo_ids) for s in sim.strips]


def separate_plan_rmse(sim) -> list[float]:
    out = []
    for s in sim.strips:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StripAerotriWarning)
            sub = strip_observations(sim.observations, s.photo_ids)
            out.append(triangulate(sub, sim.control, sim.crs).check_statistics.rmse_plan)
    return out


@pytest.fixture(scope="module")
def film():
    return simulate_block(3, 8, preset="film", seed=1)


@pytest.fixture(scope="module")
def drone():
    return simulate_block(4, 15, preset="drone", side_overlap=0.4, seed=1)


@pytest.mark.parametrize("name", ["film", "drone"])
def test_block_by_models_beats_the_strips_alone(name, request):
    """The block's check points against the truth: better than the same
    strips adjusted one by one on the same control (their median), and with
    sigma0 near 1 (the weights of the models' rays are right)."""
    sim = request.getfixturevalue(name)
    result = adjust_block(
        sim.observations, sim.control, sim.crs, specs(sim), construction="models"
    )
    check = result.check_statistics
    assert check.n_plan > 50
    assert check.rmse_plan < np.median(separate_plan_rmse(sim))
    assert 0.7 < result.sigma0 < 1.5
    assert len(result.joins) == len(sim.strips) - 1 + 0  # adjacent strips only share points
    assert all(j.n_points >= 3 for j in result.joins)


@pytest.mark.parametrize("name", ["film", "drone"])
def test_block_by_models_is_near_the_bundle(name, request):
    """Against the rigorous bundle on the same observations (the refinement
    of the whole block, started from the block's solution): within 1.3 times
    its check-point RMSE in plan and height (measured 1.03-1.16 on three
    seeds each), and the refinement's sigma0 near 1."""
    sim = request.getfixturevalue(name)
    models = adjust_block(sim.observations, sim.control, sim.crs, specs(sim))
    bundle = adjust_block(sim.observations, sim.control, sim.crs, specs(sim), refine=True)
    assert bundle.refined and 0.8 < bundle.refined_sigma0 < 1.25
    m, b = models.check_statistics, bundle.check_statistics
    assert m.rmse_plan < 1.3 * b.rmse_plan
    assert m.rmse[2] < 1.3 * b.rmse[2]


def test_block_by_strips_runs_and_reports_the_joins(film):
    """Every strip by one similarity (R4 3): weaker than every model, but a
    block; the joins of adjacent strips are reported."""
    by_strips = adjust_block(
        film.observations, film.control, film.crs, specs(film), construction="strips"
    )
    by_models = adjust_block(
        film.observations, film.control, film.crs, specs(film), construction="models"
    )
    assert by_strips.check_statistics.rmse_plan < 0.2
    assert by_models.check_statistics.rmse_plan <= by_strips.check_statistics.rmse_plan
    assert [j.strips for j in by_strips.joins] == [(0, 1), (1, 2)]
    # the photos carry their strip; every photo has a position and an attitude
    assert np.isfinite(by_strips.photo_centres).all() and np.isfinite(by_strips.photo_opk).all()
    assert by_strips.photo_strip.tolist() == [0] * 8 + [1] * 8 + [2] * 8


def _observed_by(sim, strip_index: int) -> np.ndarray:
    """(P,) whether the strip's photos observe each point."""
    obs = sim.observations
    photos = [obs.photo_ids.index(p) for p in sim.strips[strip_index].photo_ids]
    seen = np.zeros(obs.n_points, dtype=bool)
    seen[np.unique(obs.point[np.isin(obs.photo, photos)])] = True
    return seen


def _control_seen_by(sim, control: ControlPoints, strip_index: int) -> list[str]:
    """The control points (not check points) the strip's photos observe."""
    seen = _observed_by(sim, strip_index)
    lookup = {pid: i for i, pid in enumerate(sim.observations.point_ids)}
    return [
        p
        for p, kind in zip(control.point_ids, control.kind, strict=True)
        if kind.value != "check" and p in lookup and seen[lookup[p]]
    ]


def _without_control_of(sim, strip_index: int) -> ControlPoints:
    """The control minus every control point the given strip observes (its
    own and those it shares with its neighbours); check points are kept."""
    gone = set(_control_seen_by(sim, sim.control, strip_index))
    c = sim.control
    keep = np.array([p not in gone for p in c.point_ids])
    return dataclasses.replace(
        c,
        point_ids=tuple(np.array(c.point_ids)[keep]),
        xyz=c.xyz[keep],
        kind=tuple(np.array(c.kind, dtype=object)[keep]),
        sigma_xy=c.sigma_xy[keep],
        sigma_h=c.sigma_h[keep],
        source_line=c.source_line[keep] if c.source_line.size else c.source_line,
    )


def test_a_strip_without_control_is_carried_by_its_neighbours(film):
    control = _without_control_of(film, 1)
    # the middle strip really has no control left, and the others still have some
    assert len(control.point_ids) < len(film.control.point_ids)
    assert _control_seen_by(film, film.control, 1) != []
    assert _control_seen_by(film, control, 1) == []
    assert _control_seen_by(film, control, 0) and _control_seen_by(film, control, 2)
    result = adjust_block(film.observations, control, film.crs, specs(film), construction="models")
    full = adjust_block(
        film.observations, film.control, film.crs, specs(film), construction="models"
    )
    # the middle strip's own points against the simulator's truth: carried by
    # its neighbours' common points, it lands within 1.5x of the full block
    middle = _observed_by(film, 1)
    truth = film.truth.points_crs[middle]

    def plan_rmse(block) -> float:
        d = block.points[middle, :2] - truth[:, :2]
        d = d[np.isfinite(d).all(axis=1)]
        return float(np.sqrt(np.mean(np.sum(d**2, axis=1))))

    assert np.isfinite(result.points[middle]).all(axis=1).mean() > 0.95
    assert plan_rmse(result) < 1.5 * plan_rmse(full)  # measured 1.19x


def test_an_isolated_strip_without_control_is_named(film):
    obs = film.observations
    third = [obs.photo_ids.index(p) for p in film.strips[2].photo_ids]
    second = [obs.photo_ids.index(p) for p in film.strips[1].photo_ids]
    shared = np.intersect1d(
        obs.point[np.isin(obs.photo, third)], obs.point[np.isin(obs.photo, second)]
    )
    keep = ~(np.isin(obs.photo, third) & np.isin(obs.point, shared))
    isolated = dataclasses.replace(
        obs,
        photo=obs.photo[keep],
        point=obs.point[keep],
        xy=obs.xy[keep],
        sigma=obs.sigma[keep],
        source_line=obs.source_line[keep] if obs.source_line.size else obs.source_line,
    )
    control = _without_control_of(film, 2)
    with pytest.raises(GeometryError, match=r"strip 'S3' shares 0 point\(s\) with the rest"):
        adjust_block(isolated, control, film.crs, specs(film))


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True)


def test_cli_end_to_end(tmp_path: Path, film):
    toml = film.write_project(tmp_path / "p", block="models")
    run = run_cli("run", str(toml))
    assert run.returncode == 0, run.stderr
    out = toml.parent / "out"
    header = (out / "photos.csv").read_text().splitlines()[0].split(",")
    assert header[:7] == ["photo", "X", "Y", "Z", "omega", "phi", "kappa"] and "strip" in header
    report = json.loads((out / "report.json").read_text())
    assert [s["name"] for s in report["block"]["strips"]] == ["S1", "S2", "S3"]
    assert len(report["block"]["joins"]) == 2
    assert report["check"]["statistics"]["n_plan"] > 50
    page = (out / "report.html").read_text()
    assert "block" in page and page.count("<img") == 1  # the block figure
    check = run_cli("check", str(toml))
    assert check.returncode == 0 and "OK" in check.stdout


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        (lambda t: '[strip]\nphotos = ["S1_01", "S1_02"]\n' + t, ("[strip]", "[[strips]]")),
        (
            lambda t: t.replace('photos = ["S2_01"', 'photos = ["S1_01", "S2_01"', 1),
            ("'S1_01'", "S1", "S2"),
        ),
        (lambda t: t.replace('name = "S2"', 'name = "S1"', 1), ("'S1'", "name")),
        (
            lambda t: t + '\n[[straight_line]]\npoints = ["P00001", "P00002", "P00003"]\n',
            ("[[straight_line]]", "block"),
        ),
    ],
    ids=["mixed", "photo in two strips", "two names", "straight line"],
)
def test_cli_bad_blocks_are_one_line(tmp_path: Path, film, edit, named):
    toml = film.write_project(tmp_path / "p")
    toml.write_text(edit(toml.read_text()))
    run = run_cli("run", str(toml))
    assert run.returncode == 1
    lines = run.stderr.strip().splitlines()
    assert lines[-1].startswith("stripaero: error:") and all(n in lines[-1] for n in named)
    assert not (toml.parent / "out").exists()


# --------------------------------------------------------------------------- the real UAV block

UAV = Path(__file__).resolve().parents[2] / "shared" / "data" / "uav-block-fc300x"


@pytest.mark.skipif(not (UAV / "GCP_UTM.txt").is_file(), reason=f"FC300X data not found in {UAV}")
def test_real_uav_block_beats_its_strips_run_one_by_one(tmp_path: Path):
    """The 3-strip FC300X block (docs/block.md): imported as the importer
    chooses the control (per strip the GCPs nearest its start, middle and
    end; every other GCP a check point), adjusted as a block, and each strip
    alone with the same control file.  On the same check points the block is
    better, and within the bounds measured (docs/block.md)."""
    from strip_aerotri.importers.common import ImportOptions, write_project
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.project import load_project, run_project

    def checks(result) -> dict[str, np.ndarray]:
        final = getattr(result, "ground", result)  # a strip's are its ground stage's
        rows = np.asarray(final.control_index)
        return {
            result.control.point_ids[r]: np.asarray(d)
            for r, d, c in zip(rows, final.control_residuals, final.is_check, strict=True)
            if c and np.isfinite(d).all()
        }

    block_toml = write_project(import_uav_fc300x(UAV), tmp_path / "block")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        block = run_project(load_project(block_toml))
        separate: list[tuple[np.ndarray, np.ndarray]] = []
        in_block = checks(block)
        for k in (1, 2, 3):
            toml = write_project(
                import_uav_fc300x(UAV, ImportOptions(strips=(k,))), tmp_path / f"s{k}"
            )
            (toml.parent / "control.csv").write_bytes(
                (block_toml.parent / "control.csv").read_bytes()
            )
            alone = checks(run_project(load_project(toml)))
            separate += [(d, in_block[p]) for p, d in alone.items() if p in in_block]
    assert len(separate) >= 25
    alone_d = np.array([s[0] for s in separate])
    block_d = np.array([s[1] for s in separate])

    def rmse(d: np.ndarray) -> tuple[float, float]:
        return float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))), float(
            np.sqrt(np.mean(d[:, 2] ** 2))
        )

    (bp, bh), (sp, sh) = rmse(block_d), rmse(alone_d)
    assert bp < sp and bh < sh
    # measured 0.034 / 0.036 m on the block's 15 check points (2.3 cm ground pixel)
    assert block.check_statistics.rmse_plan < 0.045
    assert block.check_statistics.rmse[2] < 0.05
    # the transfer errors of the free block (R4 1.7.7.3), measured 70 / 12 / 13 um:
    # B1 / B2 shares the weak edge tie points that also fail on the ground
    transfer = {tuple(block.specs[i].name for i in j.strips): j for j in block.joins}
    assert transfer["B1", "B2"].mean_transfer_um > 40.0
    assert transfer["B2", "B3"].mean_transfer_um < 40.0


def test_gnss_centres_in_the_block_refinement():
    """A drone block with control at its corners only: GNSS centres (3 cm plan,
    5 cm height) in the refinement of the whole block improve its plan
    accuracy (measured 0.022 -> 0.014 m), with sigma0 near 1."""
    from strip_aerotri.observations import GnssCentres

    sim = simulate_block(3, 10, preset="drone", side_overlap=0.4, seed=4, control="corners")
    rng = np.random.default_rng(1)
    truth = sim.truth.photo_centres_crs
    noise = np.column_stack(
        [rng.normal(0.0, 0.03, (len(truth), 2)), rng.normal(0.0, 0.05, len(truth))]
    )
    gnss = GnssCentres(
        sim.observations.photo_ids,
        truth + noise,
        np.full(len(truth), 0.03),
        np.full(len(truth), 0.05),
    )
    without = adjust_block(sim.observations, sim.control, sim.crs, specs(sim), refine=True)
    with_gnss = adjust_block(
        sim.observations, sim.control, sim.crs, specs(sim), refine=True, gnss=gnss
    )
    assert with_gnss.check_statistics.rmse_plan < 0.8 * without.check_statistics.rmse_plan
    assert 0.8 < with_gnss.refined_sigma0 < 1.25
    # the centres' residuals are reported: every photo used, about their sigmas
    out = with_gnss.gnss
    assert without.gnss is None and out is not None
    assert out.n_used == len(truth) and not np.asarray(out.rejected).any()
    # residuals below the noise put in (3 cm per plan axis, 5 cm up), not zero
    assert 0.3 * 0.042 < out.rms_plan < 0.042 and 0.3 * 0.05 < out.rms[2] < 0.05
    from strip_aerotri.report.block import build_block_report

    report = build_block_report(with_gnss)
    assert report["bundle"]["gnss"]["n_used"] == len(truth)
    assert len(report["bundle"]["gnss"]["photos"]) == len(truth)
    assert build_block_report(without)["bundle"]["gnss"] is None
    # the block's own solution beside the refinement's, for comparison
    own = report["bundle"]["block_check"]
    assert own["n_plan"] == report["check"]["statistics"]["n_plan"]
    assert own["rmse_plan_m"] != report["check"]["statistics"]["rmse_plan_m"]
    assert len(report["check"]["points"]) == with_gnss.check_statistics.n_plan


def test_control_blunders_in_a_block_are_found():
    """Two control points off by 0.5-2 m and five image blunders: the block's
    tests reject exactly the two planted control points, and the check
    points stay near the clean block's (measured 0.040 / 0.076 against
    0.040 / 0.062 m)."""
    kw: dict[str, Any] = {"preset": "film", "side_overlap": 0.2, "seed": 8}
    sim = simulate_block(3, 10, **kw, image_blunders=5, control_blunders=2)
    clean = simulate_block(3, 10, **kw)
    result = adjust_block(sim.observations, sim.control, sim.crs, specs(sim))
    planted = sorted(sim.control.point_ids[i] for i in sim.truth.blunder_control)
    assert sorted(r.point for r in result.rejections if r.stage == "control") == planted
    reference = adjust_block(clean.observations, clean.control, clean.crs, specs(clean))
    assert result.check_statistics.rmse_plan < 1.2 * reference.check_statistics.rmse_plan
    assert result.check_statistics.rmse[2] < 1.5 * reference.check_statistics.rmse[2]


def test_the_refinement_tests_the_blocks_control_itself():
    """The bundle refinement of a block starts from all its control, as a
    strip's does, and tests it itself: the two planted control blunders fail
    its tests again and stay out of the refinement; the check points stay
    near the clean block's refinement."""
    kw: dict[str, Any] = {"preset": "film", "side_overlap": 0.2, "seed": 8}
    sim = simulate_block(3, 10, **kw, control_blunders=2)
    clean = simulate_block(3, 10, **kw)
    result = adjust_block(sim.observations, sim.control, sim.crs, specs(sim), refine=True)
    planted = sorted(sim.control.point_ids[i] for i in sim.truth.blunder_control)
    # the block's tests name the component "XY", the bundle's "plan"
    by_block = sorted(r.point for r in result.rejections if r.component == "XY")
    by_bundle = sorted(r.point for r in result.rejections if r.component == "plan")
    assert by_block == by_bundle == planted, (by_block, by_bundle, planted)
    rows = [sim.control.point_ids[r] for r in result.control_index]
    for pid in planted:
        assert not result.used_xy[rows.index(pid)], pid
    reference = adjust_block(
        clean.observations, clean.control, clean.crs, specs(clean), refine=True
    )
    assert result.check_statistics.rmse_plan < 1.2 * reference.check_statistics.rmse_plan
    assert result.check_statistics.rmse[2] < 1.5 * reference.check_statistics.rmse[2]


@pytest.mark.parametrize("preset", ["drone", "film"])
def test_auto_chooses_again_without_the_control_blunders(preset: str) -> None:
    """An error-free block with two control points off by 0.5-2 m: chosen
    with them, "auto" kept k1 and k3 for their bending (drone; film seeds
    1-4: 7 of 8 blocks kept a set); once the tests reject them it chooses
    again without them, keeps nothing, and the refinement is the plain one."""
    from strip_aerotri.options import SelfCalibration

    sim = simulate_block(3, 10, preset=preset, side_overlap=0.3, seed=2, control_blunders=2)
    args = (sim.observations, sim.control, sim.crs, specs(sim))
    plain = adjust_block(*args, refine=True)
    auto = adjust_block(*args, refine=True, self_calibration=SelfCalibration("auto"))
    outcome = auto.self_calibration
    assert outcome is not None and outcome.kept == ()
    assert any("chosen again without the" in n and "control" in n for n in outcome.notes)
    assert auto.check_statistics.rmse_plan == pytest.approx(plain.check_statistics.rmse_plan)
    assert auto.check_statistics.rmse[2] == pytest.approx(plain.check_statistics.rmse[2])


def test_rejected_control_in_a_block_keeps_its_residual():
    """A control point the block's tests reject is listed with its residual
    (given - adjusted, about the planted error), as a strip's is; the control
    statistics leave it out."""
    kw: dict[str, Any] = {"preset": "film", "side_overlap": 0.2, "seed": 8}
    sim = simulate_block(3, 10, **kw, control_blunders=2)
    result = adjust_block(sim.observations, sim.control, sim.crs, specs(sim))
    rejected = {r.point for r in result.rejections if r.stage == "control"}
    assert rejected
    ids = list(sim.observations.point_ids)
    rows = result.control_index
    for k, row in enumerate(rows):
        pid = sim.control.point_ids[row]
        if pid not in rejected:
            continue
        planted = sim.control.xyz[row] - sim.truth.points_crs[ids.index(pid)]
        resid = result.control_residuals[k]
        assert np.all(np.isfinite(resid[:2])), pid
        assert np.hypot(*(resid[:2] - planted[:2])) < 0.3, (pid, resid, planted)
    used = ~np.isin([sim.control.point_ids[r] for r in rows], sorted(rejected))
    n_control = int(np.sum(used & ~result.is_check & result.used_xy))
    assert result.control_statistics.n_plan == n_control


def test_long_strips_by_one_similarity_stop_instead_of_rejecting_good_control():
    """Two drone strips of 100 photos: one similarity per strip cannot follow
    their bending, and a quarter of the (error-free) control would fail its
    test.  As the ground stage of one strip, the block stops when more than
    ``max_fraction`` of the control fails, and says why, instead of
    rejecting good control one point after another (a 10 x 100-photo block
    rejected 45 of 86 plan and 50 of 374 height points, check points 0.48 m,
    against 0.014 m with every model its own similarity)."""
    sim = simulate_block(2, 100, preset="drone", side_overlap=0.4, seed=1)
    assert sim.truth.blunder_control == ()
    with pytest.raises(GeometryError, match=r'more than 20% of the control.*block = "models"'):
        adjust_block(
            sim.observations, sim.control, sim.crs, specs(sim), construction="strips", polynomial=0
        )


@pytest.mark.skipif(not (UAV / "GCP_UTM.txt").is_file(), reason=f"FC300X data not found in {UAV}")
def test_real_uav_block_of_strips_weighs_its_points_by_their_rays(tmp_path: Path):
    """``block = "strips"`` on the real FC300X block: its control cannot
    determine the strips' polynomial terms (all left out, a warning per
    strip), and the strips' points weighted by their rays put the check
    points at 0.030 / 0.025 m (0.125 / 0.045 m with one sigma per strip)."""
    from strip_aerotri.importers.common import write_project
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.project import load_project, run_project

    toml = write_project(import_uav_fc300x(UAV), tmp_path / "block")
    toml.write_text(toml.read_text() + '\n[adjustment]\nblock = "strips"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = run_project(load_project(toml))
    assert sum("polynomial term(s)" in w for w in result.warnings) == 3
    # the strips' own rejections and the check points not determined are told,
    # as one strip's run tells them (measured: 154 tie tests; '16' and '44')
    assert sum(w.startswith("tie_points:") for w in result.warnings) > 100
    assert any("check point '16' is not triangulated" in w for w in result.warnings)
    assert result.check_statistics.rmse_plan < 0.04
    assert result.check_statistics.rmse[2] < 0.035
