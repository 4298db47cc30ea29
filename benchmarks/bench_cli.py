"""End-to-end time of ``stripaero run`` on a long strip (project read to outputs written).

Usage::

    python benchmarks/bench_cli.py                 # 1000 photos x 100 points per photo
    python benchmarks/bench_cli.py --photos 300 --points 300 --repeats 5

Writes a project (``strip.toml``, ``image_points.csv``, ``control.csv``) from
the generator of ``bench_strip.py`` into a temporary folder, then runs the
installed ``stripaero run`` in a fresh process several times and prints the
median wall-clock time, with the time of the Python start and imports alone
(``stripaero --version``) for reference, and the stages from the run's own
progress messages.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_strip import make_strip


def write_project(folder: Path, n_photos: int, points_per_photo: int) -> tuple[int, int]:
    obs, control, _ = make_strip(n_photos, points_per_photo)
    photos = ", ".join(f'"{p}"' for p in obs.photo_ids)
    (folder / "strip.toml").write_text(
        "[strip]\n"
        f'name = "Benchmark strip, {n_photos} photos"\n'
        f"photos = [{photos}]\n\n"
        f"[camera]\nprincipal_distance_mm = {obs.principal_distance!r}\n\n"
        '[images]\nfile = "image_points.csv"\n\n'
        '[control]\nfile = "control.csv"\ncrs = "local"\n\n'
        '[adjustment]\nroute = "projected"\npolynomial = 3\n'
        # one section per 20 photos, two control stations each (bench_strip)
        f"sections = {max(n_photos // 20, 1)}\n",
        encoding="utf-8",
    )
    photo_names = [obs.photo_ids[i] for i in obs.photo]
    point_names = [obs.point_ids[i] for i in obs.point]
    with (folder / "image_points.csv").open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["photo", "point", "x", "y", "sigma"])
        w.writerows(
            (p, q, f"{x:.4f}", f"{y:.4f}", "0.005")
            for p, q, (x, y) in zip(photo_names, point_names, obs.xy.tolist(), strict=True)
        )
    with (folder / "control.csv").open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["point", "X", "Y", "H", "type", "sigma_xy", "sigma_h"])
        w.writerows(
            (pid, f"{x:.3f}", f"{y:.3f}", f"{h:.3f}", "full", "0.02", "0.02")
            for pid, (x, y, h) in zip(control.point_ids, control.xyz.tolist(), strict=True)
        )
    return obs.photo.size, len(control.point_ids)


def timed(cmd: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    return time.perf_counter() - t0, done


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=1000)
    parser.add_argument("--points", type=int, default=100, help="points per photo")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    exe = shutil.which("stripaero")
    if exe is None:
        sys.exit("stripaero is not installed (pip install .)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        n_obs, n_control = write_project(folder, args.photos, args.points)
        size = sum(f.stat().st_size for f in folder.iterdir()) / 1e6
        startup = statistics.median(timed([exe, "--version"])[0] for _ in range(args.repeats))
        times = []
        for _ in range(args.repeats):
            elapsed, done = timed([exe, "-v", "run", str(folder / "strip.toml")])
            if done.returncode not in (0, 3):
                sys.exit(f"stripaero run failed ({done.returncode}): {done.stderr.strip()}")
            times.append(elapsed)
        outputs = sum(f.stat().st_size for f in (folder / "out").iterdir()) / 1e6
        print(
            f"{args.photos} photos x {args.points} points per photo: {n_obs} image "
            f"observations, {n_control} control points, {size:.1f} MB of input, "
            f"{outputs:.1f} MB of output"
        )
        print(f"stripaero --version (start-up and imports): {startup:.2f} s")
        print(
            f"stripaero run: median {statistics.median(times):.2f} s "
            f"(runs: {', '.join(f'{t:.2f}' for t in times)}; exit code {done.returncode})"
        )
        print("last run's messages:")
        print(done.stderr.rstrip())


if __name__ == "__main__":
    main()
