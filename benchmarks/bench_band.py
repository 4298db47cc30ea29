"""The banded Cholesky of the reduced normal equations at the sizes of strips and blocks.

Usage::

    python benchmarks/bench_band.py              # strips and blocks up to 20 x 500
    python benchmarks/bench_band.py --quick      # small sizes only

After the points are eliminated (method.md 6B), the reduced system of a
strip or block of ``n`` photos (``d`` = 6 unknowns each; 7 for models) is a
block band.  Numbered along a strip, a photo shares points with the ``w``
photos on either side (80 % forward overlap: ``w`` = 4); in a block of ``s``
strips numbered across the strips (the classical rule), the half-bandwidth
grows to about ``w s + s`` photos.  This script builds random symmetric
positive definite band matrices of exactly those sizes, times LAPACK's
banded Cholesky (``scipy.linalg.cholesky_banded``) and one solve
(``cho_solve_banded``) with one BLAS thread, and fits ``t = c N b²`` (``N``
= d n unknowns, ``b`` the half-bandwidth in unknowns) to predict the sizes
it does not run.  docs/scaling.md quotes it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded
from threadpoolctl import threadpool_limits


def half_band(strips: int, window: int = 4, d: int = 6) -> int:
    """Half-bandwidth in unknowns of a strip (strips = 1) or a block numbered across."""
    photos = window if strips == 1 else window * strips + strips
    return d * (photos + 1) - 1


def random_band(n: int, b: int, rng: np.random.Generator) -> np.ndarray:
    """Upper band storage (b + 1, n) of a diagonally dominant SPD matrix."""
    band = rng.uniform(-1.0, 1.0, size=(b + 1, n))
    band[b] = 2.0 * (b + 1)  # the diagonal
    return band


def time_band(n: int, b: int, repeat: int) -> tuple[float, float, float]:
    """(factor s, solve s, band MB): the median of ``repeat`` runs."""
    rng = np.random.default_rng(1)
    band = random_band(n, b, rng)
    rhs = rng.standard_normal(n)
    factor, solve = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        chol = cholesky_banded(band, lower=False, check_finite=False)
        t1 = time.perf_counter()
        cho_solve_banded((chol, False), rhs, check_finite=False)
        t2 = time.perf_counter()
        factor.append(t1 - t0)
        solve.append(t2 - t1)
    return statistics.median(factor), statistics.median(solve), band.nbytes / 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    d = 6
    cases = [(1, 1000), (1, 10000), (2, 300), (5, 300), (10, 100), (10, 300)]
    predict = [(10, 300), (20, 500), (40, 500), (60, 1000)]
    if args.quick:
        cases = [(1, 300), (2, 100), (5, 100)]
        predict = [(10, 300), (20, 500)]
    else:
        cases.append((20, 500))
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}; one BLAS thread")
    print(f"{'block':>9s} {'photos':>7s} {'N':>7s} {'b':>5s} {'factor s':>9s} {'solve s':>8s} "
          f"{'band MB':>8s} {'ns per N b^2':>13s}")
    coefficients = []
    with threadpool_limits(limits=1, user_api="blas"):
        for s, m in cases:
            n, b = d * s * m, half_band(s, d=d)
            factor, solve, mb = time_band(n, b, args.repeat)
            per = factor / (n * b * b) * 1e9
            coefficients.append(per)
            print(f"{s:>4d} x {m:<4d}{s * m:>7d} {n:>7d} {b:>5d} {factor:>9.3f} {solve:>8.3f} "
                  f"{mb:>8.1f} {per:>13.3f}")
    c = statistics.median(coefficients)
    print(f"t = c N b^2 with c = {c:.3f} ns (median of the rows above); predicted:")
    for s, m in predict:
        n, b = d * s * m, half_band(s, d=d)
        print(f"{s:>4d} x {m:<4d}{s * m:>7d} {n:>7d} {b:>5d} factor {c * n * b * b / 1e9:8.2f} s, "
              f"band {8 * n * (b + 1) / 1e6:8.0f} MB")


if __name__ == "__main__":
    main()
