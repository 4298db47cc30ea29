"""Time and memory of ``stripaero run`` at scale: long strips, wide blocks, cost against photos.

Usage::

    python benchmarks/bench_scale.py                    # every case and the curve (long)
    python benchmarks/bench_scale.py --quick            # small cases: a few seconds
    python benchmarks/bench_scale.py --cases strip-1000 strip-1000-bundle --threads 1
    python benchmarks/bench_scale.py --curve-only --curve 100 300 1000 3000 10000

Every case is a project written by the package's simulator (drone preset:
1-inch camera at 120 m, 80 % forward overlap, about 100 image points per
photo) and run by the installed ``stripaero -q run`` in a fresh child
process, report included.  For each run the table gives the size (photos,
observations), the wall time, the child's peak memory (``ru_maxrss`` of
``os.wait4``), the stages' own timings from ``report.json`` and the ratio to
the case's floor (time / floor; memory / floor).

The cases:

* ``strip-1000``, ``strip-1000-bundle``: a 1000-photo strip, default and
  ``refine = "bundle"`` (floors 1.5 s and 2.5 s);
* ``block-10x300``, ``block-10x300-bundle``: ten strips of 300 photos
  (floors 10 s / 1 GB and 15 s / 1.5 GB);
* ``block-20x500``: twenty strips of 500 photos, about a million
  observations (floor 60 s / 4 GB);
* the curve: strips of ``--curve`` photos (default 100 to 10 000), with the
  least-squares slope of log(time) against log(photos) (floor 1.1), of the
  wall time and of the CPU time.

``--quick`` runs a 30-photo strip with its refinement, a 2 x 10 block and
a curve of 15 and 30 photos, with one BLAS thread: it shows that the script
works (tests/test_bench_scale.py), not the floors.

``--project CASE=STRIP_TOML`` runs a project from elsewhere (another
simulator, real data) as the case CASE, with that case's floors, instead of
the package's simulation; given alone, only those cases run.

``--timeout S`` stops a run after S seconds (default 1800) and shows it
without a result; a run that fails is shown with its error line; the
others go on.

``--threads`` runs every case with the package's BLAS limit (``1``: one
thread, the default of the adjustments), with BLAS's own threads (``auto``:
``STRIPAERO_BLAS_THREADS=auto``, OpenBLAS's one thread per core) or both
(``both``, the default), and prints their ratio.  The load average is
printed before and after: the machine's other work moves single timings.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

#: ``extra_points_per_photo`` for about 100 image points per photo (measured:
#: strips 102 per photo, blocks of ten strips 104).
STRIP_EXTRA_POINTS = 18
BLOCK_EXTRA_POINTS = 9

#: (seconds, GB) of each case's floor; None where there is none.
FLOORS: dict[str, tuple[float | None, float | None]] = {
    "strip-1000": (1.5, None),
    "strip-1000-bundle": (2.5, None),
    "block-10x300": (10.0, 1.0),
    "block-10x300-bundle": (15.0, 1.5),
    "block-20x500": (60.0, 4.0),
}
SLOPE_FLOOR = 1.1
CASES = tuple(FLOORS)
QUICK_CASES = ("strip-30-bundle", "block-2x10")
CURVE = (100, 300, 1000, 3000, 10000)
QUICK_CURVE = (15, 30)


def parse_case(name: str) -> tuple[int, int, bool]:
    """``strip-M[-bundle]`` or ``block-SxM[-bundle]`` -> (strips, photos per strip, refine)."""
    parts = name.split("-")
    refine = parts[-1] == "bundle"
    if refine:
        parts = parts[:-1]
    try:
        if parts[0] == "strip" and len(parts) == 2:
            return 1, int(parts[1]), refine
        if parts[0] == "block" and len(parts) == 2:
            strips, photos = parts[1].split("x")
            return int(strips), int(photos), refine
    except ValueError:
        pass
    raise ValueError(f"Expected a case strip-M, block-SxM (optionally -bundle), got {name!r}")


def write_case(
    folder: Path, strips: int, photos: int, *, refine: bool = False, seed: int = 1
) -> Path:
    """Write the simulated project of a case into ``folder``; its ``strip.toml``."""
    from strip_aerotri import simulate_block, simulate_strip

    folder.mkdir(parents=True, exist_ok=True)
    if strips == 1:
        sim = simulate_strip(
            photos, preset="drone", seed=seed, extra_points_per_photo=STRIP_EXTRA_POINTS
        )
        toml = sim.write_project(folder)
    else:
        block = simulate_block(
            strips, photos, preset="drone", seed=seed, extra_points_per_photo=BLOCK_EXTRA_POINTS
        )
        toml = block.write_project(folder)
    if refine:
        text = toml.read_text(encoding="utf-8")
        toml.write_text(text.replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n', 1))
    return toml


@dataclass
class Run:
    """One ``stripaero run`` in a child process."""

    wall_s: float
    peak_mb: float
    exit_code: int
    cpu_s: float = 0.0  # user + system of the child and the processes it waited for
    stages: dict[str, float] = field(default_factory=dict)
    failed: str = ""  # why the run gave no result (its error, or the timeout)


def run_once(exe: str, toml: Path, out: Path, threads: str, timeout: float = 1800.0) -> Run:
    """Run the project once; wall time, peak memory of the child, report.json's
    timings; a run still going after ``timeout`` seconds is killed."""
    env = dict(os.environ)
    env.pop("STRIPAERO_BLAS_THREADS", None)
    if threads != "1":
        env["STRIPAERO_BLAS_THREADS"] = threads
    shutil.rmtree(out, ignore_errors=True)
    killed: list[bool] = []
    with tempfile.TemporaryFile() as errors:
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            [exe, "-q", "run", str(toml), "--out", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=errors,
            env=env,
        )
        timer = threading.Timer(timeout, lambda: (killed.append(True), proc.kill()))
        timer.start()
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own resource usage
        timer.cancel()
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        errors.seek(0)
        stderr = errors.read().decode(errors="replace").strip()
    peak = usage.ru_maxrss / 1024.0
    cpu = usage.ru_utime + usage.ru_stime
    if killed:
        return Run(wall, peak, proc.returncode, cpu, failed=f"stopped after {timeout:g} s")
    if proc.returncode not in (0, 3):  # 3: the run met the data but failed a tolerance
        line = stderr.splitlines()[-1] if stderr else ""
        return Run(wall, peak, proc.returncode, cpu, failed=f"exit {proc.returncode}: {line}")
    stages: dict[str, float] = {}
    report = out / "report.json"
    if report.exists():
        stages = json.loads(report.read_text(encoding="utf-8")).get("timings_s", {}) or {}
    return Run(wall, peak, proc.returncode, cpu, stages)


def compile_package() -> str:
    """Compile the package's bytecode, as ``pip install`` does, and say so.

    An editable install (``pip install -e .``) under ``PYTHONDONTWRITEBYTECODE``
    compiles the package's 130 modules from source at every start of
    ``stripaero``: 0.25-0.3 s of CPU that an installed package does not
    spend.  The runs are timed as installed; ``--no-compile`` times them as
    they are.
    """
    import compileall

    import strip_aerotri

    folder = Path(strip_aerotri.__file__).parent
    done = compileall.compile_dir(folder, quiet=1, force=False)
    state = "compiled" if done else "could not be compiled (timed as they are)"
    return f"bytecode of {folder}: {state} (as pip install does; --no-compile leaves it)"


def project_size(toml: Path) -> tuple[int, int]:
    """(photos, image observations) of a project, as the package reads it."""
    import warnings

    from strip_aerotri import StripAerotriWarning, load_project

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        project = load_project(toml)
    return len(project.photo_ids), int(project.observations.photo.size)


def _fmt_floor(value: float, floor: float | None) -> str:
    return f"{value / floor:5.2f}" if floor else "    -"


def measure(
    exe: str,
    name: str,
    tmp: Path,
    threads: list[str],
    repeat: int,
    project: Path | None = None,
    timeout: float = 1800.0,
) -> dict[str, object]:
    """Write (or take ``project``) and run one case; a row per thread setting
    (the median of ``repeat`` runs)."""
    if project is None:
        strips, photos, refine = parse_case(name)
        toml = write_case(tmp / name, strips, photos, refine=refine)
    else:
        toml = project.resolve()
    n_photos, n_obs = project_size(toml)
    floor_s, floor_gb = FLOORS.get(name, (None, None))
    rows: dict[str, object] = {"case": name, "photos": n_photos, "observations": n_obs}
    for t in threads:
        runs = [run_once(exe, toml, tmp / name / f"out-{t}", t, timeout) for _ in range(repeat)]
        if any(r.failed for r in runs):
            failed = next(r.failed for r in runs if r.failed)
            rows[t] = {"failed": failed}
            print(f"{name:20s} {n_photos:7d} {n_obs:9d}  {t:>4s}  no result: {failed}")
            continue
        wall = statistics.median(r.wall_s for r in runs)
        cpu = statistics.median(r.cpu_s for r in runs)
        peak = max(r.peak_mb for r in runs)
        stages = runs[-1].stages
        rows[t] = {"wall_s": wall, "cpu_s": cpu, "peak_mb": peak, "stages": stages}
        stage_text = ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
        print(
            f"{name:20s} {n_photos:7d} {n_obs:9d}  {t:>4s}  {wall:8.2f} "
            f"{peak:8.0f}  {_fmt_floor(wall, floor_s)} "
            f"{_fmt_floor(peak / 1024.0, floor_gb)} {cpu:6.2f}   {stage_text}",
            flush=True,
        )
    one, auto = rows.get("1"), rows.get("auto")
    if isinstance(one, dict) and isinstance(auto, dict) and "wall_s" in one and "wall_s" in auto:
        print(f"{'':20s} BLAS's own threads / one thread: {auto['wall_s'] / one['wall_s']:.2f}")
    return rows


def slope(photos: list[int], seconds: list[float]) -> float:
    """Least-squares slope of log(seconds) against log(photos)."""
    x = [math.log(p) for p in photos]
    y = [math.log(s) for s in seconds]
    mx, my = statistics.fmean(x), statistics.fmean(y)
    return sum((a - mx) * (b - my) for a, b in zip(x, y, strict=True)) / sum(
        (a - mx) ** 2 for a in x
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small cases, short curve")
    parser.add_argument("--cases", nargs="*", help="case names (strip-M, block-SxM, -bundle)")
    parser.add_argument("--curve", type=int, nargs="*", help="photos of the strips of the curve")
    parser.add_argument("--curve-only", action="store_true")
    parser.add_argument("--no-curve", action="store_true")
    parser.add_argument(
        "--threads",
        choices=("1", "auto", "both"),
        default=None,
        help="BLAS threads of the runs (default: both; with --quick: 1)",
    )
    parser.add_argument("--repeat", type=int, default=1, help="runs per case (median)")
    parser.add_argument(
        "--no-compile",
        action="store_true",
        help="leave the package's bytecode as it is (see compile_package)",
    )
    parser.add_argument("--json", type=Path, help="also write the results to this file")
    parser.add_argument(
        "--timeout",
        type=float,
        default=1800.0,
        help="seconds after which a run is stopped and shown without a result (default 1800)",
    )
    parser.add_argument(
        "--project",
        action="append",
        default=[],
        metavar="CASE=STRIP_TOML",
        help="run this project (from any source) as the case CASE instead of simulating it; "
        "repeatable (e.g. strip-1000=data/strip/strip.toml)",
    )
    args = parser.parse_args(argv)
    exe = shutil.which("stripaero")
    if exe is None:
        sys.exit("stripaero is not installed (pip install .)")
    given: dict[str, Path] = {}
    for item in args.project:
        case, sep, path = item.partition("=")
        if not sep or not Path(path).is_file():
            sys.exit(f"--project {item}: expected CASE=STRIP_TOML naming an existing file")
        given[case] = Path(path)
    cases = args.cases if args.cases is not None else QUICK_CASES if args.quick else CASES
    if given and args.cases is None:
        cases = list(given)
    curve = args.curve if args.curve is not None else QUICK_CURVE if args.quick else CURVE
    setting = args.threads or ("1" if args.quick else "both")
    threads = ["1", "auto"] if setting == "both" else [setting]
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if not args.no_compile:
        print(compile_package())
    print(
        f"{'case':20s} {'photos':>7s} {'obs':>9s}  {'BLAS':>4s}  {'wall s':>8s} "
        f"{'peak MB':>8s}  {'t/flr':>5s} {'m/flr':>5s} {'cpu s':>6s}   "
        "stages (report.json timings_s)"
    )
    curves: dict[str, object] = {}
    results: dict[str, object] = {"cases": [], "curve": curves}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        if not args.curve_only:
            results["cases"] = [
                measure(exe, c, tmp, threads, args.repeat, given.get(c), args.timeout)
                for c in cases
            ]
        if not args.no_curve and len(curve) >= 2:
            rows = [
                measure(exe, f"strip-{m}", tmp, threads, args.repeat, timeout=args.timeout)
                for m in curve
            ]
            for t in threads:
                runs = [r[t] for r in rows]
                if not all(isinstance(r, dict) and "wall_s" in r for r in runs):
                    print(f"slope, BLAS {t}: not computed (a run gave no result)")
                    continue
                secs = [float(r["wall_s"]) for r in runs]
                cpus = [float(r["cpu_s"]) for r in runs]
                s, s_cpu = slope(list(curve), secs), slope(list(curve), cpus)
                curves[t] = {
                    "photos": list(curve), "wall_s": secs, "slope": s, "cpu_s": cpus,
                    "slope_cpu": s_cpu,
                }
                print(
                    f"slope log(time) / log(photos), BLAS {t}: {s:.2f} over "
                    f"{curve[0]}-{curve[-1]} photos (floor {SLOPE_FLOOR}); "
                    f"of the CPU time {s_cpu:.2f}"
                )
    print(
        f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}; "
        f"{time.perf_counter() - started:.0f} s in all"
    )
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
