"""Build the outputs of a simulated strip and take a screenshot of report.html.

Usage::

    python scripts/screenshot_report.py [OUT_DIR] [--photos N] [--preset film|drone|corridor]
        [--crs EPSG:32634] [--map-scale 2000] [--height 4000]

Writes every output file into OUT_DIR (default ``./report-preview``) and
``OUT_DIR/report.png``, a screenshot of ``report.html`` taken by headless
Chromium (``/usr/bin/chromium``; on Debian ``apt-get install chromium``).
Chromium is not a dependency of the package; without it only the files are
written.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from strip_aerotri.ground.polynomials import GroundOptions, LineSpec
from strip_aerotri.pipeline import triangulate
from strip_aerotri.report.outputs import build_outputs
from strip_aerotri.simulate import simulate_strip


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(html: Path, png: Path, *, width: int = 1280, height: int = 4000) -> bool:
    """Screenshot of ``html`` into ``png`` with headless Chromium; False if none is found."""
    browser = _chromium()
    if browser is None:
        print("chromium not found: no screenshot (apt-get install chromium)", file=sys.stderr)
        return False
    with tempfile.TemporaryDirectory(prefix="stripaero-chromium-") as profile:
        cmd = [
            browser,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={profile}",
            f"--screenshot={png.resolve()}",
            f"--window-size={width},{height}",
            html.resolve().as_uri(),
        ]
        subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    return png.is_file()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="report-preview", type=Path)
    parser.add_argument("--photos", type=int, default=14)
    parser.add_argument("--preset", default="corridor", choices=["film", "drone", "corridor"])
    parser.add_argument("--crs", default="EPSG:32634")
    parser.add_argument("--map-scale", type=float, default=2000.0)
    parser.add_argument("--polynomial", default="auto")
    parser.add_argument("--height", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args(argv)

    t0 = time.perf_counter()
    sim = simulate_strip(
        args.photos,
        preset=args.preset,
        crs=args.crs,
        seed=args.seed,
        control="every_k_models",
        control_every=4,
    )
    lines = [
        LineSpec(point_ids=tuple(ids), weight=weight, name=f"line {k + 1}")
        for k, (ids, weight) in enumerate(sim.lines)
    ]
    polynomial = args.polynomial if args.polynomial == "auto" else int(args.polynomial)
    route = "projected" if args.crs.lower() == "local" else "geocentric"
    result = triangulate(
        sim.observations,
        sim.control,
        sim.crs,
        lines=lines,
        ground_options=GroundOptions(route=route, polynomial=polynomial),
    )
    t1 = time.perf_counter()
    files = build_outputs(result, map_scale=args.map_scale)
    t2 = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (args.out / name).write_bytes(data)
    print(
        f"{len(files)} files in {args.out} (adjustment {t1 - t0:.1f} s, outputs {t2 - t1:.1f} s; "
        f"report.html {len(files['report.html']) / 1e3:.0f} kB)"
    )
    png = args.out / "report.png"
    if screenshot(args.out / "report.html", png, height=args.height):
        print(f"screenshot: {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
