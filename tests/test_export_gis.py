"""``stripaero export geojson`` and ``export gpkg``: the points and photo
centres of a run for a GIS (docs/export.md)."""

from __future__ import annotations

import csv
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.errors import ConfigError
from strip_aerotri.export import read_results, results_geojson
from strip_aerotri.simulate import simulate_block, simulate_strip


def _run(toml: Path) -> Path:
    result = CliRunner().invoke(cli, ["-q", "run", str(toml)])
    assert result.exit_code == 0, result.output
    return toml


@pytest.fixture(scope="module")
def utm(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A film strip in UTM 34N, run (results in p/out)."""
    return _run(simulate_strip(8, seed=2).write_project(tmp_path_factory.mktemp("utm") / "p"))


@pytest.fixture(scope="module")
def local(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same strip in a local site system, run."""
    sim = simulate_strip(8, seed=2, crs="local")
    return _run(sim.write_project(tmp_path_factory.mktemp("local") / "p"))


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


def test_geojson_holds_every_point_and_photo_centre(utm: Path) -> None:
    """Every row of points.csv and photos.csv is a feature; the lon/lat are
    pyproj's (an independent Transformer) and the properties the CSV's."""
    from pyproj import Transformer

    runner = CliRunner()
    done = runner.invoke(cli, ["export", "geojson", str(utm)])
    assert done.exit_code == 0, done.output
    out = utm.parent / "out"
    data = json.loads((out / "results.geojson").read_text(encoding="utf-8"))
    assert data["type"] == "FeatureCollection" and "crs" not in data  # RFC 7946: no crs member
    points = [f for f in data["features"] if f["properties"]["feature"] == "point"]
    photos = [f for f in data["features"] if f["properties"]["feature"] == "photo_centre"]
    csv_points, csv_photos = _rows(out / "points.csv"), _rows(out / "photos.csv")
    assert [f["properties"]["point"] for f in points] == [r["point"] for r in csv_points]
    assert [f["properties"]["photo"] for f in photos] == [r["photo"] for r in csv_photos]
    to_wgs84 = Transformer.from_crs("EPSG:32634", "EPSG:4326", always_xy=True)
    for features, rows in ((points, csv_points), (photos, csv_photos)):
        xy = np.array([[float(r["X"]), float(r["Y"])] for r in rows])
        lon, lat = to_wgs84.transform(xy[:, 0], xy[:, 1])
        got = np.array([f["geometry"]["coordinates"] for f in features])
        np.testing.assert_allclose(got, np.column_stack([lon, lat]), rtol=0, atol=1e-8)
    for f, r in zip(points, csv_points, strict=True):
        assert f["properties"]["role"] == r["role"]
        assert f["properties"]["n_images"] == int(r["n_images"])
        for c in ("H", "dE", "dN", "dH"):
            assert f["properties"][c] == (float(r[c]) if r[c] else None)
    control = [f for f in points if f["properties"]["role"] == "control-full"]
    assert control and all(f["properties"]["dH"] is not None for f in control)
    for f, r in zip(photos, csv_photos, strict=True):
        opk = [f["properties"][c] for c in ("omega", "phi", "kappa")]
        assert opk == [float(r[c]) for c in ("omega", "phi", "kappa")]
        assert f["properties"]["strip"] == "Simulated film strip, 8 photos"
    assert "east-north-up" in data["stripaero"]["angles"]
    assert len({f["id"] for f in data["features"]}) == len(data["features"])


def test_geojson_of_a_local_crs_is_refused_in_one_line(local: Path) -> None:
    done = CliRunner().invoke(cli, ["export", "geojson", str(local)])
    assert done.exit_code == 1
    assert done.stderr.count("\n") == 1 and "no geodesy to WGS 84" in done.stderr
    assert not (local.parent / "out" / "results.geojson").exists()


def test_geojson_without_a_run_says_so(tmp_path: Path) -> None:
    toml = simulate_strip(6, seed=1).write_project(tmp_path / "p")
    done = CliRunner().invoke(cli, ["export", "geojson", str(toml), "-o", str(tmp_path / "x")])
    assert done.exit_code == 1 and "run the project first" in done.stderr


def test_geojson_of_a_block_names_each_photos_strip(tmp_path: Path) -> None:
    toml = _run(simulate_block(2, 6, seed=1).write_project(tmp_path / "b"))
    points, photos = read_results(toml.parent / "out")
    data = json.loads(results_geojson(points, photos, "EPSG:32634", strip="ignored"))
    strips = [f["properties"]["strip"] for f in data["features"][len(points.ids) :]]
    assert strips == [r["strip"] for r in _rows(toml.parent / "out" / "photos.csv")]
    assert len(set(strips)) == 2


def test_a_foreign_table_is_refused(tmp_path: Path) -> None:
    (tmp_path / "points.csv").write_text("id,E,N\n1,2,3\n")
    with pytest.raises(ConfigError, match=r"not a points\.csv of stripaero run"):
        read_results(tmp_path)


def _wkb_xyz(blobs: np.ndarray) -> np.ndarray:
    """X, Y, Z of WKB points (ISO 1001 or extended 0x80000001, little endian)."""
    out = []
    for blob in blobs:
        order, kind = struct.unpack_from("<BI", blob)
        assert order == 1 and kind in (1001, 0x80000001)
        out.append(struct.unpack_from("<ddd", blob, 5))
    return np.array(out)


def _read_layers(path: Path) -> dict[str, tuple[dict, np.ndarray, dict]]:
    from pyogrio.raw import read

    layers = {}
    for layer in ("points", "photo_centres"):
        meta, _, geometry, fields = read(path, layer=layer)
        layers[layer] = (meta, _wkb_xyz(geometry), dict(zip(meta["fields"], fields, strict=True)))
    return layers


def _check_layers(path: Path, out: Path) -> dict[str, tuple[dict, np.ndarray, dict]]:
    layers = _read_layers(path)
    for layer, name, key, z in (
        ("points", "points.csv", "point", "H"),
        ("photo_centres", "photos.csv", "photo", "Z"),
    ):
        rows = _rows(out / name)
        meta, xyz, fields = layers[layer]
        assert meta["geometry_type"] == "Point Z" and len(xyz) == len(rows)
        assert list(fields[key]) == [r[key] for r in rows]
        want = np.array([[float(r[c]) for c in ("X", "Y", z)] for r in rows])
        np.testing.assert_array_equal(xyz, want)  # the CSV's values, not reprojected
    return layers


def test_gpkg_layers_in_the_projects_crs(utm: Path) -> None:
    """Read back with pyogrio: both layers, every row, the CSV's coordinates
    and the project's CRS (EPSG:32634, not WGS 84)."""
    pytest.importorskip("pyogrio")
    from pyproj import CRS

    done = CliRunner().invoke(cli, ["export", "gpkg", str(utm)])
    assert done.exit_code == 0, done.output
    out = utm.parent / "out"
    layers = _check_layers(out / "results.gpkg", out)
    for meta, _, _ in layers.values():
        assert CRS.from_user_input(meta["crs"]) == CRS.from_epsg(32634)
    points = layers["points"][2]
    rows = _rows(out / "points.csv")
    assert list(points["role"]) == [r["role"] for r in rows]
    dh = np.array([float(r["dH"]) if r["dH"] else np.nan for r in rows])
    np.testing.assert_array_equal(points["dH"], dh)  # empty cells NULL (NaN)
    assert set(layers["photo_centres"][2]["strip"]) == {"Simulated film strip, 8 photos"}
    assert not list(out.glob(".*partial*"))
    again = CliRunner().invoke(cli, ["export", "gpkg", str(utm)])  # replaced, not appended
    assert again.exit_code == 0 and len(_read_layers(out / "results.gpkg")["points"][1]) == len(
        rows
    )


def test_gpkg_of_a_local_crs_has_no_crs(local: Path) -> None:
    pytest.importorskip("pyogrio")
    target = local.parent / "site.gpkg"
    done = CliRunner().invoke(cli, ["export", "gpkg", str(local), "-o", str(target)])
    assert done.exit_code == 0, done.output
    layers = _check_layers(target, local.parent / "out")
    assert all(meta["crs"] is None for meta, _, _ in layers.values())


def test_gpkg_of_a_geographic_crs_keeps_longitude_first(tmp_path: Path) -> None:
    pytest.importorskip("pyogrio")
    from pyproj import CRS

    toml = _run(
        simulate_strip(6, seed=3, crs="EPSG:4326", centre_lonlat=(21.0, 42.0)).write_project(
            tmp_path / "g"
        )
    )
    points, photos = read_results(toml.parent / "out")
    from strip_aerotri.export import write_gpkg

    write_gpkg(tmp_path / "g.gpkg", points, photos, "EPSG:4326")
    layers = _check_layers(tmp_path / "g.gpkg", toml.parent / "out")
    meta, xyz, _ = layers["points"]
    assert CRS.from_user_input(meta["crs"]) == CRS.from_epsg(4326)
    assert np.all(np.abs(xyz[:, 0] - 21.0) < 1.0) and np.all(np.abs(xyz[:, 1] - 42.0) < 1.0)


def test_gpkg_without_pyogrio_names_the_extra(
    utm: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "pyogrio", None)  # import fails as if not installed
    monkeypatch.setitem(sys.modules, "pyogrio.raw", None)
    target = tmp_path / "x.gpkg"
    done = CliRunner().invoke(cli, ["export", "gpkg", str(utm), "-o", str(target)])
    assert done.exit_code == 1
    assert done.stderr.count("\n") == 1
    assert "pip install 'strip_aerotri[gpkg]'" in done.stderr
    assert not target.exists()


def test_point_features_text_equals_one_feature_at_a_time() -> None:
    """The column-wise writer gives what json gives for each feature dict:
    escaped and non-ASCII ids, a key with braces and a percent sign, floats of every size, NaN
    properties (null) and a row without a geometry (null)."""
    from strip_aerotri.export.geojson import geojson_text, point_feature, point_features_text

    rng = np.random.default_rng(2345)
    n = 200
    ids = np.array([f'p"{k}\\é{{%s' if k % 7 == 0 else f"P{k}" for k in range(n)], dtype=object)
    lonlat = np.round(rng.uniform(-180, 180, (n, 2)), 8)
    lonlat[3] = (np.nan, 1.0)
    lonlat[5, 1] = np.inf
    heights = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 17, n)
    heights[[1, 9]] = (np.nan, -np.inf)
    counts = rng.integers(0, 1000, n)
    roles = np.array(["tie", "check", "control-full"] * 67)[:n]
    props = {"id": ids, "role": roles, "H {x} %s": heights, "n_models": counts}
    got = point_features_text(ids, lonlat, props)
    want = [
        geojson_text(
            point_feature(
                str(ids[k]),
                float(lonlat[k, 0]),
                float(lonlat[k, 1]),
                {
                    "id": str(ids[k]),
                    "role": str(roles[k]),
                    "H {x} %s": float(heights[k]) if np.isfinite(heights[k]) else None,
                    "n_models": int(counts[k]),
                },
            )
        )
        for k in range(n)
    ]
    assert got == want
    assert (
        json.loads(got[3])["geometry"] is None
        and json.loads(got[9])["properties"]["H {x} %s"] is None
    )
    assert point_features_text(ids[:0], lonlat[:0], {"id": ids[:0]}) == []
    with pytest.raises(ValueError, match="property 'H'"):
        point_features_text(ids, lonlat, {"H": heights[:3]})
    with pytest.raises(TypeError, match="str, int or float"):
        point_features_text(ids, lonlat, {"b": np.ones(n, dtype=bool)})
