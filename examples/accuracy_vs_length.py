"""Accuracy of strip formation against strip length (random error propagation).

Simulates film strips (1:8000, c = 152.87 mm, 60 % overlap, 5 µm image noise
by default) of increasing length, forms each strip model with
:func:`strip_aerotri.strip.chaining.form_strip`, removes the best-fitting 3D
similarity against the true ground points and reports the RMS of what is
left, split into the along-strip (X), across-strip (Y) and height (Z)
components, in metres.

Theory: the scale and the rotation of every model are transferred from the
previous one; their random errors add up as a random walk along the strip.
A random walk of the scale (or of the pitch / yaw angle) displaces the
centres by the sum of a random walk, whose deviation grows like n^(3/2), and
a best-fit similarity removes only its linear part, so the RMS error grows
like n^(3/2) for long strips, on top of a constant from the noise of a single
model (and a term like n^(1/2) from the random walk of the roll angle and of
the base components).  The script fits

    e(n)² = a² + b² n³          (the theory, two parameters)
    e(n)² = a² + b² n^γ         (free exponent)

and prints the table and both fits.  Run::

    python examples/accuracy_vs_length.py
    python examples/accuracy_vs_length.py --replicas 100 --figure out/

The figure (``accuracy_vs_length.png``) is written only when ``--figure`` is
given (matplotlib with the Agg backend, no display needed).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from strip_aerotri.simulate import simulate_strip
from strip_aerotri.strip.chaining import StripOptions, form_strip

try:  # gross-error tests are off: the study is about random errors alone
    from strip_aerotri.blunders import BlunderOptions

    NO_TESTS = {"blunders": BlunderOptions(action="off")}
except ImportError:  # a version without gross-error tests
    NO_TESTS = {}

DEFAULT_LENGTHS = (6, 9, 12, 18, 24, 36, 48, 72, 100)


def best_fit_residuals(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Target minus source mapped by the least-squares 3D similarity (Umeyama 1991).

    source, target : (N, 3); returns (N, 3) residuals in target units.
    """
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    a, b = source - cs, target - ct
    u, s, vt = np.linalg.svd(b.T @ a)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    rotation = u @ d @ vt
    scale = np.trace(np.diag(s) @ d) / np.sum(a * a)
    return b - scale * a @ rotation.T


def strip_error(n_photos: int, seed: int, noise_mm: float, options: StripOptions) -> np.ndarray:
    """RMS error (along, across, height) in metres of one simulated strip.

    The strip is flown east (heading 90°), so the local east-north-up frame
    of the truth is (along, left, up): X along the strip, Y across.
    """
    sim = simulate_strip(n_photos, image_noise_mm=noise_mm, seed=seed, heading_deg=90.0)
    strip = form_strip(sim.observations, options, **NO_TESTS)
    ok = strip.triangulated
    resid = best_fit_residuals(strip.points[ok], sim.truth.points_local[ok])
    return np.sqrt(np.mean(resid**2, axis=0))


def fit_theory(n: np.ndarray, e2: np.ndarray) -> tuple[float, float]:
    """a², b² of e² = a² + b² n³, least squares on relative residuals."""
    design = np.column_stack([np.ones_like(n), n**3]) / e2[:, None]
    (a2, b2), *_ = np.linalg.lstsq(design, np.ones_like(e2), rcond=None)
    return float(a2), float(b2)


def fit_free(n: np.ndarray, e2: np.ndarray) -> tuple[float, float, float]:
    """a², b², γ of e² = a² + b² n^γ, least squares on log e²."""
    a2, b2 = fit_theory(n, e2)
    start = [np.log(max(a2, 1e-6 * e2.min())), np.log(max(b2, 1e-12)), 2.0]

    def resid(p):
        return np.log(np.exp(p[0]) + np.exp(p[1]) * n ** p[2]) - np.log(e2)

    sol = least_squares(resid, start)
    return float(np.exp(sol.x[0])), float(np.exp(sol.x[1])), float(sol.x[2])


def study(
    lengths=DEFAULT_LENGTHS,
    replicas: int = 40,
    noise_mm: float = 0.005,
    options: StripOptions | None = None,
    seed0: int = 1000,
):
    """Per-coordinate RMS errors, shape (len(lengths), replicas, 3), metres."""
    options = options or StripOptions()
    out = np.empty((len(lengths), replicas, 3))
    for i, n in enumerate(lengths):
        for r in range(replicas):
            out[i, r] = strip_error(n, seed0 + 1000 * i + r, noise_mm, options)
    return out


def bootstrap_gamma(
    lengths: np.ndarray, errors: np.ndarray, rounds: int = 200, seed: int = 7
) -> np.ndarray:
    """Free-fit exponents of bootstrap resamples of the replicas."""
    rng = np.random.default_rng(seed)
    sq = np.sum(errors**2, axis=2)  # (lengths, replicas)
    k = sq.shape[1]
    out = np.empty(rounds)
    for b in range(rounds):
        pick = rng.integers(0, k, (sq.shape[0], k))
        e2 = np.take_along_axis(sq, pick, axis=1).mean(axis=1)
        out[b] = fit_free(lengths, e2)[2]
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicas", type=int, default=40, help="strips per length")
    parser.add_argument(
        "--lengths",
        default=",".join(str(n) for n in DEFAULT_LENGTHS),
        help="comma-separated numbers of photos",
    )
    parser.add_argument("--noise-um", type=float, default=5.0, help="image noise, µm")
    parser.add_argument("--seed", type=int, default=1000, help="first simulation seed")
    parser.add_argument("--figure", type=Path, help="folder for accuracy_vs_length.png")
    args = parser.parse_args(argv)
    lengths = np.array([int(v) for v in args.lengths.split(",")], dtype=np.float64)

    t0 = time.perf_counter()
    errors = study(
        lengths.astype(int).tolist(), args.replicas, args.noise_um / 1000.0, seed0=args.seed
    )
    seconds = time.perf_counter() - t0
    rms = np.sqrt(np.mean(errors**2, axis=1))  # (lengths, 3)
    e2 = np.sum(rms**2, axis=1)
    a2, b2 = fit_theory(lengths, e2)
    fa2, _, gamma = fit_free(lengths, e2)
    gammas = bootstrap_gamma(lengths, errors)
    model = np.sqrt(a2 + b2 * lengths**3)

    print(
        f"Film strips 1:8000, {args.noise_um:g} µm image noise, {args.replicas} strips per "
        f"length ({seconds:.0f} s); RMS error after a best-fit 3D similarity, metres"
    )
    print(
        f"{'n':>5} {'X along':>9} {'Y across':>9} {'Z height':>9} {'total':>9} {'fit n^1.5':>10}"
    )
    for n, (ex, ey, ez), e, m in zip(lengths, rms, np.sqrt(e2), model, strict=True):
        print(f"{n:5.0f} {ex:9.3f} {ey:9.3f} {ez:9.3f} {e:9.3f} {e / m:10.2f}")
    print(f"fit e² = a² + b² n³:  a = {np.sqrt(max(a2, 0)):.3f} m, b = {np.sqrt(b2) * 1e3:.3f} mm")
    lo, hi = np.percentile(gammas, [2.5, 97.5])
    print(
        f"free fit e² = a² + b² n^γ:  γ = {gamma:.2f} (bootstrap 95 %: {lo:.2f} .. {hi:.2f}), "
        f"a = {np.sqrt(fa2):.3f} m"
    )

    if args.figure is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        args.figure.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(6.0, 4.2), layout="constrained")
        for k, label in enumerate(("X along", "Y across", "Z height")):
            ax.loglog(lengths, rms[:, k], "o", label=label)
        ax.loglog(lengths, np.sqrt(e2), "ks", label="total")
        fine = np.geomspace(lengths.min(), lengths.max(), 100)
        ax.loglog(fine, np.sqrt(a2 + b2 * fine**3), "k-", label="a² + b² n³ fit")
        ax.set_xlabel("photos in the strip")
        ax.set_ylabel("RMS error after similarity (m)")
        ax.set_title(f"Strip formation, {args.noise_um:g} µm image noise")
        ax.legend()
        path = args.figure / "accuracy_vs_length.png"
        fig.savefig(path, dpi=120)
        print(f"figure: {path}")


if __name__ == "__main__":
    main()
