"""The importers' shared part: TOML and CSV writing, strips, flight direction, control split."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError
from strip_aerotri.importers.common import (
    Camera,
    ControlTable,
    ImageFrame,
    ImageTable,
    ImportOptions,
    Strip,
    assemble,
    decide_flight_direction,
    natural_key,
    photo_id,
    split_control,
    strips_from_positions,
    toml_value,
    write_project,
)
from strip_aerotri.geodesy import grid_convergence_deg
from strip_aerotri.project import load_project

# --------------------------------------------------------------------------- a small strip


def _strip_images(n_photos=4, shift=(0.0, -20.0), ids=None):
    """Image points (mm) of a grid seen on consecutive photos that move along image +y.

    Each point moves by ``shift`` mm from one photo to the next (the camera
    moves the other way).
    """
    rng = np.random.default_rng(2345)
    grid = rng.uniform(-40.0, 40.0, (30, 2)) + np.array([0.0, 60.0])
    photos, points, xy = [], [], []
    names = ids or [f"P{k}" for k in range(n_photos)]
    for k, name in enumerate(names):
        here = grid + np.asarray(shift) * k
        inside = np.all(np.abs(here) < 50.0, axis=1)
        photos += [name] * int(inside.sum())
        points += [f"{j:03d}" for j in np.flatnonzero(inside)]
        xy.append(here[inside])
    xy = np.concatenate(xy)
    return ImageTable(photos, points, xy)


def _control(images: ImageTable, n=8) -> ControlTable:
    pts = np.unique(images.point)[:n]
    xyz = np.column_stack([np.arange(n) * 10.0, (np.arange(n) % 2) * 50.0, np.full(n, 100.0)])
    return ControlTable(pts, xyz)


# --------------------------------------------------------------------------- TOML / ids


@pytest.mark.parametrize(
    "text",
    ["plain", 'quote " and \\ backslash', "tab\tnew\nline", "ünïcode ø", "\x7f"],
    ids=["plain", "quote", "control", "unicode", "del"],
)
def test_toml_string_round_trips_through_tomllib(text: str) -> None:
    doc = tomllib.loads(f"key = {toml_value(text)}\nlist = {toml_value([text, 1.5, 2, True])}")
    assert doc["key"] == text
    assert doc["list"] == [text, 1.5, 2, True]


def test_toml_value_refuses_nan() -> None:
    with pytest.raises(ValueError, match="no value"):
        toml_value(float("nan"))


def test_photo_id_strips_folders_and_extension() -> None:
    got = photo_id(["images/DJI_0001.JPG", "C:\\f\\DJI_0002.jpg", "1203", "a.b.tif"])
    assert got.tolist() == ["DJI_0001", "DJI_0002", "1203", "a.b"]


def test_natural_key_orders_numbers_as_numbers() -> None:
    assert sorted(["B1_10", "B1_2", "B2_1", "B1_1"], key=natural_key) == [
        "B1_1",
        "B1_2",
        "B1_10",
        "B2_1",
    ]


# --------------------------------------------------------------------------- rotations


def test_grid_convergence_has_the_sign_of_conventions_md() -> None:
    # docs/conventions.md: +2.12 deg at 24 deg E, 45 deg N in UTM zone 34N
    from pyproj import Transformer

    e, n = Transformer.from_crs("EPSG:4326", "EPSG:32634", always_xy=True).transform(24.0, 45.0)
    gamma = grid_convergence_deg("EPSG:32634", np.array([[e, n]]))
    assert gamma[0] == pytest.approx(2.12, abs=0.01)
    assert grid_convergence_deg("local", np.zeros((3, 2))).tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match="not a projected CRS"):
        grid_convergence_deg("EPSG:4326", np.array([[24.0, 45.0]]))


# --------------------------------------------------------------------------- strips


def _track():
    """Two lines 40 m apart flown north then south, one photo in the turn."""
    north = [(0.0, 15.0 * k, 160.0) for k in range(5)]
    turn = [(20.0, 70.0, 160.0)]
    south = [(40.0, 60.0 - 15.0 * k, 160.0) for k in range(5)]
    names = [f"DJI_{k + 1:04d}" for k in range(11)]
    return names, np.array(north + turn + south)


def test_strips_split_at_the_turn_and_drop_the_turn_photo() -> None:
    names, xyz = _track()
    strips, dropped = strips_from_positions(names, xyz)
    assert strips == [tuple(names[:5]), tuple(names[6:])]
    assert dropped == ["DJI_0006"]


def test_strips_are_ordered_along_their_direction_whatever_the_input_order() -> None:
    names, xyz = _track()
    order = np.random.default_rng(2345).permutation(len(names))
    strips, _ = strips_from_positions([names[k] for k in order], xyz[order])
    assert strips == [tuple(names[:5]), tuple(names[6:])]


def test_strips_from_positions_refuses_photos_at_one_place() -> None:
    with pytest.raises(ConfigError, match="one place"):
        strips_from_positions(["a", "b", "c"], np.full((3, 3), 5.0))


# --------------------------------------------------------------------------- flight direction


def test_flight_direction_from_the_shift_of_the_points() -> None:
    images = _strip_images()  # points move along -y: the camera along +y
    strips = [Strip("1", ("P0", "P1", "P2", "P3"))]
    direction, out, _, warnings = decide_flight_direction(images, ImageFrame(), strips)
    assert direction == "+y"
    assert out == strips
    assert not warnings


def test_flight_direction_reverses_a_strip_flown_back() -> None:
    images = _strip_images()
    forward = Strip("1", ("P0", "P1", "P2", "P3"))
    back = Strip("2", ("P3", "P2", "P1", "P0"))  # the same photos listed the other way
    assert decide_flight_direction(images, ImageFrame(), [forward])[1] == [forward]
    _, out_back, notes_back, _ = decide_flight_direction(images, ImageFrame(), [back], "+y")
    assert out_back[0].photos == forward.photos
    assert any("reverse" in n for n in notes_back)


def test_flight_direction_in_pixels_turns_the_row_axis() -> None:
    # rows grow downwards: a shift of -y in mm is +row in pixels
    mm = _strip_images()
    frame = ImageFrame("pixel", 0.01, (0.0, 0.0))
    px = ImageTable(mm.photo, mm.point, np.column_stack([mm.xy[:, 0] / 0.01, -mm.xy[:, 1] / 0.01]))
    direction, *_ = decide_flight_direction(px, frame, [Strip("1", ("P0", "P1", "P2", "P3"))])
    assert direction == "+y"


def test_flight_direction_needs_common_points_or_an_option() -> None:
    images = ImageTable(["a", "b"], ["1", "2"], [[0.0, 0.0], [1.0, 1.0]])
    strips = [Strip("1", ("a", "b"))]
    with pytest.raises(ConfigError, match="--flight-direction"):
        decide_flight_direction(images, ImageFrame(), strips)
    direction, _, _, warnings = decide_flight_direction(images, ImageFrame(), strips, "-x")
    assert direction == "-x"
    assert warnings


def test_strips_moving_along_different_axes_are_refused() -> None:
    a = _strip_images(ids=["a0", "a1", "a2"])
    b = _strip_images(ids=["b0", "b1", "b2"], shift=(-20.0, 0.0))
    images = ImageTable.concat([a, ImageTable(b.photo, np.char.add("b", b.point), b.xy)])
    strips = [Strip("1", ("a0", "a1", "a2")), Strip("2", ("b0", "b1", "b2"))]
    with pytest.raises(ConfigError, match="different image axes"):
        decide_flight_direction(images, ImageFrame(), strips)


# --------------------------------------------------------------------------- control / check


def test_split_control_options() -> None:
    images = _strip_images()
    control = _control(images)
    strips = [Strip("1", ("P0", "P1", "P2", "P3"))]
    ids = control.point.tolist()
    table, _ = split_control(control, images, strips, control_ids=ids[:3])
    assert table.kind.tolist() == ["full"] * 3 + ["check"] * 5
    table, _ = split_control(control, images, strips, check_ids=ids[:2])
    assert table.kind.tolist() == ["check"] * 2 + ["full"] * 6
    table, notes = split_control(control, images, strips, control_ids=ids[:2], check_ids=ids[5:])
    assert table.point.tolist() == ids[:2] + ids[5:]
    assert any("left out" in n for n in notes)
    with pytest.raises(ConfigError, match="'nope' is not a control point"):
        split_control(control, images, strips, control_ids=["nope"])
    with pytest.raises(ConfigError, match="both name"):
        split_control(control, images, strips, control_ids=ids[:2], check_ids=ids[1:3])


def test_default_split_keeps_at_most_six_full_per_strip() -> None:
    images = _strip_images(n_photos=6)
    pts = np.unique(images.point)
    control = ControlTable(
        pts,
        np.column_stack(
            [np.arange(pts.size) * 3.0, (np.arange(pts.size) % 3) * 20.0, np.full(pts.size, 100.0)]
        ),
    )
    table, _ = split_control(control, images, [Strip("1", tuple(f"P{k}" for k in range(6)))])
    assert 3 <= int((table.kind == "full").sum()) <= 6
    assert int((table.kind == "check").sum()) == pts.size - int((table.kind == "full").sum())


# --------------------------------------------------------------------------- assemble / write


def _project(tmp_path: Path, **kw):
    images = _strip_images()
    control = _control(images)
    opts = ImportOptions(**kw)
    return assemble(
        "a test source",
        images,
        ImageFrame("mm", 0.005),
        Camera(50.0),
        control,
        "local",
        opts,
        inputs=[tmp_path / "source.txt"],
        default_name="test",
    )


def test_assembled_project_is_loaded_by_load_project(tmp_path: Path) -> None:
    project = _project(tmp_path)
    toml = write_project(project, tmp_path / "proj")
    loaded = load_project(toml)
    assert loaded.photo_ids == ("P0", "P1", "P2", "P3")
    assert loaded.images.flight_direction.value == "+y"
    assert loaded.observations.xy.shape[0] == len(project.images)
    np.testing.assert_allclose(loaded.observations.sigma, 0.005)  # one pixel


def test_ids_with_commas_quotes_and_hashes_survive_the_csv(tmp_path: Path) -> None:
    images = _strip_images(ids=["#1", "a,b", 'q"x', "0004"])
    control = _control(images)
    project = assemble(
        "odd ids",
        images,
        ImageFrame(),
        Camera(50.0),
        control,
        "local",
        ImportOptions(),
        inputs=[],
        default_name="odd",
        strips=[Strip("1", ("#1", "a,b", 'q"x', "0004"))],
    )
    loaded = load_project(write_project(project, tmp_path / "proj"))
    assert loaded.photo_ids == ("#1", "a,b", 'q"x', "0004")


def test_block_is_written_as_strips_tables(tmp_path: Path) -> None:
    a = _strip_images(ids=["a0", "a1", "a2"])
    b = _strip_images(ids=["b0", "b1", "b2"])
    images = ImageTable.concat([a, b])
    project = assemble(
        "block",
        images,
        ImageFrame(),
        Camera(50.0),
        _control(a),
        "local",
        ImportOptions(),
        inputs=[],
        default_name="block",
        strips=[Strip("A", ("a0", "a1", "a2")), Strip("B", ("b0", "b1", "b2"))],
    )
    toml = write_project(project, tmp_path / "proj")
    doc = tomllib.loads(toml.read_text(encoding="utf-8"))
    assert "strip" not in doc
    assert [s["name"] for s in doc["strips"]] == ["A", "B"]
    assert [s["photos"] for s in doc["strips"]] == [["a0", "a1", "a2"], ["b0", "b1", "b2"]]


def test_write_refuses_an_existing_folder_without_force(tmp_path: Path) -> None:
    project = _project(tmp_path)
    out = tmp_path / "proj"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ConfigError, match="give --force"):
        write_project(project, out)
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
    write_project(project, out, force=True)
    assert not (out / "keep.txt").exists()
    assert (out / "strip.toml").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["proj"]  # no temporary folder left


def test_write_never_replaces_a_folder_holding_an_input(tmp_path: Path) -> None:
    src = tmp_path / "data"
    src.mkdir()
    (src / "source.txt").write_text("input")
    images = _strip_images()
    project = assemble(
        "s",
        images,
        ImageFrame(),
        Camera(50.0),
        _control(images),
        "local",
        ImportOptions(),
        inputs=[src / "source.txt"],
        default_name="s",
    )
    for target in (src, tmp_path):
        with pytest.raises(ConfigError, match="contains the input file"):
            write_project(project, target, force=True)
    assert (src / "source.txt").read_text() == "input"


def test_failed_write_leaves_the_old_folder_as_it_was(tmp_path: Path, monkeypatch) -> None:
    project = _project(tmp_path)
    out = tmp_path / "proj"
    out.mkdir()
    (out / "old.txt").write_text("old")
    from strip_aerotri import _atomic

    real = _atomic.os.replace
    calls = []

    def failing(a, b):
        calls.append((a, b))
        if len(calls) == 2:  # moving the new folder in
            raise OSError("disk full")
        return real(a, b)

    monkeypatch.setattr(_atomic.os, "replace", failing)
    with pytest.raises(OSError, match="disk full"):
        write_project(project, out, force=True)
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["proj"]


def test_assemble_refuses_duplicated_observations(tmp_path: Path) -> None:
    images = _strip_images()
    twice = ImageTable.concat([images, images.take(np.array([0]))])
    with pytest.raises(ConfigError, match="observed twice"):
        assemble(
            "dup",
            twice,
            ImageFrame(),
            Camera(50.0),
            _control(images),
            "local",
            ImportOptions(),
            inputs=[],
            default_name="d",
        )


def test_assemble_needs_observed_control(tmp_path: Path) -> None:
    images = _strip_images()
    far = ControlTable(["G1"], [[0.0, 0.0, 0.0]])
    with pytest.raises(ConfigError, match="a project needs control"):
        assemble(
            "none",
            images,
            ImageFrame(),
            Camera(50.0),
            far,
            "local",
            ImportOptions(),
            inputs=[],
            default_name="n",
        )


def test_strip_selection_is_checked(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="--strips: no strip 2"):
        _project(tmp_path, strips=(2,))


def test_strips_from_a_geographic_track(tmp_path: Path) -> None:
    # the two-line track of _track() in longitude, latitude: the same strips
    from pyproj import Transformer

    from strip_aerotri.importers.common import PhotoPositions

    names, xyz = _track()
    to_geo = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True)
    lon, lat = to_geo.transform(610000.0 + xyz[:, 0], 5040000.0 + xyz[:, 1])
    track = PhotoPositions(names, np.column_stack([lon, lat, xyz[:, 2]]))
    images = ImageTable.concat(
        [
            _strip_images(ids=names[:5]),
            _strip_images(ids=names[6:]),
        ]
    )
    project = assemble(
        "geo",
        images,
        ImageFrame(),
        Camera(50.0),
        _control(images),
        "EPSG:4326",
        ImportOptions(),
        inputs=[],
        default_name="g",
        track=track,
        track_crs="EPSG:4326",
    )
    assert [s.photos for s in project.strips] == [tuple(names[:5]), tuple(names[6:])]


def test_photo_order_names_an_unknown_photo(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="--photo-order: photo 'P9' has no image observations"):
        _project(tmp_path, photo_order=(("P0", "P1", "P9"),))
    project = _project(tmp_path, photo_order=(("P0", "P1"), ("P2", "P3")))
    assert [s.photos for s in project.strips] == [("P0", "P1"), ("P2", "P3")]
