"""The rolling shutter's motion over noise draws: is it unbiased?

Each ray is read at the row where it lands, its true position ``x̂``
(``x̂ + Δ(x̂) = x(S + s(x̂) d, R, X)``, ``bundle/_observation_space.py``).
Read at the measured row instead, the projection carries the measurement's
error ``e`` as ``u aᵀ e`` (``u = ∂x/∂s``, ``a = ∂s/∂x``): the residual is
``(I - u aᵀ)`` times the error, a scale of the rows' axis that moves with
the motion, and the least squares draw the motion's component along the
rows by about ``sd (r / 2) (c / H) / h`` of its standard deviations (``sd``
in m, ``r`` the redundancy, ``c / H`` the image scale in mm per m, ``h`` the
readout's extent in mm), as a scaled residual drew c
(``bench_selfcal_c_pull.py``).

The network is ``tests/test_shutter.py``'s (two strips of six photos, c =
100 mm at 1000 m, rows read along image y over 120 mm, motions of 0.3-0.9
m per strip, 1 point in 12 controlled); per component of the two motions
the mean of (estimate - truth) / sd over the draws, its standard error and
the spread of the deviations (1 when the sd is right).

    python benchmarks/bench_shutter_rows.py --noise 0.3 --draws 100
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_shutter as network  # noqa: E402
from strip_aerotri.bundle.adjust import bundle_adjust  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--noise", type=float, default=0.3, help="image noise, mm")
    parser.add_argument("--draws", type=int, default=100)
    args = parser.parse_args(argv)
    devs, redundancy = [], 0
    for seed in range(100, 100 + args.draws):
        obs, shutter, centres, rotations, points = network._network(
            network.TRUTH, seed=seed, noise_mm=args.noise
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = bundle_adjust(
                obs, centres, rotations, points, control_xyz=network._control(points),
                control_sigma=0.05, motion=shutter,
            )  # fmt: skip
        assert res.motion is not None
        devs.append(((res.motion.values - network.TRUTH) / res.motion.std).ravel())
        redundancy = res.redundancy
    d = np.array(devs)
    print(f"noise {args.noise} mm, {args.draws} draws, redundancy {redundancy}")
    print("component          " + " ".join(f"{g} {a}".rjust(6) for g in "12" for a in "XYZ"))
    for label, row in (
        ("mean (est-true)/sd", d.mean(0)),
        ("its standard error", d.std(0, ddof=1) / np.sqrt(args.draws)),
        ("spread of the devs", d.std(0, ddof=1)),
    ):
        print(f"{label:18s} " + " ".join(f"{v:+6.3f}" for v in row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
