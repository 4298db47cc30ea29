"""Self-calibration in the bundle: the border's algebra against a dense
reference, the estimates against a simulated truth, the choice of "auto"."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import _observation_space as mapped

from strip_aerotri.bundle.adjust import bundle_adjust
from strip_aerotri.errors import GeometryError
from strip_aerotri.geometry.camera_model import BROWN_PARAMETERS, CameraModel, brown_correction
from strip_aerotri.geometry.collinearity import project
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.observations import ImageObservations, StripSpec
from strip_aerotri.options import SelfCalibration
from strip_aerotri.pipeline import triangulate_block
from strip_aerotri.simulate import simulate_block

C = 100.0


def _small_network(seed: int = 3) -> tuple[ImageObservations, np.ndarray, np.ndarray, np.ndarray]:
    """Three vertical photos over 30 points with relief, noise-free images of
    a camera with known errors."""
    rng = np.random.default_rng(seed)
    centres = np.array([[0.0, 0, 1000], [400, 0, 1010], [800, 0, 990]])
    rotations = matrix_from_rotvec(rng.normal(0, 0.01, (3, 3)))
    points = np.column_stack(
        [rng.uniform(100, 700, 30), rng.uniform(-450, 450, 30), rng.uniform(-80, 80, 30)]
    )
    photo, point = np.repeat(np.arange(3), 30), np.tile(np.arange(30), 3)
    xy, _ = project(centres, rotations, points, photo, point, C)
    keep = np.all(np.abs(xy) < 60.0, axis=1)
    obs = ImageObservations(
        ("a", "b", "c"),
        tuple(f"p{i}" for i in range(30)),
        photo[keep],
        point[keep],
        xy[keep] + rng.normal(0, 0.003, (int(keep.sum()), 2)),
        np.full(int(keep.sum()), 0.003),
        C,
    )
    return obs, centres, rotations, points


def _residuals(obs, model, centres, rotations, points, camera, control, c_sigma):  # type: ignore[no-untyped-def]
    xy, _ = project(centres, rotations, points, obs.photo, obs.point, C)
    img = mapped.residuals(model, camera, xy, obs.xy) / obs.sigma[:, None]
    ctrl = (points - control) / c_sigma
    return np.concatenate([img.ravel(), ctrl[np.isfinite(ctrl)]])


def test_border_cofactors_match_a_dense_inverse() -> None:
    """Camera cofactors, point and centre standard deviations of the bordered
    solution equal those of N^-1 formed densely from a finite-difference
    Jacobian of all observation equations at the solution."""
    obs, centres, rotations, points = _small_network()
    control = np.full_like(points, np.nan)
    control[:6] = points[:6]
    model = CameraModel("brown", ("k1", "p1", "b1"), C)
    res = bundle_adjust(
        obs, centres + 1.0, rotations, points - 1.0,
        control_xyz=control, control_sigma=0.05, camera=model,
    )
    assert res.camera is not None
    m, p = 3, 30
    x0 = np.concatenate([np.zeros(6 * m), res.points.ravel(), res.camera.values])

    def f(x: np.ndarray) -> np.ndarray:
        d = x[: 6 * m].reshape(m, 6)
        return _residuals(
            obs, model, res.centres + d[:, :3], res.rotations @ matrix_from_rotvec(d[:, 3:]),
            x[6 * m : 6 * m + 3 * p].reshape(p, 3), x[6 * m + 3 * p :], control, 0.05,
        )

    jac = np.empty((f(x0).size, x0.size))
    for i in range(x0.size):
        h = 1e-6 * max(1.0, abs(x0[i])) if i < 6 * m + 3 * p else 1e-4 * abs(x0[i]) + 1e-12
        e = np.zeros_like(x0)
        e[i] = h
        jac[:, i] = (f(x0 + e) - f(x0 - e)) / (2 * h)
    q = np.linalg.inv(jac.T @ jac)
    q_cam = q[6 * m + 3 * p :, 6 * m + 3 * p :]
    assert np.allclose(res.camera.cofactor, q_cam, rtol=2e-3)
    q_pts = np.diag(q)[6 * m : 6 * m + 3 * p].reshape(p, 3)
    assert np.allclose((res.point_std / res.sigma0) ** 2, q_pts, rtol=2e-3)
    q_cen = np.diag(q)[: 6 * m].reshape(m, 6)[:, :3]
    assert np.allclose((res.centre_std / res.sigma0) ** 2, q_cen, rtol=2e-3)
    assert res.redundancy == f(x0).size - x0.size


def test_border_recovers_noise_free_camera_errors() -> None:
    """Images made with known corrections: the adjustment finds them."""
    obs, centres, rotations, points = _small_network()
    truth = np.zeros(10)
    truth[[3, 6, 8]] = [-2e-6, 3e-5, 2e-4]
    # measured m with m + Δ(m) = ideal, by fixed point
    ideal = obs.xy.copy()
    m = ideal.copy()
    for _ in range(20):
        m = ideal - brown_correction(m, truth, C)
    noisy = ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo, obs.point, m, obs.sigma, C
    )
    control = np.full_like(points, np.nan)
    control[:6] = points[:6]
    res = bundle_adjust(
        noisy, centres, rotations, points, control_xyz=control, control_sigma=0.05,
        camera=CameraModel("brown", ("k1", "p1", "b1"), C),
    )
    assert res.camera is not None
    dev = (res.camera.values - truth[[3, 6, 8]]) / res.camera.std
    assert np.all(np.abs(dev) < 3.0), dev


def test_undetermined_parameter_is_named() -> None:
    """c with vertical photos over flat ground: GeometryError naming it."""
    obs, centres, rotations, points = _small_network()
    flat = points.copy()
    flat[:, 2] = 0.0
    photo, point = obs.photo, obs.point
    xy, _ = project(centres, np.broadcast_to(np.eye(3), (3, 3, 3)), flat, photo, point, C)
    obs = ImageObservations(obs.photo_ids, obs.point_ids, photo, point, xy, obs.sigma, C)
    control = flat.copy()
    control[6:] = np.nan
    with pytest.raises(GeometryError, match="camera parameter c is not determined"):
        bundle_adjust(
            obs, centres, np.broadcast_to(np.eye(3), (3, 3, 3)).copy(), flat,
            control_xyz=control, control_sigma=0.05,
            camera=CameraModel("brown", ("c",), C),
        )


# ---------------------------------------------------------------- simulated block

#: 30 µm radial at the corner of the drone format, decentring, affinity, shear
_DRONE_ERRORS = {"k1": -6.0e-5, "p1": 1.6e-4, "p2": -8.0e-5, "b1": 1.26e-3, "b2": 6.3e-4}


def _drone_block(errors: dict[str, float] | None):  # type: ignore[no-untyped-def]
    sim = simulate_block(3, 8, preset="drone", seed=2, crs="local", camera_errors=errors)
    return sim, [StripSpec(s.name, s.photo_ids) for s in sim.strips]


def _run(sim, specs, choice):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        return triangulate_block(
            sim.observations, sim.control, sim.crs, specs, route="projected", refine="bundle",
            self_calibration=None if choice is None else SelfCalibration(choice),
        )


def test_simulated_block_estimates_agree_with_the_truth() -> None:
    sim, specs = _drone_block(_DRONE_ERRORS)
    res = _run(sim, specs, tuple(_DRONE_ERRORS))
    sc = res.self_calibration
    assert sc is not None and sc.estimate is not None
    for par in sc.parameters:
        assert abs(par.value - _DRONE_ERRORS[par.name]) < 3.0 * par.std, par
        assert abs(par.t) > 3.0
    assert 0.9 < res.refined_sigma0 < 1.1


def test_auto_keeps_the_true_set_and_holds_the_rest() -> None:
    sim, specs = _drone_block(_DRONE_ERRORS)
    auto = _run(sim, specs, "auto")
    sc = auto.self_calibration
    assert sc is not None
    assert set(sc.kept) == set(_DRONE_ERRORS)
    held = {p.name: p.reason for p in sc.parameters if not p.kept}
    assert "flying height" in held["c"] and "exterior orientation" in held["x0"]
    assert any("self-calibration held" in w for w in auto.warnings)
    # the principal point is absorbed, yet the decentring is kept: here the
    # data separate it (multiple correlation below the bound it is then held to)
    from strip_aerotri.bundle.selfcal import INTERIOR_CORRELATION

    r_eo = {p.name: p.orientation_correlation for p in sc.parameters}
    assert r_eo["p1"] < INTERIOR_CORRELATION and r_eo["p2"] < INTERIOR_CORRELATION
    # as good as the explicit list of the true parameters
    given = _run(sim, specs, tuple(_DRONE_ERRORS))
    assert auto.check_statistics.rmse_plan <= 1.02 * given.check_statistics.rmse_plan
    assert auto.check_statistics.rmse[2] <= 1.02 * given.check_statistics.rmse[2]


def test_auto_leaves_an_error_free_block_as_it_is() -> None:
    sim, specs = _drone_block(None)
    none = _run(sim, specs, None)
    auto = _run(sim, specs, "auto")
    assert auto.check_statistics.rmse_plan <= 1.02 * none.check_statistics.rmse_plan
    assert auto.check_statistics.rmse[2] <= 1.02 * none.check_statistics.rmse[2]


def test_self_calibration_options() -> None:
    with pytest.raises(ValueError, match="unknown parameter .k9."):
        SelfCalibration(("k1", "k9"))
    with pytest.raises(ValueError):
        SelfCalibration("everything")
    assert SelfCalibration("ebner12").family == "ebner"
    assert set(BROWN_PARAMETERS) >= set(_DRONE_ERRORS)


# ---------------------------------------------------------------- project file


def _project(tmp_path, adjustment: str):  # type: ignore[no-untyped-def]
    import shutil
    from pathlib import Path

    folder = tmp_path / "p"
    shutil.copytree(Path(__file__).parent / "data" / "minimal", folder)
    toml = folder / "strip.toml"
    toml.write_text(toml.read_text() + "\n[adjustment]\n" + adjustment + "\n")
    return toml


@pytest.mark.parametrize(
    ("adjustment", "message"),
    [
        ('self_calibration = "auto"', r'self_calibration: .*add refine = "bundle"'),
        ('refine = "bundle"\nself_calibration = ["k1", "k9"]', r"unknown parameter 'k9'"),
        ('refine = "bundle"\nself_calibration = ["k1", "k1"]', r"'k1' is listed twice"),
        ('refine = "bundle"\nself_calibration = "all"', r'expected "none", "auto", "ebner12"'),
    ],
)
def test_bad_self_calibration_is_one_line(tmp_path, adjustment: str, message: str) -> None:  # type: ignore[no-untyped-def]
    from strip_aerotri.errors import ConfigError
    from strip_aerotri.project import load_project

    toml = _project(tmp_path, adjustment)
    with pytest.raises(ConfigError, match=message) as info:
        load_project(toml)
    assert "strip.toml" in str(info.value) and "\n" not in str(info.value)


def test_self_calibration_is_read(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from strip_aerotri.project import load_project

    toml = _project(tmp_path, 'refine = "bundle"\nself_calibration = ["K2", "k1"]')
    adj = load_project(toml).adjustment
    assert adj.self_calibration == ("k1", "k2")
    spec = adj.calibration("+y")
    assert spec is not None and spec.choice == ("k1", "k2") and spec.flight_direction.value == "+y"
    plain = load_project(_project(tmp_path / "b", 'refine = "bundle"')).adjustment
    assert plain.self_calibration == "none" and plain.calibration("+x") is None


# ---------------------------------------------------------------- systematic errors


def test_systematic_pattern_tells_camera_errors_from_blunders() -> None:
    from strip_aerotri.ground.systematic import systematic_message, systematic_pattern

    rng = np.random.default_rng(4)
    # a deformation: many points fail at similar test values
    w = rng.normal(0, 1.5, (14, 3))
    w[[0, 3, 6, 9, 12], 2] = [-4.9, 5.1, 4.4, -4.7, 5.5]
    assert systematic_pattern(w, 4.1)
    assert "5 of 14 control points" in systematic_message("control", w, 4.1)
    # one gross error dragging two neighbours over the limit: not systematic
    g = rng.normal(0, 1.0, (14, 3))
    g[5, 2], g[[4, 6], 2] = 40.0, [5.0, -4.5]
    assert not systematic_pattern(g, 4.1)
    # two failing points are "one or two points", and 3 points too few to judge
    two = rng.normal(0, 1.0, (14, 3))
    two[[2, 9], 0] = [6.0, -5.5]
    assert not systematic_pattern(two, 4.1)
    assert not systematic_pattern(w[[0, 3, 6]], 4.1)


def test_camera_errors_are_not_blunders_in_the_default_construction() -> None:
    """The film strip of the camera-error family: radial distortion (30 µm at
    100 mm) and 60 ppm affinity fail much of the control; the default
    construction keeps it, warns and names the remedy; the bundle with
    "auto" calibrates the camera."""
    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.options import GroundOptions
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(12, seed=1, crs="local", systematic_k1=3e-8, film_shrink_y=1 + 60e-6)
    opts = GroundOptions(route="projected")
    with pytest.warns(StripAerotriWarning, match="fail the blunder test alike.*self_calibration"):
        strip = triangulate(sim.observations, sim.control, sim.crs, ground_options=opts)
    assert not any(r.stage == "control" and r.applied for r in strip.ground.rejections)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        auto = triangulate(
            sim.observations, sim.control, sim.crs, ground_options=opts, refine="bundle",
            self_calibration=SelfCalibration("auto"),
        )
    assert auto.refined is not None and auto.refined.self_calibration is not None
    assert "k1" in auto.refined.self_calibration.kept
    assert auto.refined.check_statistics.rmse[2] < 0.5 * strip.check_statistics.rmse[2]


# ---------------------------------------------------------------- outputs


def test_camera_toml_calibrates_the_next_project(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The adjusted camera is written to camera.toml and report.json; a
    project with those tables runs the strip method on the calibrated camera:
    the control no longer fails alike and the height errors shrink."""
    import json
    import re

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.options import GroundOptions
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project
    from strip_aerotri.report.outputs import build_outputs
    from strip_aerotri.simulate import simulate_strip
    from strip_aerotri.simulate.writer import write_strip_project

    sim = simulate_strip(12, seed=1, crs="local", systematic_k1=3e-8, film_shrink_y=1 + 60e-6)
    toml = write_strip_project(tmp_path / "a", sim.observations, sim.control, sim.crs, name="a")
    plain = toml.read_text()
    with_adjustment = re.sub(
        r"\[adjustment\]\n", '[adjustment]\nrefine = "bundle"\nself_calibration = "auto"\n', plain
    )
    assert with_adjustment != plain
    toml.write_text(with_adjustment)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        project = load_project(toml)
        files = build_outputs(run_project(project), project=project, html=False)
    record = json.loads(files["report.json"])["bundle"]["self_calibration"]
    assert record["kept"] == ["k1"] and record["camera"]["distortion_fit_rms_um"] < 1e-3
    k1 = next(p for p in record["parameters"] if p["name"] == "k1")
    assert abs(k1["estimate"] + 3e-8) < 3 * k1["sd"]  # the simulated 30 µm at 100 mm
    camera = files["camera.toml"].decode()
    # the fit's RMS in plain figures (it read "within 8.28e-15 µm RMS")
    fit = re.search(r"within (\S+) µm RMS", camera)
    assert fit is not None and re.fullmatch(r"\d+\.\d{3}", fit.group(1)), camera
    fit_rms_um = record["camera"]["distortion_fit_rms_um"]
    assert float(fit.group(1)) == pytest.approx(fit_rms_um, abs=5e-4)
    # the next project: the same data with camera.toml's tables, the strip method
    nxt = tmp_path / "b" / "strip.toml"
    nxt.parent.mkdir()
    for name in ("image_points.csv", "control.csv"):
        (nxt.parent / name).write_bytes((toml.parent / name).read_bytes())
    nxt.write_text(re.sub(r"\[camera\]\n[^\[]*", "", plain) + "\n" + camera)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        calibrated = run_project(load_project(nxt))
    assert not any("alike" in str(w.message) for w in caught)
    with pytest.warns(StripAerotriWarning, match="alike"):  # the same data, uncalibrated
        before = triangulate(
            sim.observations, sim.control, sim.crs, ground_options=GroundOptions(route="projected")
        )
    assert calibrated.check_statistics.rmse[2] < 0.6 * before.check_statistics.rmse[2]


# ---------------------------------------------------------------- simulator


def test_simulator_camera_errors_are_the_corrections_needed() -> None:
    """Off by default (the same observations bit for bit); on, the measured
    coordinates m satisfy m + Δ(m) = the error-free measurement."""
    from strip_aerotri.simulate import simulate_strip

    plain = simulate_strip(8, seed=3, crs="local")
    none = simulate_strip(8, seed=3, crs="local", camera_errors={})
    assert np.array_equal(plain.observations.xy, none.observations.xy)
    errors = {"k1": -3e-8, "p1": 2e-6, "b1": 6e-5, "b2": -2e-5}
    bent = simulate_strip(8, seed=3, crs="local", camera_errors=errors)
    pa, pb = plain.observations, bent.observations
    key_a = {
        (pa.photo_ids[f], pa.point_ids[q]): k
        for k, (f, q) in enumerate(zip(pa.photo, pa.point, strict=True))
    }
    pairs = np.array(
        [
            (key_a[(pb.photo_ids[f], pb.point_ids[q])], k)
            for k, (f, q) in enumerate(zip(pb.photo, pb.point))
            if (pb.photo_ids[f], pb.point_ids[q]) in key_a
        ]
    )
    assert pairs.shape[0] > 0.95 * pa.photo.size
    values = np.array([errors.get(n, 0.0) for n in BROWN_PARAMETERS])
    m = pb.xy[pairs[:, 1]]
    back = m + brown_correction(m, values, pb.principal_distance)
    assert np.max(np.abs(m - pa.xy[pairs[:, 0]])) > 0.01  # the errors are there (> 10 µm)
    # and exactly these: the noise is added after the errors, so Δ is evaluated
    # at m + noise instead of m (|dΔ/dxy| ~1e-3 times 5 µm of noise)
    assert np.max(np.abs(back - pa.xy[pairs[:, 0]])) < 1e-4
    with pytest.raises(ValueError, match="Unknown camera error"):
        simulate_strip(8, seed=3, crs="local", camera_errors={"k4": 1.0})


def test_simulate_command_writes_camera_errors(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli as main

    runner = CliRunner()
    ok = runner.invoke(
        main, ["simulate", "film", "--out", str(tmp_path / "a"), "--camera-error", "k1=-3e-8"]
    )
    assert ok.exit_code == 0, ok.output
    bad = runner.invoke(
        main, ["simulate", "film", "--out", str(tmp_path / "b"), "--camera-error", "k9=1"]
    )
    assert bad.exit_code == 2 and "--camera-error" in bad.output


def test_gnss_centres_separate_c_from_the_flying_height() -> None:
    """c is held over flat ground without GNSS (correlation 1 with the
    heights of the photos), and estimated with GNSS centres, within 3 sd of
    the simulated error."""
    from strip_aerotri.observations import GnssCentres

    errors = {"c": 0.05, "k1": -6e-5}
    sim = simulate_block(3, 8, preset="drone", seed=2, crs="local", camera_errors=errors)
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    m = sim.truth.photo_centres_crs.shape[0]
    noise = np.random.default_rng(1).normal(0, 0.02, (m, 3))
    gnss = GnssCentres(
        tuple(sim.observations.photo_ids),
        sim.truth.photo_centres_crs + noise,
        np.full(m, 0.02),
        np.full(m, 0.02),
    )
    outcomes = {}
    for label, g in (("none", None), ("gnss", gnss)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = triangulate_block(
                sim.observations, sim.control, sim.crs, specs, route="projected",
                refine="bundle", gnss=g, self_calibration=SelfCalibration("auto"),
            )
        assert res.self_calibration is not None
        outcomes[label] = {p.name: p for p in res.self_calibration.parameters}
    held = outcomes["none"]["c"]
    assert not held.kept and "flying height" in held.reason
    c = outcomes["gnss"]["c"]
    assert c.kept and c.orientation_correlation < 0.999
    assert abs(c.value - errors["c"]) < 3 * c.std


def test_ebner12_finds_a_film_affinity() -> None:
    """A film affinity b1 (Δx = b1 x) is Ebner's e1 (x, -y) times b1/2 plus a
    scale that the flying height takes: e1 = b1/2 within 3 sd, the eleven
    others zero within 3 sd."""
    from strip_aerotri.options import GroundOptions
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.simulate import simulate_strip

    b1 = 1.2e-4
    sim = simulate_strip(12, seed=1, crs="local", camera_errors={"b1": b1}, control="dense")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = triangulate(
            sim.observations, sim.control, sim.crs,
            ground_options=GroundOptions(route="projected"),
            refine="bundle", self_calibration=SelfCalibration("ebner12"),
        )
    assert res.refined is not None and res.refined.self_calibration is not None
    for p in res.refined.self_calibration.parameters:
        truth = b1 / 2 if p.name == "e1" else 0.0
        assert p.kept and abs(p.value - truth) < 3 * p.std, p


def test_a_block_writes_its_camera() -> None:
    """A block's outputs carry the self-calibration as a strip's do."""
    import json

    from strip_aerotri.report.block import build_block_outputs

    sim, specs = _drone_block(_DRONE_ERRORS)
    res = _run(sim, specs, "auto")
    files = build_block_outputs(res)
    record = json.loads(files["report.json"])["bundle"]["self_calibration"]
    assert set(record["kept"]) == set(_DRONE_ERRORS)
    assert {p["name"] for p in record["parameters"]} == set(BROWN_PARAMETERS)
    assert "[distortion]" in files["camera.toml"].decode()
    page = files["report.html"].decode()
    assert "Self-calibration of the camera" in page and page.count("data:image/png") >= 3


def test_auto_with_estimated_weights_keeps_its_choice_and_reasons() -> None:
    """With the weights estimated the later adjustments estimate the set the
    first one chose, and the outcome keeps the reasons of the held ones."""
    from strip_aerotri.block.strips import adjust_block

    sim, specs = _drone_block(_DRONE_ERRORS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = adjust_block(
            sim.observations, sim.control, sim.crs, specs, route="projected", refine=True,
            self_calibration=SelfCalibration("auto"), variance_components=True,
        )  # fmt: skip
    sc = res.self_calibration
    assert sc is not None and set(sc.kept) == set(_DRONE_ERRORS)
    held = {p.name: p.reason for p in sc.parameters if not p.kept}
    assert "flying height" in held["c"] and "exterior orientation" in held["x0"]
    assert res.variance_components is not None and res.variance_components.iterations >= 1
    assert sc.estimate is not None
    for par in sc.parameters:
        if par.kept:
            assert abs(par.value - _DRONE_ERRORS[par.name]) < 3.0 * par.std, par


def test_auto_that_keeps_nothing_still_reports_its_choice() -> None:
    """An error-free 6-photo film strip in a projected CRS: "auto" holds every
    parameter and the second plan/height pass adjusts without a camera; the
    outcome still names every candidate held, with its reason, and the
    warning says so (the second pass used to drop the outcome: no
    self-calibration section, no camera.toml)."""
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(6, preset="film", crs="EPSG:32634", seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = triangulate(
            sim.observations, sim.control, sim.crs, refine="bundle",
            self_calibration=SelfCalibration("auto"),
        )  # fmt: skip
    assert res.refined is not None
    sc = res.refined.self_calibration
    assert sc is not None and sc.kept == ()
    held = {p.name: p.reason for p in sc.parameters}
    assert set(held) == set(BROWN_PARAMETERS)
    assert "flying height" in held["c"] and all(held.values())
    assert any("self-calibration held" in w for w in res.warnings)


def test_auto_trials_do_not_warn_of_their_convergence() -> None:
    """The trials of "auto" with c, x0 and y0 (correlation 1 with the
    orientation on a flat drone strip) run out of iterations; that is what
    holds them, and the delivered adjustment converges: no warning of a
    bundle adjustment that did not converge reaches the user."""
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(12, preset="drone", crs="EPSG:32634", seed=0)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = triangulate(
            sim.observations, sim.control, sim.crs, refine="bundle",
            self_calibration=SelfCalibration("auto"),
        )  # fmt: skip
    assert res.refined is not None and res.refined.converged
    assert res.refined.self_calibration is not None
    assert not [w for w in seen if "did not converge" in str(w.message)]
    assert not [w for w in res.warnings if "did not converge" in w]
