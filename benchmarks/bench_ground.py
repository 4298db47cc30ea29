"""The ground stage alone against photos: time, solutions, iterations, rejections.

Usage::

    python benchmarks/bench_ground.py                       # 100 300 1000 3000 10000 photos
    python benchmarks/bench_ground.py --photos 100 1000 --keep /tmp/strips

Each case is a drone strip of ``benchmarks/bench_scale.py`` (the package's
simulator, about 100 image points per photo), loaded and formed as
``stripaero run`` does it; the ground stage (every model at once,
:func:`strip_aerotri.ground.models.adjust_models_to_ground`, the stage
report.json's ``timings_s.ground`` times) then runs in this process with one
BLAS thread.  Printed per case: photos, determinations (model points),
wall and CPU seconds of the stage, the solutions (one per snooping round),
the Gauss-Newton iterations over all of them, the groups of models of the
start of a long strip (:mod:`strip_aerotri.geometry.grouped_start`; 0 when
the strip starts from J's similarity) and the iterations of their
adjustment, the rejections, the passes of the plan/height iteration and the
process's peak memory; then the log-log slope of CPU time against photos.  ``--keep DIR`` keeps the formed strips
(pickled) for the next run: strip formation is not what is timed.
"""

from __future__ import annotations

import argparse
import pickle
import resource
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_scale import slope, write_case

import strip_aerotri.ground.models as ground_models
from strip_aerotri import load_project
from strip_aerotri._threads import limit_blas_threads
from strip_aerotri.pipeline import form_strip_of


class _Counted:
    """``adjust_units`` as the ground stage calls it, counting calls and iterations."""

    def __init__(self) -> None:
        self.inner = ground_models.adjust_units
        self.solutions = 0
        self.iterations = 0

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        result = self.inner(*args, **kwargs)
        self.solutions += 1
        self.iterations += result.iterations
        return result


class _Grouped:
    """``grouped_start`` as the ground stage calls it: its groups and iterations."""

    def __init__(self) -> None:
        self.inner = ground_models.grouped_start
        self.groups = 0
        self.iterations = 0

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        result = self.inner(*args, **kwargs)
        self.groups += result.groups
        self.iterations += result.iterations
        return result


def _strip(photos: int, folder: Path) -> tuple[Any, ...]:
    """(control, crs, lines, options, blunders, strip) of the case, formed once."""
    cached = folder / f"strip-{photos}.pkl"
    if cached.exists():
        loaded: tuple[Any, ...] = pickle.loads(cached.read_bytes())
        return loaded
    toml = write_case(folder / f"strip-{photos}", 1, photos)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        project = load_project(toml)
        strip = form_strip_of(project.observations, project.adjustment)
    case = (
        project.control, project.crs, project.straight_lines, project.adjustment,
        project.blunders, strip,
    )  # fmt: skip
    cached.write_bytes(pickle.dumps(case))
    return case


@limit_blas_threads
def run(photos: int, folder: Path) -> dict[str, float]:
    """One case; its figures (see the module docstring)."""
    control, crs, lines, adjustment, blunders, strip = _strip(photos, folder)
    counted = _Counted()
    grouped = _Grouped()
    ground_models.adjust_units = counted  # type: ignore[assignment]
    ground_models.grouped_start = grouped  # type: ignore[assignment]
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ground = ground_models.adjust_models_to_ground(
                strip, control, crs, lines=lines, options=adjustment.ground_options(),
                blunders=blunders,
            )  # fmt: skip
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        ground_models.adjust_units = counted.inner
        ground_models.grouped_start = grouped.inner
    return {
        "photos": photos,
        "determinations": int(strip.model.shape[0]),
        "wall": wall,
        "cpu": cpu,
        "solutions": counted.solutions,
        "iterations": counted.iterations,
        "groups": grouped.groups,
        "group_iterations": grouped.iterations,
        "rejections": len(ground.rejections),
        "passes": ground.passes,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, nargs="*", default=[100, 300, 1000, 3000, 10000])
    parser.add_argument("--keep", type=Path, help="keep the formed strips in this folder")
    args = parser.parse_args(argv)
    print(
        f"{'photos':>6s} {'determ.':>8s} {'wall s':>7s} {'CPU s':>7s} {'solutions':>9s} "
        f"{'iterations':>10s} {'groups':>6s} {'(iter.)':>7s} {'rejected':>8s} {'passes':>6s} "
        f"{'peak MB':>7s}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        rows = []
        for photos in args.photos:
            r = run(photos, folder)
            rows.append(r)
            print(
                f"{photos:6d} {r['determinations']:8d} {r['wall']:7.2f} {r['cpu']:7.2f} "
                f"{r['solutions']:9d} {r['iterations']:10d} {r['groups']:6d} "
                f"{r['group_iterations']:7d} {r['rejections']:8d} "
                f"{r['passes']:6d} {r['peak_mb']:7.0f}",
                flush=True,
            )
    if len(rows) >= 2:
        s = slope([int(r["photos"]) for r in rows], [r["cpu"] for r in rows])
        span = f"{rows[0]['photos']}-{rows[-1]['photos']}"
        print(f"slope log(CPU) / log(photos): {s:.2f} over {span}")


if __name__ == "__main__":
    main()
