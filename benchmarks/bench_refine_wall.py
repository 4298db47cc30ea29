"""The bundle refinement against tuned Ceres, wall and CPU time, taken in turn.

Run from the repository root (Ceres through pycolmap:
``pip install -r benchmarks/requirements-peers.txt``)::

    python benchmarks/bench_refine_wall.py                        # drone-1000
    python benchmarks/bench_refine_wall.py --cases drone-1000 block-10x300 --repeat 9
    python benchmarks/bench_refine_wall.py --workers 1 2 auto     # the thread settings compared

The cases are :func:`bench_peers.simulate_case`'s (``drone-M``: a drone
strip of M photos, about 100 points per photo, control every 10 models;
``block-SxM``: S strips of M photos).  The strip method runs once; from its
result, in turn and ``--repeat`` times each:

* **ours, workers=N** - the refinement of ``refine = "bundle"``
  (:func:`strip_aerotri.bundle.refine.refine_bundle`; a block's inside
  ``triangulate_block``), timed as report.json's ``timings_s.bundle`` (the
  bundle with its blunder tests and cofactors), with
  ``STRIPAERO_WORKERS=N`` (``auto``: the variable unset, the rule of
  ``_threads.worker_count``);
* **ceres tuned** - pycolmap's Ceres bundle adjuster (two threads) with the
  settings of ``bench_peers.CERES_TUNED`` from the same start (the strip
  method's photos and points), its solve alone.

Printed per row: median wall seconds, median CPU seconds (user + system of
the whole process during the call, every thread counted), and the median
over the rounds of the wall-time ratio to Ceres in the same round (the
rounds alternate, so a change of the machine's load falls on both); then
the load average before and after.  The machine is shared: CPU time is the
steadier figure, and the wall-time ratio means most where the load stays
below the cores.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_peers  # noqa: E402

from strip_aerotri import StripAerotriWarning  # noqa: E402
from strip_aerotri.bundle.refine import refine_bundle  # noqa: E402
from strip_aerotri.geometry.rotation import matrix_from_opk  # noqa: E402


def _strip(sim):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        if hasattr(sim, "strips"):
            from strip_aerotri.observations import StripSpec
            from strip_aerotri.pipeline import triangulate_block

            specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
            return triangulate_block(sim.observations, sim.control, sim.crs, specs)
        return bench_peers.triangulate(sim.observations, sim.control, sim.crs)


def _ours(sim, strip, workers: str) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """(wall, CPU) seconds of the refinement with ``workers``: the call that
    report.json's ``timings_s.bundle`` times (a block's refinement is timed
    inside a whole ``triangulate_block`` run)."""
    if workers == "auto":
        os.environ.pop("STRIPAERO_WORKERS", None)
    else:
        os.environ["STRIPAERO_WORKERS"] = workers
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        if hasattr(sim, "strips"):
            import strip_aerotri.block.strips as block_strips
            from strip_aerotri.observations import StripSpec
            from strip_aerotri.pipeline import triangulate_block

            seen: list[tuple[float, float]] = []
            refine = block_strips._refine

            def timed(*args, **kwargs):  # type: ignore[no-untyped-def]
                t0, c0 = time.perf_counter(), time.process_time()
                out = refine(*args, **kwargs)
                seen.append((time.perf_counter() - t0, time.process_time() - c0))
                return out

            block_strips._refine = timed
            try:
                specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
                triangulate_block(sim.observations, sim.control, sim.crs, specs, refine="bundle")
            finally:
                block_strips._refine = refine
            return seen[0]
        t0, c0 = time.perf_counter(), time.process_time()
        refine_bundle(strip)
        return time.perf_counter() - t0, time.process_time() - c0


class _CpuClock:
    perf_counter = staticmethod(time.process_time)


def _ceres(sim, start) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """(wall, CPU) seconds of tuned Ceres's solve from ``start``."""
    _, wall = bench_peers.ceres(sim, *start, tuned=True)
    real = bench_peers.time
    bench_peers.time = _CpuClock  # the same call, its solve timed by the CPU clock
    try:
        _, cpu = bench_peers.ceres(sim, *start, tuned=True)
    finally:
        bench_peers.time = real
    return wall, cpu


def run_case(name: str, repeat: int, workers: list[str], seed: int) -> None:
    sim = bench_peers.simulate_case(name, seed)
    strip = _strip(sim)
    start = (strip.photo_centres, matrix_from_opk(strip.photo_opk), strip.points)
    rows: dict[str, list[tuple[float, float]]] = {f"ours, workers={w}": [] for w in workers}
    rows["ceres tuned (2 threads)"] = []
    load0 = os.getloadavg()[0]
    _ours(sim, strip, workers[0])  # warm: the imports and the caches of the first call
    for _ in range(repeat):
        for w in workers:
            rows[f"ours, workers={w}"].append(_ours(sim, strip, w))
        rows["ceres tuned (2 threads)"].append(_ceres(sim, start))
    load1 = os.getloadavg()[0]
    obs = sim.observations
    print(
        f"\n{name}: {obs.n_photos} photos, {obs.photo.size} observations; load average "
        f"{load0:.2f} -> {load1:.2f} on {os.cpu_count()} cores; {repeat} rounds"
    )
    print(f"{'':28s} {'wall s':>8s} {'CPU s':>8s} {'wall / ceres':>13s}")
    ceres = rows["ceres tuned (2 threads)"]
    med = statistics.median
    for label, values in rows.items():
        ratio = med(v[0] / c[0] for v, c in zip(values, ceres, strict=True))
        print(
            f"{label:28s} {med(v[0] for v in values):8.3f} {med(v[1] for v in values):8.3f} "
            f"{ratio:13.2f}"
        )
    sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", nargs="*", default=["drone-1000"])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--workers", nargs="*", default=["1", "auto"])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    for name in args.cases:
        run_case(name, args.repeat, args.workers, args.seed)


if __name__ == "__main__":
    main()
