"""Regenerate the fixture projects in tests/data (see SOURCES.md).

Run from the repository root: ``python tests/data/make_fixtures.py``.

Both projects are synthetic and geometrically exact up to the rounding of
the written values (image 0.001 mm, ground 0.001 m, geographic 1e-9 degree):
photos are projected with the collinearity equations, image vector
``(x, y, -c)``, ``R = R_x(omega) R_y(phi) R_z(kappa)`` mapping image to object.

* ``minimal/``: crs = "local", 3 photos, only the required keys.
* ``full/``: every key of strip.toml, EPSG:32634 (UTM 34N), 5 photos with
  leading-zero ids, a principal point offset, every control type, a
  straight line, an unobserved control point, and the CSV variants the
  reader must accept (BOM, CRLF, comments before the header, blank lines,
  spaces around fields, empty sigma cells, mixed-case header).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def matrix_from_opk(omega: float, phi: float, kappa: float) -> np.ndarray:
    co, so = np.cos(omega), np.sin(omega)
    cp, sp = np.cos(phi), np.sin(phi)
    ck, sk = np.cos(kappa), np.sin(kappa)
    rx = np.array([[1, 0, 0], [0, co, -so], [0, so, co]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[ck, -sk, 0], [sk, ck, 0], [0, 0, 1]])
    return rx @ ry @ rz


def project(points: np.ndarray, centre: np.ndarray, rotation: np.ndarray, c: float) -> np.ndarray:
    """Image x, y in mm of object points (N, 3) on one photo."""
    local = (points - centre) @ rotation  # = R.T @ (P - S) for each row
    return -c * local[:, :2] / local[:, 2:3]


def observe(
    ids: list[str],
    points: np.ndarray,
    photos: list[str],
    centres: np.ndarray,
    angles: np.ndarray,
    c: float,
    half_format: float,
) -> list[tuple[str, str, float, float]]:
    rows = []
    for pid, centre, opk in zip(photos, centres, angles, strict=True):
        xy = project(points, centre, matrix_from_opk(*opk), c)
        inside = np.all(np.abs(xy) <= half_format, axis=1)
        rows += [(pid, ids[i], xy[i, 0], xy[i, 1]) for i in np.flatnonzero(inside)]
    return rows


def minimal() -> None:
    rng = np.random.default_rng(101)
    c = 152.87
    photos = ["1201", "1202", "1203"]
    centres = np.array([[0.0, 0.0, 1000.0], [600.0, 0.0, 1005.0], [1200.0, 10.0, 995.0]])
    angles = np.deg2rad(rng.uniform(-1.0, 1.0, size=(3, 3)))
    grid_x, grid_y = np.meshgrid(np.arange(0.0, 1201.0, 300.0), [-400.0, 0.0, 400.0])
    points = np.column_stack([grid_x.ravel(), grid_y.ravel(), rng.uniform(0.0, 40.0, grid_x.size)])
    ids = [f"{i + 1:03d}" for i in range(points.shape[0])]
    rows = observe(ids, points, photos, centres, angles, c, 115.0)
    folder = HERE / "minimal"
    folder.mkdir(exist_ok=True)
    (folder / "strip.toml").write_text(
        "[strip]\n"
        'photos = ["1201", "1202", "1203"]\n\n'
        "[camera]\n"
        "principal_distance_mm = 152.87\n\n"
        "[images]\n"
        'file = "image_points.csv"\n\n'
        "[control]\n"
        'file = "control.csv"\n'
        'crs = "local"\n',
        encoding="utf-8",
    )
    text = "photo,point,x,y\n" + "".join(f"{p},{q},{x:.3f},{y:.3f}\n" for p, q, x, y in rows)
    (folder / "image_points.csv").write_text(text, encoding="utf-8")
    control = [0, 4, 10, 14, 7]  # the four corners and the centre
    text = "point,X,Y,H,type\n" + "".join(
        f"{ids[i]},{points[i, 0]:.3f},{points[i, 1]:.3f},{points[i, 2]:.3f},full\n"
        for i in control
    )
    (folder / "control.csv").write_text(text, encoding="utf-8")


def full() -> None:
    from pyproj import Transformer

    rng = np.random.default_rng(202)
    c = 152.87
    pp = np.array([0.012, -0.008])  # principal point, mm
    lat0, lon0, h0 = np.deg2rad(42.70), np.deg2rad(21.00), 300.0
    photos = ["0101", "0102", "0103", "0104", "0105"]
    # East-North-Up truth; the strip flies east, so image y points north.
    centres = np.column_stack(
        [600.0 * np.arange(5), rng.normal(0.0, 10.0, 5), 1000.0 + rng.normal(0.0, 5.0, 5)]
    )
    angles = np.deg2rad(rng.uniform(-1.5, 1.5, size=(5, 3)))
    grid_x, grid_y = np.meshgrid(np.arange(-50.0, 2451.0, 250.0), [-420.0, 0.0, 420.0])
    ties = np.column_stack([grid_x.ravel(), grid_y.ravel(), rng.uniform(0.0, 60.0, grid_x.size)])
    tie_ids = [f"T{i + 1:02d}" for i in range(ties.shape[0])]
    line = np.column_stack(
        [[100.0, 900.0, 1700.0, 2300.0], np.full(4, 200.0), [12.0, 30.0, 25.0, 8.0]]
    )
    line_ids = ["R1", "R2", "R3", "R4"]
    points = np.vstack([ties, line])
    ids = tie_ids + line_ids
    rows = observe(ids, points, photos, centres, angles, c, 115.0)

    # ENU -> ECEF -> geodetic -> UTM 34N, heights above the ellipsoid.
    sl, cl, sb, cb = np.sin(lon0), np.cos(lon0), np.sin(lat0), np.cos(lat0)
    enu2ecef = np.array([[-sl, -sb * cl, cb * cl], [cl, -sb * sl, cb * sl], [0.0, cb, sb]])
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    to_geodetic = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    to_utm = Transformer.from_crs("EPSG:4326", "EPSG:32634", always_xy=True)
    origin = np.array(to_ecef.transform(np.rad2deg(lon0), np.rad2deg(lat0), h0))
    ecef = origin + (points - [0.0, 0.0, 0.0]) @ enu2ecef.T
    lon, lat, h = to_geodetic.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
    east, north = to_utm.transform(lon, lat)

    folder = HERE / "full"
    folder.mkdir(exist_ok=True)
    (folder / "strip.toml").write_text(
        "# Every key of strip.toml, with values other than the defaults where possible.\n"
        "[strip]\n"
        'name = "Full fixture"\n'
        'photos = ["0101", "0102", "0103", "0104", "0105"]\n\n'
        "[camera]\n"
        "principal_distance_mm = 152.87\n"
        "principal_point_mm = [0.012, -0.008]\n\n"
        "[images]\n"
        'file = "data/image_points.csv"\n'
        "sigma_mm = 0.004\n\n"
        "[control]\n"
        'file = "data/control.csv"\n'
        'crs = "EPSG:32634"\n'
        "sigma_xy_m = 0.05\n"
        "sigma_h_m = 0.08\n\n"
        "[[straight_line]]\n"
        'points = ["R1", "R2", "R3", "R4"]\n'
        "weight = 50.0\n"
        'name = "north road"\n\n'
        "[adjustment]\n"
        'route = "Projected"\n'
        'polynomial = "auto"\n'
        'relative_orientation = "BASE"\n'
        'intersection = "normal"\n'
        'scale_transfer = "distance"\n'
        "max_iterations = 12\n\n"
        "[output]\n"
        'directory = "results"\n\n'
        "[report]\n"
        "map_scale = 5000\n",
        encoding="utf-8",
    )
    data = folder / "data"
    data.mkdir(exist_ok=True)
    lines = [
        "# Image coordinates of the full fixture (mm, not reduced to the principal point)",
        "# written with a BOM and CRLF line ends",
        "",
        " Photo , point , x , y , sigma ",
    ]
    for k, (p, q, x, y) in enumerate(rows):
        sigma = "0.003" if k % 3 == 0 else ""
        lines.append(f"{p}, {q} ,{x + pp[0]:.3f}, {y + pp[1]:.3f} ,{sigma}")
        if k == 10:
            lines += ["", "# a comment between rows"]
    (data / "image_points.csv").write_bytes(
        ("\ufeff" + "\r\n".join(lines) + "\r\n").encode("utf-8")
    )

    index = {name: i for i, name in enumerate(ids)}

    def utm(name: str) -> tuple[str, str, str]:
        i = index[name]
        return f"{east[i]:.3f}", f"{north[i]:.3f}", f"{h[i]:.3f}"

    rows_c = [
        "# control of the full fixture: UTM 34N, ellipsoidal heights",
        "point,X,Y,H,type,sigma_xy,sigma_h",
    ]
    rows_c += [",".join([n, *utm(n), "full", "", ""]) for n in ("T01", "T11", "T23", "T33")]
    e, n, hh = utm("T17")
    rows_c.append(",".join(["T17", e, n, hh, "FULL", "0.01", "0.02"]))
    e, n, _ = utm("T06")
    rows_c.append(",".join(["T06", e, n, "", "plan", "0.03", ""]))
    _, _, hh = utm("T28")
    rows_c.append(",".join(["T28", "", "", hh, "height", "", "0.04"]))
    rows_c.append(",".join(["T20", *utm("T20"), "check", "", ""]))
    rows_c.append("G99,510000.000,4730000.000,350.000,full,,")  # observed on no photo
    (data / "control.csv").write_text("\n".join(rows_c) + "\n", encoding="utf-8")


if __name__ == "__main__":
    minimal()
    full()
