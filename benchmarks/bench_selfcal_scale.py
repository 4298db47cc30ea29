"""The cost of ``self_calibration = "auto"`` on a long strip, against the plain refinement.

Usage::

    python benchmarks/bench_selfcal_scale.py                 # 2000 photos, 5 pairs
    python benchmarks/bench_selfcal_scale.py --photos 300 --repeat 3
    python benchmarks/bench_selfcal_scale.py --photos 1000 --set k1,k2,p1,p2,b1,b2

The strip is ``bench_scale.py``'s simulated drone strip (1-inch camera at
120 m, 80 % forward overlap, about 100 image points per photo, control at
both ends).  The strip method runs once, as ``stripaero run`` does; then its
bundle refinement (:func:`strip_aerotri.bundle.refine.refine_bundle`, the
bundle stage of ``refine = "bundle"``) runs in turn without and with
``self_calibration = "auto"`` (plain, auto, plain, auto, ...) in the same
process, with one thread, so that a drift of the machine's speed moves both
alike.  Printed per run and as medians: the refinement's CPU time (the
process's, ``time.process_time``) and wall time, the ratios auto / plain of
each pair, the set ``"auto"`` kept and the check RMSE of both (which agree
when nothing is kept); with the load average before and after.  CPU time is
the figure to quote on a shared machine.  ``--set`` gives a list of
parameters to estimate instead of ``"auto"`` (the name "auto" in the printout
stays): what one self-calibrating refinement costs, its image rows mapped to
the observations' space included.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--photos", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=5, help="pairs of runs")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--set", default="auto", help='"auto" or a comma-separated list')
    args = parser.parse_args(argv)
    os.environ.setdefault("STRIPAERO_WORKERS", "1")

    from bench_scale import STRIP_EXTRA_POINTS

    from strip_aerotri import simulate_strip
    from strip_aerotri.bundle.refine import refine_bundle
    from strip_aerotri.options import SelfCalibration
    from strip_aerotri.pipeline import triangulate

    sim = simulate_strip(
        args.photos, preset="drone", seed=args.seed, extra_points_per_photo=STRIP_EXTRA_POINTS
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        strip = triangulate(sim.observations, sim.control, sim.crs)
    print(
        f"{args.photos} photos, {sim.observations.photo.size} image points; load average "
        f"before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    family = "auto" if args.set == "auto" else tuple(args.set.split(","))
    cases = {"plain": None, "auto": SelfCalibration(family)}
    runs: dict[str, list[tuple[float, float]]] = {"plain": [], "auto": []}
    rmse: dict[str, tuple[float, float]] = {}
    kept: tuple[str, ...] = ()
    print(f"{'pair':>4s} {'case':>5s} {'cpu s':>7s} {'wall s':>7s}")
    for i in range(args.repeat):
        for name, spec in cases.items():
            c0, w0 = time.process_time(), time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                refined = refine_bundle(strip, self_calibration=spec)
            cpu, wall = time.process_time() - c0, time.perf_counter() - w0
            runs[name].append((cpu, wall))
            stats = refined.check_statistics
            rmse[name] = (stats.rmse_plan, float(stats.rmse[2]))
            if refined.self_calibration is not None:
                kept = refined.self_calibration.kept
            print(f"{i:4d} {name:>5s} {cpu:7.2f} {wall:7.2f}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for name in cases:
        cpu = statistics.median(r[0] for r in runs[name])
        wall = statistics.median(r[1] for r in runs[name])
        plan, height = rmse[name]
        print(
            f"median {name:>5s}: cpu {cpu:.2f} s, wall {wall:.2f} s; check RMSE "
            f"{plan:.6f} / {height:.6f} m"
        )
    pairs = list(zip(runs["auto"], runs["plain"], strict=True))
    for j, what in ((0, "cpu"), (1, "wall")):
        ratios = [a[j] / p[j] for a, p in pairs]
        print(
            f"auto / plain, {what}: median {statistics.median(ratios):.2f} "
            f"(pairs {', '.join(f'{r:.2f}' for r in ratios)})"
        )
    print(f"auto kept: {', '.join(kept) or 'nothing'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
