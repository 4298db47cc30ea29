"""The pull on a self-calibrated c, on simulated blocks with a known error of c.

A residual written ``x(S, R, X) - (x_obs + D(x_obs))`` scales with ``1 - dc
/ c`` where c is corrected as ``D = -(x/c) dc``, so its sum of squares falls
as c grows and the estimate is drawn towards a larger c by about ``Q_cc
Omega / c = sd(c)^2 r / c`` (Omega = sigma0^2 r): ``sd(c) r / c`` of its own
standard deviations (docs/bundle.md, "Self-calibration").  The refinement
takes its residuals in the observations' space (``x̂ - x_obs``, ``x̂ + D(x̂) =
x``) and has no such pull; the last column is the reference bundle's
re-solve with the residuals mapped (``bench_fc300x_selfcal_bias.py``), the
same c to 1e-9 of it.

Run from the repository root::

    python benchmarks/bench_selfcal_c_pull.py --seeds 10

Drone blocks of :func:`strip_aerotri.simulate_block` (3 strips of 8 and of
20 photos, c = 8.8 mm, crs "local") with an uncorrected error of c of +0.05
mm (``camera_errors``), GNSS centres with 2 cm of noise (without them c is
the flying height's twin), ``refine = "bundle"`` with ``self_calibration =
["c"]``.  Printed per block: the redundancy, c's mean standard deviation,
the mean of (estimate - truth) / sd over the seeds with its standard error,
and the pull ``sd(c) r / c`` the former residuals had.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_fc300x_selfcal_bias as bias  # noqa: E402
from strip_aerotri.observations import GnssCentres, StripSpec
from strip_aerotri.options import SelfCalibration
from strip_aerotri.pipeline import triangulate_block
from strip_aerotri.simulate import simulate_block

ERROR_C_MM = 0.05


def one_block(
    n_photos: int, seed: int, error: float = ERROR_C_MM, gnss_sigma: float = 0.02
) -> tuple[float, float, float, int, float]:
    """(estimate - truth, the same mapped, sd of c, redundancy, c) of one simulated block
    whose c is ``error`` mm off, GNSS centres with ``gnss_sigma`` m of noise."""
    sim = simulate_block(3, n_photos, preset="drone", seed=seed, crs="local",
                         camera_errors={"c": error})  # fmt: skip
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    m = sim.truth.photo_centres_crs.shape[0]
    noise = np.random.default_rng(100 + seed).normal(0, gnss_sigma, (m, 3))
    gnss = GnssCentres(tuple(sim.observations.photo_ids), sim.truth.photo_centres_crs + noise,
                       np.full(m, gnss_sigma), np.full(m, gnss_sigma))  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = triangulate_block(sim.observations, sim.control, sim.crs, specs, route="projected",
                                refine="bundle", gnss=gnss, self_calibration=SelfCalibration(("c",)))  # fmt: skip
    (par,) = res.self_calibration.parameters
    _, camera = bias.mapped_solution(res, gnss=(sim.truth.photo_centres_crs + noise, np.full((m, 3), gnss_sigma)))
    c = float(sim.observations.principal_distance)
    return par.value - error, camera["c"] - error, par.std, int(res.redundancy), c


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--photos", type=int, nargs="+", default=[8, 20])
    parser.add_argument("--error", type=float, default=ERROR_C_MM, help="the error of c, mm")
    parser.add_argument("--gnss-sigma", type=float, default=0.02, help="m")
    args = parser.parse_args(argv)
    print(f"{'block':8s} {'redundancy':>10s} {'sd(c) mm':>9s} {'mean (est - true) / sd':>24s} "
          f"{'predicted sd(c) r / c':>22s} {'mapped (est - true) / sd':>26s}")  # fmt: skip
    for n in args.photos:
        rows = np.array([one_block(n, seed, args.error, args.gnss_sigma) for seed in range(args.seeds)])
        z, z_mapped = rows[:, 0] / rows[:, 2], rows[:, 1] / rows[:, 2]
        predicted = np.mean(rows[:, 2] * rows[:, 3] / rows[:, 4])
        spread = np.sqrt(len(z))
        print(f"3 x {n:<4d} {np.mean(rows[:, 3]):10.0f} {np.mean(rows[:, 2]):9.4f} "
              f"{np.mean(z):+12.2f} ± {np.std(z, ddof=1) / spread:.2f}      {predicted:+12.2f}"
              f"      {np.mean(z_mapped):+12.2f} ± {np.std(z_mapped, ddof=1) / spread:.2f}",
              flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
