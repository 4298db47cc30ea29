"""Time of the report's figures of a long strip: each figure's drawing, their
total against the floor (0.3 s for a 1000-photo strip), and how long a run
waits for them.

Usage::

    python benchmarks/bench_figures.py                    # 1000-photo strip, 9 repeats
    python benchmarks/bench_figures.py --photos 300 --repeats 5
    python benchmarks/bench_figures.py --project path/to/strip.toml
    python benchmarks/bench_figures.py --figures-only     # the per-figure CPU alone

The project (``bench_scale.write_case``: drone preset, about 100 image
points per photo, or ``--project``) is run once; then, in this process:

* **per figure**: CPU time (user + system, ``time.process_time``) of each
  of the four figures of the strip's page, drawn here as with
  ``STRIPAERO_FORK=0``, after :func:`strip_aerotri.report.html.prepare_drawing`
  (the run's drawing process has matplotlib loaded and warm by then);
  medians of ``--repeats``, and their total against the floor;
* **the run's wait**: wall time of writing the result's files with the
  figures drawn by a waiting process (as ``stripaero run`` does: forked and
  prepared before the adjustment), less the same without the page: what
  the figures add to a run's wall time;
* **imports**: wall time of importing matplotlib's Figure and Agg canvas
  (what the drawing process loads) and of pyplot, each in a fresh
  interpreter, for reference.

CPU time is the steadier figure on a shared machine; the load average is
printed before and after.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

FLOOR_S = 0.3
FIGURES = ("figure_layout", "figure_residuals", "figure_parallax", "figure_ties")


def _load() -> str:
    try:
        return " ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "unknown"


def _import_time(statement: str, repeats: int = 3) -> float:
    """Median wall time [s] of ``statement`` in a fresh interpreter."""
    code = f"import time; t = time.perf_counter(); {statement}; print(time.perf_counter() - t)"
    times = [
        float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout)
        for _ in range(repeats)
    ]
    return statistics.median(times)


def _result(toml: Path):  # type: ignore[no-untyped-def]
    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    project = load_project(toml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        return project, run_project(project)


def per_figure(data, repeats: int) -> dict[str, list[float]]:  # type: ignore[no-untyped-def]
    """CPU seconds of each figure, ``repeats`` times, drawn in this process."""
    import matplotlib

    from strip_aerotri.report import figures, html

    html.prepare_drawing()
    times: dict[str, list[float]] = {name: [] for name in FIGURES}
    paused = getattr(html, "_no_collection", contextlib.nullcontext)  # as draw_figures does
    for _ in range(repeats):
        with paused(), matplotlib.rc_context(html._STYLE):
            for name in FIGURES:
                start = time.process_time()
                getattr(figures, name)(data)
                times[name].append(time.process_time() - start)
    return times


def run_wait(result, project, repeats: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Median wall seconds of writing the files without the page, and with
    the page drawn by a process forked and prepared beforehand."""
    from strip_aerotri.report.aside import Standby
    from strip_aerotri.report.html import prepare_drawing
    from strip_aerotri.report.outputs import strip_outputs

    plain, paged = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        strip_outputs(result, project=project, html=False)
        plain.append(time.perf_counter() - start)
        with Standby(prepare_drawing) as standby:
            time.sleep(1.0)  # the adjustment's time: the child imports and warms up
            start = time.perf_counter()
            strip_outputs(result, project=project, standby=standby)
            paged.append(time.perf_counter() - start)
    return statistics.median(plain), statistics.median(paged)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--photos", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--project", type=Path, help="a strip.toml to run instead")
    parser.add_argument(
        "--figures-only", action="store_true", help="only the figures' CPU (no wait, no imports)"
    )
    args = parser.parse_args(argv)

    from strip_aerotri.report.figures import figure_data
    from strip_aerotri.report.record import model_records

    print(f"load average before: {_load()}")
    with tempfile.TemporaryDirectory() as tmp:
        toml = args.project
        if toml is None:
            from bench_scale import write_case

            toml = write_case(Path(tmp) / "strip", 1, args.photos)
        project, result = _result(Path(toml))
    data = figure_data(result, model_records(result))
    os.environ["STRIPAERO_FORK"] = "0"  # every figure drawn here
    times = per_figure(data, args.repeats)
    del os.environ["STRIPAERO_FORK"]
    print(f"{len(project.photo_ids)} photos, {len(data.points)} points, "
          f"{data.n_pairs} pairs; CPU per figure, median of {args.repeats}:")
    total = 0.0
    for name in FIGURES:
        median = statistics.median(times[name])
        total += median
        print(f"  {name:18s} {1000 * median:7.1f} ms   (min {1000 * min(times[name]):.1f})")
    verdict = "met" if total <= FLOOR_S else "NOT met"
    print(f"  {'total':18s} {1000 * total:7.1f} ms   floor {1000 * FLOOR_S:.0f} ms: {verdict}")
    if args.figures_only:
        return 0 if total <= FLOOR_S else 1
    plain, paged = run_wait(result, project, max(1, min(3, args.repeats // 3)))
    print(f"writing the files: {plain:.3f} s without the page, {paged:.3f} s with it "
          f"(figures drawn aside): the run waits {paged - plain:+.3f} s for them")
    runs = max(1, min(3, args.repeats))
    figure_import = _import_time(
        "import matplotlib.figure, matplotlib.backends.backend_agg", runs
    )
    pyplot_import = _import_time("import matplotlib.pyplot", runs)
    print(f"imports: matplotlib Figure + Agg {figure_import:.3f} s, "
          f"pyplot {pyplot_import:.3f} s (fresh interpreter, not in the totals)")
    print(f"load average after: {_load()}")
    return 0 if total <= FLOOR_S else 1


if __name__ == "__main__":
    sys.exit(main())
