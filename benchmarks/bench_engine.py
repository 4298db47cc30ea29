"""The bundle on the structured normal equations: cost against photos, a block, blunders.

Run from the repository root::

    python benchmarks/bench_engine.py                        # 100 ... 2000 photos
    python benchmarks/bench_engine.py --photos 100 1000 10000
    python benchmarks/bench_engine.py --block 10 300          # a 10 x 300 block
    python benchmarks/bench_engine.py --photos 200 --blunders 20 --seeds 3

Each case is a drone strip (or block) of the package's simulator with about
104 points per photo (``extra_points_per_photo=18``), control every 10
models, ``crs = "local"``.  The bundle with its data snooping and its
precision (:func:`strip_aerotri.bundle.refine.refine_frame`, the code of
``refine = "bundle"``) starts 5 cm and 0.01 degrees off the truth, so that
the time is the bundle's alone (no strip method before it).  Printed per
case: process CPU seconds and wall seconds (on a shared machine the CPU time
is the figure to compare; set ``OPENBLAS_NUM_THREADS=1`` for one thread),
iterations, adjustments (rounds), the half-band of the reduced matrix,
rejections against the simulated blunders, and the peak memory of the
process; then the log-log slope of CPU time against photos.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import warnings

import numpy as np

from strip_aerotri.bundle.snooping import refine_frame
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.simulate import simulate_block, simulate_strip


def _case(photos: int, seed: int, blunders: int, strips: int):  # type: ignore[no-untyped-def]
    if strips > 1:
        return simulate_block(strips, photos, preset="drone", crs="local", seed=seed)
    return simulate_strip(
        photos, preset="drone", crs="local", seed=seed, control="every_k_models",
        control_every=10, extra_points_per_photo=18, image_blunders=blunders,
    )  # fmt: skip


def run(photos: int, seed: int = 1, blunders: int = 0, strips: int = 1) -> dict[str, float]:
    """One case; returns its figures (see the module docstring)."""
    sim = _case(photos, seed, blunders, strips)
    obs, truth = sim.observations, sim.truth
    p = obs.n_points
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    control = np.full((p, 3), np.nan)
    sigma = np.full((p, 3), np.inf)
    c = sim.control
    for i, pid in enumerate(c.point_ids):
        j = lookup[pid]
        if c.uses_xy[i]:
            control[j, :2], sigma[j, :2] = truth.points_local[j, :2], c.sigma_xy[i]
        if c.uses_h[i]:
            control[j, 2], sigma[j, 2] = truth.points_local[j, 2], c.sigma_h[i]
    rng = np.random.default_rng(seed)
    centres = truth.photo_centres_local + rng.normal(0.0, 0.05, truth.photo_centres_local.shape)
    turn = matrix_from_rotvec(rng.normal(0.0, 2e-4, (obs.n_photos, 3)))
    rotations = truth.photo_rotations_local @ turn
    points = truth.points_local + rng.normal(0.0, 0.05, truth.points_local.shape)
    wall, cpu = time.perf_counter(), time.process_time()
    fr = refine_frame(obs, centres, rotations, points, control_xyz=control, control_sigma=sigma)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    blundered = np.zeros(obs.photo.size, bool)
    blundered[list(getattr(truth, "blunder_observations", ()))] = True
    rejected = fr.observation_rejected
    return {
        "photos": float(obs.n_photos),
        "observations": float(obs.photo.size),
        "cpu": cpu,
        "wall": wall,
        "iterations": float(fr.iterations),
        "rounds": float(fr.rounds),
        "blunders": float(blundered.sum()),
        "found": float(np.count_nonzero(rejected & blundered)),
        "other": float(np.count_nonzero(rejected & ~blundered)),
        "sigma0": fr.sigma0,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, nargs="+", default=[100, 300, 1000, 2000])
    ap.add_argument("--block", type=int, nargs=2, metavar=("STRIPS", "PHOTOS"))
    ap.add_argument("--blunders", type=int, default=0, help="image blunders per strip")
    ap.add_argument("--seeds", type=int, default=1)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    cases = [(args.block[1], args.block[0])] if args.block else [(m, 1) for m in args.photos]
    run(30, 0)  # imports and first calls out of the figures
    print(f"load {os.getloadavg()[0]:.1f}")
    print(" photos      obs   CPU s  wall s  iter  rounds  blunders found other  sigma0  peak MB")
    rows = []
    for photos, strips in cases:
        for seed in range(1, args.seeds + 1):
            r = run(photos, seed, args.blunders, strips)
            rows.append(r)
            print(
                f"{r['photos']:7.0f} {r['observations']:8.0f} {r['cpu']:7.2f} {r['wall']:7.2f}"
                f" {r['iterations']:5.0f} {r['rounds']:7.0f} {r['blunders']:9.0f} {r['found']:5.0f}"
                f" {r['other']:5.0f} {r['sigma0']:7.3f} {r['peak_mb']:8.0f}",
                flush=True,
            )
    m = np.array([r["photos"] for r in rows])
    t = np.array([r["cpu"] for r in rows])
    if np.unique(m).size > 1:
        slope = np.polyfit(np.log(m), np.log(t), 1)[0]
        print(f"log-log slope of CPU time against photos: {slope:.2f}")


if __name__ == "__main__":
    main()
