"""Tests of interior orientation: pixels, flight axes, distortion, fiducials."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError, ConvergenceError, GeometryError
from strip_aerotri.interior import (
    BrownDistortion,
    correct_distortion,
    distortion_shift,
    fit_fiducial_transform,
    flight_from_sensor,
    mm_from_pixel,
    reduce_image_coordinates,
    sensor_from_flight,
)
from strip_aerotri.project import load_project

RNG = np.random.default_rng(2345)


# --------------------------------------------------------------------------- pixels


def test_mm_from_pixel_rows_grow_downwards() -> None:
    # a pixel right of and above the centre: x > 0, y > 0
    xy = mm_from_pixel([[2010.0, 1490.0], [2000.0, 1500.0]], 0.002, [2000.0, 1500.0])
    np.testing.assert_allclose(xy, [[0.02, 0.02], [0.0, 0.0]], atol=1e-15)


def test_mm_from_pixel_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="pixel_size_mm"):
        mm_from_pixel([[0.0, 0.0]], 0.0, [0.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        mm_from_pixel([0.0, 0.0, 0.0], 0.002, [0.0, 0.0])


# --------------------------------------------------------------------------- flight axes


@pytest.mark.parametrize(
    ("direction", "expected"),
    [("+x", [1.0, 2.0]), ("-x", [-1.0, -2.0]), ("+y", [2.0, -1.0]), ("-y", [-2.0, 1.0])],
    ids=["+x", "-x", "+y", "-y"],
)
def test_flight_from_sensor(direction: str, expected: list[float]) -> None:
    xy = flight_from_sensor([[1.0, 2.0]], direction)
    np.testing.assert_array_equal(xy[0], expected)
    np.testing.assert_array_equal(sensor_from_flight(xy, direction), [[1.0, 2.0]])


@pytest.mark.parametrize("direction", ["+x", "-x", "+y", "-y"])
def test_flight_axes_are_a_proper_rotation(direction: str) -> None:
    m = flight_from_sensor(np.eye(2), direction).T
    assert np.linalg.det(m) == pytest.approx(1.0)


def test_flight_direction_plus_y_puts_the_motion_on_x() -> None:
    # the camera moves along sensor +y: ground points move to -y on the next photo
    # (tie points of the FC300X strip: mean shift (-0.06, -0.16) mm, data README)
    shift = flight_from_sensor([[-0.06, -0.16]], "+y")[0]
    assert shift[0] < 0 and abs(shift[0]) > abs(shift[1])  # like a film strip along +x


# --------------------------------------------------------------------------- distortion


def test_brown_distortion_hand_computed() -> None:
    # x = 3, y = 4, r^2 = 25: radial 0.001*25 = 0.025 -> (0.075, 0.1);
    # decentring p1 (r^2 + 2x^2) + 2 p2 x y = 1e-4*43 + 2e-4*12 = 0.0067,
    # 2 p1 x y + p2 (r^2 + 2y^2) = 1e-4*24 + 1e-4*57 = 0.0081
    d = BrownDistortion(k1=0.001, p1=1e-4, p2=1e-4)
    np.testing.assert_allclose(distortion_shift([[3.0, 4.0]], d, 10.0), [[0.0817, 0.1081]])
    np.testing.assert_allclose(correct_distortion([[3.0, 4.0]], d, 10.0), [[3.0817, 4.1081]])


def test_normalized_units_equal_scaled_mm_coefficients() -> None:
    c = 3.6
    xy = RNG.uniform(-3, 3, (50, 2))
    normalized = BrownDistortion(
        k1=-0.012, k2=0.01, k3=-0.002, p1=1e-4, p2=-2e-4, units="normalized"
    )
    mm = BrownDistortion(
        k1=-0.012 / c**2, k2=0.01 / c**4, k3=-0.002 / c**6, p1=1e-4 / c, p2=-2e-4 / c
    )
    np.testing.assert_allclose(
        distortion_shift(xy, normalized, c), distortion_shift(xy, mm, c), atol=1e-15
    )


def test_projection_model_is_inverted() -> None:
    d = BrownDistortion(k1=-9e-4, k2=1e-5, p1=1e-5, p2=-2e-5, model="projection")
    ideal = RNG.uniform(-3, 3, (100, 2))
    measured = ideal + distortion_shift(ideal, d, 3.6)
    np.testing.assert_allclose(correct_distortion(measured, d, 3.6), ideal, atol=1e-9)


def test_projection_inversion_failure_is_a_convergence_error() -> None:
    d = BrownDistortion(k1=1.0, model="projection")  # r^2 of 25 mm^2: no fixed point
    with pytest.raises(ConvergenceError, match="did not converge"):
        correct_distortion([[3.0, 4.0]], d, 10.0)


def test_zero_distortion_is_a_copy() -> None:
    xy = np.array([[1.0, 2.0]])
    out = correct_distortion(xy, BrownDistortion(), 10.0)
    np.testing.assert_array_equal(out, xy)
    assert out is not xy


def test_inputs_are_not_modified() -> None:
    xy = np.array([[2010.0, 1490.0]])
    before = xy.copy()
    reduce_image_coordinates(
        xy,
        [0],
        3.6,
        units="pixel",
        pixel_size_mm=0.002,
        principal_point_px=[2000, 1500],
        distortion=BrownDistortion(k1=1e-3),
        flight_direction="+y",
    )
    np.testing.assert_array_equal(xy, before)


# --------------------------------------------------------------------------- fiducials

# Calibrated marks of a 230 mm film camera, corner marks at +-106 mm (RMK-like).
MARKS = np.array([[-106.0, -106.0], [106.0, -106.0], [106.0, 106.0], [-106.0, 106.0]])


def _comparator(scale_x: float, scale_y: float, angle: float, shift: tuple[float, float]):
    # calibrated = A @ comparator + t  ->  comparator = A^-1 (calibrated - t)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    a = rot @ np.diag([scale_x, scale_y])
    return (MARKS - shift) @ np.linalg.inv(a).T


def test_affine_recovers_deformation_coefficients() -> None:
    comp = _comparator(1.0002, 1.00023, 0.01, (120.0, 95.0))
    fit = fit_fiducial_transform(comp, MARKS, "affine", photo_id="1201")
    assert fit.scale_x == pytest.approx(1.0002, abs=1e-12)
    assert fit.scale_y == pytest.approx(1.00023, abs=1e-12)
    assert fit.rotation == pytest.approx(0.01, abs=1e-12)
    np.testing.assert_allclose(fit.residuals, 0.0, atol=1e-11)
    np.testing.assert_allclose(fit.apply(comp), MARKS, atol=1e-11)
    assert fit.passed  # |s-1| = 2e-4 <= 5e-4 and |sx-sy| = 3e-5 <= 5e-5 (R4 1.7.7.1)


@pytest.mark.parametrize(
    ("sx", "sy", "scale_ok", "difference_ok"),
    [
        (1.0006, 1.0006, False, True),  # 6 units of the 4th decimal
        (1.0002, 1.00028, True, False),  # difference 8 units of the 5th decimal
        (0.9999, 0.99994, True, True),
    ],
)
def test_r4_1_7_7_1_verdicts(sx: float, sy: float, scale_ok: bool, difference_ok: bool) -> None:
    fit = fit_fiducial_transform(_comparator(sx, sy, -0.02, (5.0, 7.0)), MARKS, "affine")
    assert (fit.scale_ok, fit.difference_ok) == (scale_ok, difference_ok)
    assert (fit.message() == "") == (scale_ok and difference_ok)


def test_similarity_has_one_scale_and_residuals_show_affinity() -> None:
    comp = _comparator(1.0, 1.001, 0.0, (0.0, 0.0))
    fit = fit_fiducial_transform(comp, MARKS, "similarity")
    assert fit.scale_x == pytest.approx(fit.scale_y, abs=1e-15)
    assert fit.rms_mm > 0.01  # 0.1 % affinity over 212 mm does not fit a similarity


def test_too_few_marks() -> None:
    with pytest.raises(GeometryError, match="at least 3"):
        fit_fiducial_transform(MARKS[:2], MARKS[:2], "affine")
    with pytest.raises(GeometryError, match="one line"):
        line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
        fit_fiducial_transform(line, line, "affine")


# --------------------------------------------------------------------------- project loading


def _write(folder: Path, toml_extra: str, images: str, *, fiducials: str | None = None) -> Path:
    (folder / "image_points.csv").write_text(images)
    (folder / "control.csv").write_text("point,X,Y,H,type\nA,0,0,0,full\n")
    if fiducials is not None:
        (folder / "fid.csv").write_text(fiducials)
    toml = (
        '[strip]\nphotos = ["1", "2"]\n[camera]\nprincipal_distance_mm = 152.0\n'
        'principal_point_mm = [0.01, -0.02]\n[images]\nfile = "image_points.csv"\n'
        '[control]\nfile = "control.csv"\ncrs = "local"\n' + toml_extra
    )
    path = folder / "strip.toml"
    path.write_text(toml)
    return path


IMAGES = "photo,point,x,y\n1,A,1.0,2.0\n2,A,-1.0,2.5\n"


def test_project_without_new_keys_is_unchanged(tmp_path: Path) -> None:
    project = load_project(_write(tmp_path, "", IMAGES))
    np.testing.assert_allclose(project.observations.xy, [[0.99, 2.02], [-1.01, 2.52]])
    assert project.distortion is None and project.fiducials == ()


def test_project_flight_direction_and_distortion(tmp_path: Path) -> None:
    extra = "[distortion]\nk1 = 0.001\n"
    toml = _write(tmp_path, extra, IMAGES)
    text = toml.read_text().replace("[control]", 'flight_direction = "+y"\n[control]')
    toml.write_text(text)
    project = load_project(toml)
    reduced = np.array([[0.99, 2.02], [-1.01, 2.52]])
    corrected = reduced * (1 + 0.001 * np.sum(reduced**2, axis=1))[:, None]
    expected = np.column_stack([corrected[:, 1], -corrected[:, 0]])
    np.testing.assert_allclose(project.observations.xy, expected, atol=1e-15)


def test_project_pixels(tmp_path: Path) -> None:
    images = "photo,point,x,y\n1,A,2010,1490\n2,A,2000,1500\n"
    extra = ""
    toml = _write(tmp_path, extra, images)
    text = toml.read_text().replace(
        "[control]",
        'units = "pixel"\npixel_size_mm = 0.002\nprincipal_point_px = [2000, 1500]\n[control]',
    )
    toml.write_text(text)
    project = load_project(toml)
    np.testing.assert_allclose(project.observations.xy, [[0.01, 0.04], [-0.01, 0.02]], atol=1e-15)


@pytest.mark.parametrize(
    ("images_keys", "match"),
    [
        ('units = "pixel"\npixel_size_mm = 0.002', "principal_point_px: required"),
        ("pixel_size_mm = 0.002", 'with units = "mm" give principal_point_px too'),
        ('flight_direction = "y"', 'expected one of "\\+x", "-x", "\\+y", "-y"'),
    ],
)
def test_project_bad_image_keys(tmp_path: Path, images_keys: str, match: str) -> None:
    toml = _write(tmp_path, "", IMAGES)
    toml.write_text(toml.read_text().replace("[control]", images_keys + "\n[control]"))
    with pytest.raises(ConfigError, match=match):
        load_project(toml)


FIDUCIAL_TOML = (
    '[interior_orientation]\nfiducials_file = "fid.csv"\ntransform = "affine"\n'
    'calibrated = { "1" = [-106.0, -106.0], "2" = [106.0, -106.0], "3" = [106.0, 106.0], '
    '"4" = [-106.0, 106.0] }\n'
)


def _fiducial_csv(scale_y: float = 1.0002) -> str:
    rows = ["photo,mark,x,y"]
    for photo, shift in (("1", (120.0, 95.0)), ("2", (118.0, 97.0))):
        comp = _comparator(1.0002, scale_y, 0.003, shift)
        rows += [f"{photo},{m + 1},{x:.12f},{y:.12f}" for m, (x, y) in enumerate(comp)]
    return "\n".join(rows) + "\n"


def test_project_fiducials(tmp_path: Path) -> None:
    comp = _comparator(1.0002, 1.0002, 0.003, (120.0, 95.0))
    fit = fit_fiducial_transform(comp, MARKS)
    measured = (comp[0] + comp[2]) / 2 + [3.0, -4.0]  # some point of photo 1
    images = f"photo,point,x,y\n1,A,{measured[0]:.12f},{measured[1]:.12f}\n2,A,0,0\n"
    project = load_project(_write(tmp_path, FIDUCIAL_TOML, images, fiducials=_fiducial_csv()))
    assert len(project.fiducials) == 2 and all(f.passed for f in project.fiducials)
    expected = fit.apply([measured])[0] - [0.01, -0.02]
    np.testing.assert_allclose(project.observations.xy[0], expected, atol=1e-10)
    assert project.fiducials_file in project.input_files
    assert not any("1.7.7.1" in w for w in project.warnings)


def test_project_fiducials_warn_on_r4_failure(tmp_path: Path) -> None:
    project = load_project(
        _write(tmp_path, FIDUCIAL_TOML, IMAGES, fiducials=_fiducial_csv(scale_y=1.0012))
    )
    failed = [w for w in project.warnings if "1.7.7.1" in w]
    assert len(failed) == 2 and "photo '1'" in failed[0]


@pytest.mark.parametrize(
    ("fiducials", "match"),
    [
        ("photo,mark,x,y\n1,9,0,0\n", "fid.csv:2: mark '9' is not in"),
        ("photo,mark,x,y\n7,1,0,0\n", "fid.csv:2: photo '7' is not in"),
        ("photo,mark,x,y\n1,1,0,0\n1,1,1,1\n", "listed twice"),
        ("photo,mark,x,y\n1,1,0,0\n", "photo '1' has 1 fiducial mark"),
    ],
)
def test_project_bad_fiducials(tmp_path: Path, fiducials: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        load_project(_write(tmp_path, FIDUCIAL_TOML, IMAGES, fiducials=fiducials))
