"""Regenerate the importer samples in tests/data/import (see ../SOURCES.md).

Run from the repository root: ``python tests/data/import/make_import_fixtures.py``.

One synthetic drone flight is written in the layout of every importer: two
strips of 5 photos flown north and back south 40 m further east, with one
photo in the turn between them.  The drone keeps the camera's heading on the
way back (image y points north on every photo), so on the second strip the
photos move along image -y.  The scene is in UTM zone 32N (EPSG:32632) near
10.4 deg E, 45.5 deg N, where the meridian convergence is about 1 deg.

The truth (``truth/points.csv``, ``truth/photos.csv``) is the generating
geometry: ground points, projection centres and, per photo, omega, phi,
kappa of ``R = Rx Ry Rz`` mapping sensor-axis image vectors (x right, y up,
z back) to the UTM grid axes.  Images are projected with the collinearity
equations and written in each format's own units and axes, distorted with
each format's published lens model where it has one (COLMAP OPENCV,
Metashape Appendix C).  Deterministic: seeded ``numpy.random.default_rng``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CRS = "EPSG:32632"
E0, N0 = 610000.0, 5040000.0
WIDTH, HEIGHT = 4000, 3000
PIXEL_MM = 0.00241
FOCAL_MM = 8.8
PP_PX = (2010.5, 1490.25)  # principal point, column and row from the top-left corner
OPENCV = {"k1": -0.012, "k2": 0.004, "p1": 2.0e-4, "p2": -1.5e-4}
METASHAPE = {"k1": -0.011, "k2": 0.0035, "p1": 1.5e-4, "p2": -2.5e-4}
UTM32N_WKT = (
    'PROJCS["WGS 84 / UTM zone 32N",GEOGCS["WGS 84",DATUM["World Geodetic System 1984'
    '",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["E'
    'PSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.017'
    '45329251994328,AUTHORITY["EPSG","9102"]],AUTHORITY["EPSG","4326"]],PROJECTION["T'
    'ransverse_Mercator",AUTHORITY["EPSG","9807"]],PARAMETER["latitude_of_origin",0],'
    'PARAMETER["central_meridian",9],PARAMETER["scale_factor",0.9996],PARAMETER["fals'
    'e_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG"'
    ',"9001"]],AUTHORITY["EPSG","32632"]]'
)
CALCAM = {"g": 0.001, "k1": -2.0, "k2": 0.5}  # cal.cal: radial terms on pixel radii scaled by g


def rot(omega: float, phi: float, kappa: float) -> np.ndarray:
    """R = Rx(omega) Ry(phi) Rz(kappa), radians."""
    co, so, cp, sp, ck, sk = (
        np.cos(omega),
        np.sin(omega),
        np.cos(phi),
        np.sin(phi),
        np.cos(kappa),
        np.sin(kappa),
    )
    rx = np.array([[1, 0, 0], [0, co, -so], [0, so, co]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[ck, -sk, 0], [sk, ck, 0], [0, 0, 1]])
    return rx @ ry @ rz


def scene(n_grid: int = 6):
    """The flight over an n_grid x n_grid grid of points (6: the test samples;
    a denser grid gives samples a run can adjust, examples/import-samples)."""
    rng = np.random.default_rng(2345)
    # ground points on a grid with relief; 8 of them (36 on a dense grid) are GCPs
    gx, gy = np.meshgrid(np.linspace(-30.0, 70.0, n_grid), np.linspace(-15.0, 75.0, n_grid))
    xy = np.column_stack([gx.ravel(), gy.ravel()]) + rng.normal(0.0, 3.0, (gx.size, 2))
    ground = np.column_stack(
        [E0 + xy[:, 0], N0 + xy[:, 1], 100.0 + rng.uniform(-3.0, 3.0, gx.size)]
    )
    if n_grid == 6:
        gcp_rows = np.array([0, 5, 14, 15, 20, 21, 30, 35])
    else:  # a 6 x 6 sub-grid, corners included: control and check points
        at = np.round(np.linspace(0, n_grid - 1, 6)).astype(int)
        gcp_rows = (at[:, None] * n_grid + at[None, :]).ravel()
    names = [f"T{k + 1:03d}" for k in range(ground.shape[0])]
    for n, k in enumerate(gcp_rows):
        names[k] = f"GCP{n + 1}"
    # photos: strip 1 north, a turn photo, strip 2 south (camera heading kept)
    centres = [(E0, N0 + 15.0 * k) for k in range(5)]
    centres.append((E0 + 20.0, N0 + 70.0))
    centres += [(E0 + 40.0, N0 + 60.0 - 15.0 * k) for k in range(5)]
    centres = np.column_stack([np.asarray(centres), 160.0 + rng.normal(0.0, 0.3, len(centres))])
    angles = np.deg2rad(rng.uniform(-1.5, 1.5, (len(centres), 3)))
    photos = [f"DJI_{k + 1:04d}" for k in range(len(centres))]
    return ground, names, centres, angles, photos


def ideal_mm(
    ground: np.ndarray, centre: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Image x, y (mm, sensor axes, reduced to the principal point) and a visibility mask."""
    v = (ground - centre) @ r  # R^T (X - C) for each row
    xy = -FOCAL_MM * v[:, :2] / v[:, 2:3]
    half = np.array([WIDTH / 2 - 40, HEIGHT / 2 - 40]) * PIXEL_MM
    return xy, (v[:, 2] < 0) & np.all(np.abs(xy) < half, axis=1)


def to_pixel(xy_mm: np.ndarray, pp=PP_PX) -> np.ndarray:
    return np.column_stack([xy_mm[:, 0] / PIXEL_MM + pp[0], -xy_mm[:, 1] / PIXEL_MM + pp[1]])


def opencv_pixels(xy_mm: np.ndarray) -> np.ndarray:
    """COLMAP OPENCV: distort the normalised camera point (x right, y down)."""
    x, y = xy_mm[:, 0] / FOCAL_MM, -xy_mm[:, 1] / FOCAL_MM
    k1, k2, p1, p2 = OPENCV["k1"], OPENCV["k2"], OPENCV["p1"], OPENCV["p2"]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    f = FOCAL_MM / PIXEL_MM
    return np.column_stack([f * xd + PP_PX[0], f * yd + PP_PX[1]])


def metashape_pixels(xy_mm: np.ndarray) -> np.ndarray:
    """Metashape frame camera (Appendix C), x right, y down, cx cy from the centre."""
    x, y = xy_mm[:, 0] / FOCAL_MM, -xy_mm[:, 1] / FOCAL_MM
    k1, k2, p1, p2 = METASHAPE["k1"], METASHAPE["k2"], METASHAPE["p1"], METASHAPE["p2"]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
    yd = y * radial + p2 * (r2 + 2 * y * y) + 2 * p1 * x * y
    f = FOCAL_MM / PIXEL_MM
    return np.column_stack(
        [
            WIDTH / 2 + (PP_PX[0] - WIDTH / 2) + f * xd,
            HEIGHT / 2 + (PP_PX[1] - HEIGHT / 2) + f * yd,
        ]
    )


def calcam_pixels(xy_mm: np.ndarray) -> np.ndarray:
    """The CalCam (cal.cal) radial model: dx_px = x' (k1 r'^2 + k2 r'^4), x' = g x_px."""
    x, y = xy_mm[:, 0] / PIXEL_MM, -xy_mm[:, 1] / PIXEL_MM  # pixels from the principal point
    g, k1, k2 = CALCAM["g"], CALCAM["k1"], CALCAM["k2"]
    r2 = (g * g) * (x * x + y * y)
    scale = g * (k1 * r2 + k2 * r2 * r2)
    return np.column_stack([PP_PX[0] + x * (1 + scale), PP_PX[1] + y * (1 + scale)])


def opk_deg(r: np.ndarray) -> np.ndarray:
    return np.rad2deg(
        [np.arctan2(-r[1, 2], r[2, 2]), np.arcsin(r[0, 2]), np.arctan2(-r[0, 1], r[0, 0])]
    )


def quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (w > 0 branch suffices here)."""
    w = np.sqrt(max(0.0, 1.0 + np.trace(r))) / 2.0
    return np.array(
        [
            w,
            (r[2, 1] - r[1, 2]) / (4 * w),
            (r[0, 2] - r[2, 0]) / (4 * w),
            (r[1, 0] - r[0, 1]) / (4 * w),
        ]
    )


def main(out: Path = HERE, n_grid: int = 6, noise_px: float = 0.0) -> None:
    """Write every format's sample into ``out`` (and the truth); ``noise_px``:
    Gaussian noise of every image measurement, pixels (0: exact projections,
    whose only errors are the files' rounding)."""
    out.mkdir(parents=True, exist_ok=True)
    ground, names, centres, angles, photos = scene(n_grid)
    rots = [rot(*a) for a in angles]
    gcp = [k for k, n in enumerate(names) if n.startswith("GCP")]
    obs = []  # (photo index, point index, ideal xy mm)
    for i, (c, r) in enumerate(zip(centres, rots, strict=True)):
        xy, vis = ideal_mm(ground, c, r)
        obs += [(i, k, xy[k]) for k in np.flatnonzero(vis)]
    pi = np.array([o[0] for o in obs])
    pk = np.array([o[1] for o in obs])
    ideal = np.array([o[2] for o in obs])
    if noise_px:
        ideal = ideal + np.random.default_rng(6789).normal(0.0, noise_px * PIXEL_MM, ideal.shape)

    truth = out / "truth"
    truth.mkdir(exist_ok=True)
    (truth / "points.csv").write_text(
        "point,X,Y,H\n"
        + "".join(
            f"{n},{x:.4f},{y:.4f},{h:.4f}\n" for n, (x, y, h) in zip(names, ground, strict=True)
        )
    )
    (truth / "photos.csv").write_text(
        "photo,X,Y,Z,omega,phi,kappa\n"
        + "".join(
            f"{p},{c[0]:.4f},{c[1]:.4f},{c[2]:.4f},{o[0]:.9f},{o[1]:.9f},{o[2]:.9f}\n"
            for p, c, o in zip(photos, centres, (opk_deg(r) for r in rots), strict=True)
        )
    )
    (truth / "observations.csv").write_text(
        "photo,point,x,y\n"
        + "".join(
            f"{photos[i]},{names[k]},{x:.9f},{y:.9f}\n"
            for i, k, (x, y) in zip(pi, pk, ideal, strict=True)
        )
    )

    is_gcp = np.isin(pk, gcp)

    # The FC300X layout: photos B<strip>_<n>, numeric ids, mm from the image centre
    fc = out / "fc300x"
    fc.mkdir(exist_ok=True)
    fc_name = {i: f"B1_{i + 1}" for i in range(5)} | {6 + i: f"B2_{i + 1}" for i in range(5)}
    cpx = calcam_pixels(ideal)
    centre_mm = np.column_stack(
        [(cpx[:, 0] - WIDTH / 2) * PIXEL_MM, -(cpx[:, 1] - HEIGHT / 2) * PIXEL_MM]
    )
    number = {
        k: (str(100 + gcp.index(k) + 1) if k in gcp else str(k + 1)) for k in range(len(names))
    }
    header = "       image \t\t     Num    x                y            n   m\n"

    def fc_rows(mask: np.ndarray, ids) -> str:
        out = [
            f"       {fc_name[i]}.JPG {ids(k):>15s} {x:>15.8f} {y:>15.8f}   0   M"
            for i, k, (x, y) in zip(pi[mask], pk[mask], centre_mm[mask], strict=True)
            if i in fc_name
        ]
        return "\r\n".join(out) + "\r\n"

    only_m = np.isin(pk, [29, 30, 31])  # tie points found only by the matcher
    (fc / "GCP_ImageCs.txt").write_text(header + fc_rows(is_gcp, lambda k: number[k]), newline="")
    (fc / "Tie_points_for_AO.txt").write_text(
        header + fc_rows(~is_gcp & ~only_m, lambda k: number[k]), newline=""
    )
    dup = np.isin(pk, [8, 9, 10, 11])  # the matcher's copies of tie points, numbered on its own
    (fc / "Matching.txt").write_text(
        fc_rows((dup | only_m) & (pi < 5), lambda k: str(500 + k)), newline=""
    )
    (fc / "MatchingB2.txt").write_text(
        fc_rows((dup | only_m) & (pi > 5), lambda k: str(k + 1)), newline=""
    )
    gcp_lines = [
        f"{number[k]}\t{ground[k, 0]:.3f}\t{ground[k, 1]:.3f}\t{ground[k, 2]:.3f}" for k in gcp
    ]
    gcp_lines.append(f"999\t{E0 + 500:.3f}\t{N0 + 500:.3f}\t100.000")  # on no photo
    (fc / "GCP_UTM.txt").write_text("\r\n".join(gcp_lines) + "\r\n", newline="")
    (fc / "cal.cal").write_text(
        "% Calibration data (synthetic, tests/data/import/make_import_fixtures.py)\r\n%\r\n\r\n"
        "Number_of_cameras 1\r\n\r\nCamera_id 1\r\n"
        f"Focal_length      {FOCAL_MM / PIXEL_MM:.10f}\r\n"
        f"Principal_point_x {PP_PX[0]:.10f}\r\nPrincipal_point_y {PP_PX[1]:.10f}\r\n"
        f"General_scaling   {CALCAM['g']}\r\nAffinity 0.0\r\n"
        f"Radial_k1 {CALCAM['k1']}\r\nRadial_k2 {CALCAM['k2']}\r\nRadial_k3 0.0\r\n"
        "Tangential_t1 0.0\r\nTangential_t2 0.0\r\nUn-orthogonality 0.0\r\n"
        f"Sensor_width  {WIDTH}  {WIDTH * PIXEL_MM:.4f}\r\n"
        f"Sensor_height {HEIGHT}  {HEIGHT * PIXEL_MM:.4f}\r\n",
        newline="",
    )

    # OpenDroneMap gcp_list.txt (pixels distorted as the COLMAP camera: the same photos)
    odm = out / "odm"
    odm.mkdir(exist_ok=True)
    px = opencv_pixels(ideal)
    lines = [CRS]
    for i, k, (u, v) in zip(pi[is_gcp], pk[is_gcp], px[is_gcp], strict=True):
        x, y, h = ground[k]
        lines.append(f"{x:.3f} {y:.3f} {h:.3f} {u:.2f} {v:.2f} {photos[i]}.JPG {names[k]}")
    (odm / "gcp_list.txt").write_text("\n".join(lines) + "\n")

    # COLMAP text model, geo-registered in the UTM grid (tie points: the non-GCP points)
    col = out / "colmap"
    col.mkdir(exist_ok=True)
    f = FOCAL_MM / PIXEL_MM
    (col / "cameras.txt").write_text(
        "# Camera list with one line of data per camera:\n"
        "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n"
        f"1 OPENCV {WIDTH} {HEIGHT} {f:.6f} {f:.6f} {PP_PX[0]} {PP_PX[1]} "
        f"{OPENCV['k1']} {OPENCV['k2']} {OPENCV['p1']} {OPENCV['p2']}\n"
    )
    ties = ~is_gcp
    lines = [
        "# Image list with two lines of data per image:",
        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
        "#   POINTS2D[] as (X, Y, POINT3D_ID)",
    ]
    tracks: dict[int, list[tuple[int, int]]] = {}
    cv = np.diag([1.0, -1.0, -1.0])
    for i, (c, r) in enumerate(zip(centres, rots, strict=True)):
        r_cw = cv @ r.T  # world (grid) to the camera frame x right, y down, z forward
        t = -r_cw @ c
        q = quaternion(r_cw)
        lines.append(
            f"{i + 1} {' '.join(f'{v:.12f}' for v in q)} {' '.join(f'{v:.6f}' for v in t)} 1 "
            f"images/{photos[i]}.JPG"
        )
        mine = np.flatnonzero((pi == i) & ties)
        parts = []
        for j, m in enumerate(mine):
            parts.append(f"{px[m, 0]:.4f} {px[m, 1]:.4f} {pk[m] + 1}")
            tracks.setdefault(int(pk[m]) + 1, []).append((i + 1, j))
        lines.append(" ".join(parts))
    (col / "images.txt").write_text("\n".join(lines) + "\n")
    lines = [
        "# 3D point list with one line of data per point:",
        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
    ]
    for pid in sorted(tracks):
        x, y, h = ground[pid - 1]
        track = " ".join(f"{a} {b}" for a, b in tracks[pid])
        lines.append(f"{pid} {x:.4f} {y:.4f} {h:.4f} 128 128 128 0.35 {track}")
    (col / "points3D.txt").write_text("\n".join(lines) + "\n")

    # PATB: .im (mm, ideal, reduced to the principal point), .con, .ori
    patb = out / "patb"
    patb.mkdir(exist_ok=True)
    lines = []
    for i in range(len(photos)):
        lines.append(f"{1001 + i:>10d}{1:>6d}")
        for m in np.flatnonzero(pi == i):
            lines.append(f"{names[pk[m]]:>10s}{ideal[m, 0]:>14.4f}{ideal[m, 1]:>14.4f}")
        lines.append("       -99")
    (patb / "block.im").write_text("\n".join(lines) + "\n")
    lines = [
        f"{names[k]:>10s}{ground[k, 0]:>15.3f}{ground[k, 1]:>15.3f}{ground[k, 2]:>11.3f}"
        for k in gcp
    ]
    (patb / "block.con").write_text("\n".join([*lines, "       -99"]) + "\n")
    lines = []
    for i, (c, r) in enumerate(zip(centres, rots, strict=True)):
        lines.append(f"{1001 + i:>16d}{'':16s}{c[0]:16.5f}{c[1]:16.5f}{c[2]:16.5f}")
        lines.append("".join(f"{v:16.12f}" for v in r.ravel()[:5]))
        lines.append("".join(f"{v:16.12f}" for v in r.ravel()[5:]))
    (patb / "block.ori").write_text("\n".join(lines) + "\n")

    # Metashape: markers XML (GCPs; GCP8 disabled: a check point) and OPK text
    ms = out / "metashape"
    ms.mkdir(exist_ok=True)
    mpx = metashape_pixels(ideal)
    cams = "\n".join(
        f'      <camera id="{i}" sensor_id="0" label="{p}"/>' for i, p in enumerate(photos)
    )
    markers = []
    for n, k in enumerate(gcp):
        x, y, h = ground[k]
        enabled = "false" if names[k] == "GCP8" else "true"
        markers.append(
            f'      <marker id="{n}" label="{names[k]}">\n'
            f'        <reference x="{x:.3f}" y="{y:.3f}" z="{h:.3f}" enabled="{enabled}"/>\n'
            "      </marker>"
        )
    locations = []
    for n, k in enumerate(gcp):
        rows = np.flatnonzero(pk == k)
        locs = "\n".join(
            f'            <location camera_id="{pi[m]}" pinned="true" x="{mpx[m, 0]:.3f}" '
            f'y="{mpx[m, 1]:.3f}"/>'
            for m in rows
        )
        locations.append(f'          <marker marker_id="{n}">\n{locs}\n          </marker>')
    cx, cy = PP_PX[0] - WIDTH / 2, PP_PX[1] - HEIGHT / 2
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<document version="1.5.0">
  <chunk label="Chunk 1" enabled="true">
    <sensors next_id="1">
      <sensor id="0" label="FC6310 (8.8mm)" type="frame">
        <resolution width="{WIDTH}" height="{HEIGHT}"/>
        <property name="pixel_width" value="{PIXEL_MM}"/>
        <property name="pixel_height" value="{PIXEL_MM}"/>
        <property name="focal_length" value="{FOCAL_MM}"/>
        <calibration type="frame" class="adjusted">
          <resolution width="{WIDTH}" height="{HEIGHT}"/>
          <f>{FOCAL_MM / PIXEL_MM:.6f}</f>
          <cx>{cx}</cx>
          <cy>{cy}</cy>
          <k1>{METASHAPE["k1"]}</k1>
          <k2>{METASHAPE["k2"]}</k2>
          <p1>{METASHAPE["p1"]}</p1>
          <p2>{METASHAPE["p2"]}</p2>
        </calibration>
      </sensor>
    </sensors>
    <cameras next_id="{len(photos)}" next_group_id="0">
{cams}
    </cameras>
    <markers next_id="{len(gcp)}" next_group_id="0">
{chr(10).join(markers)}
    </markers>
    <frames next_id="1">
      <frame id="0">
        <markers>
{chr(10).join(locations)}
        </markers>
      </frame>
    </frames>
    <reference>{UTM32N_WKT}</reference>
  </chunk>
</document>
"""
    (ms / "markers.xml").write_text(xml)
    lines = [
        "# Cameras (11)",
        "# CoordinateSystem: WGS 84 / UTM zone 32N (EPSG::32632)",
        "#Label\tX/Easting\tY/Northing\tZ/Altitude\tOmega\tPhi\tKappa\tr11\tr12\tr13\tr21\tr22\tr23\tr31\tr32\tr33",
    ]
    for p, c, r in zip(photos, centres, rots, strict=True):
        o = opk_deg(r)
        m = r.T  # written as the grid-to-camera matrix
        lines.append(
            "\t".join(
                [
                    f"{p}.JPG",
                    *(f"{v:.6f}" for v in c),
                    *(f"{v:.9f}" for v in o),
                    *(f"{v:.12f}" for v in m.ravel()),
                ]
            )
        )
    (ms / "cameras_opk.txt").write_text("\n".join(lines) + "\n")

    # Pix4D: marks (ideal pixels, accuracy 0.5 px), GCPs (easting, northing), external parameters
    p4 = out / "pix4d"
    p4.mkdir(exist_ok=True)
    ipx = to_pixel(ideal)
    lines = [
        f"{photos[i]}.JPG,{names[k]},{u:.3f},{v:.3f},0.5"
        for i, k, (u, v) in zip(pi[is_gcp], pk[is_gcp], ipx[is_gcp], strict=True)
    ]
    (p4 / "marks.csv").write_text("\n".join(lines) + "\n")
    lines = [
        f"{names[k]},{ground[k, 0]:.3f},{ground[k, 1]:.3f},{ground[k, 2]:.3f},0.02,0.03"
        for k in gcp
    ]
    (p4 / "gcps.csv").write_text("\n".join(lines) + "\n")
    lines = ["imageName X Y Z Omega Phi Kappa"]
    for p, c, r in zip(photos, centres, rots, strict=True):
        o = opk_deg(r)
        lines.append(f"{p}.JPG {c[0]:.6f} {c[1]:.6f} {c[2]:.6f} {o[0]:.9f} {o[1]:.9f} {o[2]:.9f}")
    (p4 / "flight_calibrated_external_camera_parameters.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    import sys

    # ``--dense DIR``: the runnable samples of examples/import-samples
    if len(sys.argv) == 3 and sys.argv[1] == "--dense":
        main(Path(sys.argv[2]), n_grid=14, noise_px=0.3)
    else:
        main()
