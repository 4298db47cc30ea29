"""A reference bundle on a project's own observations, to compare with the
rigorous refinement (``refine = "bundle"``) and to try weights and cameras.

The reference is written independently of the engine: unknowns are each
photo's rotation vector (a correction of the start rotation, scipy's
``Rotation``) and centre and each point; observations are the image
coordinates (the project's reduced coordinates, ``x = -c u / w``) and the
full control points' coordinates, each divided by its sigma; the Jacobian
is ``scipy.optimize``'s finite differences with the problem's sparsity, the
steps Gauss-Newton on the sparse normal equations (SuperLU), from the
engine's solution.  Optional camera terms (c, x0, y0, k1, k2, k3, p1, p2, b1,
b2 in the correction form, mm, in the reduced axes) are extra unknowns.

With ``--external`` it takes strips with a ``truth/`` folder instead (the
independent simulator's, ``../shared/data/external-strips/*``): our
refinement's check points against control.csv and against the truth, all
points and centres against the truth divided by their own standard
deviations, and a reference solved by Gauss-Newton from the truth to 1e-12
on the same rays, control and sigmas in the refinement's tangent frame, its
weighted sum of squares against ours (docs/bundle.md, "Against a reference
bundle on strips from another simulator")::

    python benchmarks/bench_reference_bundle.py - --external ../shared/data/external-strips/*

Run on the real FC300X block (data in ``../shared/data/uav-block-fc300x``)::

    python benchmarks/bench_reference_bundle.py ../shared/data/uav-block-fc300x

It imports the block, runs ``refine = "bundle"``, solves the reference on
the same observations (the rays the refinement rejected left out) and
prints: sigma0 and the check errors point by point of both; each check
point's standard deviations from the reference's normal matrix and its
rays' largest angle; the image residuals of tie, control and check rays;
the residuals averaged in 5 x 5 cells and along the radius; and the check
RMSE with other control sigmas, image sigmas and camera terms.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.optimize._numdiff import approx_derivative
from scipy.sparse.linalg import splu
from scipy.spatial.transform import Rotation

from strip_aerotri.geometry.rotation import matrix_from_opk

CAMERA_TERMS = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1", "b2")


@dataclass
class ReferenceBundle:
    """The least-squares problem (module notes) and its solution.

    ``xy`` (K, 2) reduced image coordinates (mm) of ``photo``/``point``,
    ``sigma`` (K,) mm; ``centres0`` (M, 3), ``rotations0`` (M, 3, 3) image
    -> frame and ``points0`` (P, 3) the start; ``control_point`` (N,) the
    points with full control at ``control_xyz`` (N, 3) with sigmas
    ``control_sigma`` (N, 3) (NaN components not given); ``c`` mm;
    ``camera`` the camera terms estimated; ``centre_xyz`` (M, 3) observed
    centres (GNSS; NaN or None where not) with ``centre_sigma`` (M, 3).
    """

    xy: np.ndarray
    sigma: np.ndarray
    photo: np.ndarray
    point: np.ndarray
    c: float
    centres0: np.ndarray
    rotations0: np.ndarray
    points0: np.ndarray
    control_point: np.ndarray
    control_xyz: np.ndarray
    control_sigma: np.ndarray
    camera: tuple[str, ...] = ()
    solution: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sigma0: float = float("nan")
    redundancy: int = 0
    normal: Any = None
    centre_xyz: np.ndarray | None = None
    centre_sigma: np.ndarray | None = None

    @property
    def n_unknowns(self) -> int:
        return 6 * len(self.centres0) + 3 * len(self.points0) + len(self.camera)

    def unpack(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, float]]:
        m, p = len(self.centres0), len(self.points0)
        rot = Rotation.from_rotvec(v[: 3 * m].reshape(m, 3)).as_matrix() @ self.rotations0
        centres = self.centres0 + v[3 * m : 6 * m].reshape(m, 3)
        points = self.points0 + v[6 * m : 6 * m + 3 * p].reshape(p, 3)
        return rot, centres, points, dict(zip(self.camera, v[6 * m + 3 * p :], strict=True))

    def residuals(self, v: np.ndarray) -> np.ndarray:
        rot, centres, points, q = self.unpack(v)
        image = self.image_residuals(rot, centres, points, q)
        control = (points[self.control_point] - self.control_xyz) / self.control_sigma
        parts = [image.ravel(), control[self._given].ravel()]
        if self.centre_xyz is not None:
            assert self.centre_sigma is not None
            parts.append(((centres - self.centre_xyz) / self.centre_sigma)[self._centred])
        return np.concatenate(parts)

    @property
    def _centred(self) -> np.ndarray:
        """The observed centre components (M, 3) (none without ``centre_xyz``)."""
        if self.centre_xyz is None:
            return np.zeros((len(self.centres0), 3), dtype=bool)
        return np.isfinite(self.centre_xyz)

    def image_residuals(
        self, rot: np.ndarray, centres: np.ndarray, points: np.ndarray, q: dict[str, float]
    ) -> np.ndarray:
        """(K, 2) image residuals, computed minus corrected measured, over sigma."""
        u = np.einsum("kji,kj->ki", rot[self.photo], points[self.point] - centres[self.photo])
        computed = -(self.c + q.get("c", 0.0)) * u[:, :2] / u[:, 2:3]
        m = self.xy - np.array([q.get("x0", 0.0), q.get("y0", 0.0)])
        x, y = m[:, 0], m[:, 1]
        r2 = x * x + y * y
        radial = r2 * (q.get("k1", 0.0) + r2 * (q.get("k2", 0.0) + r2 * q.get("k3", 0.0)))
        p1, p2 = q.get("p1", 0.0), q.get("p2", 0.0)
        dx = x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
        dx += q.get("b1", 0.0) * x + q.get("b2", 0.0) * y
        dy = y * radial + 2 * p1 * x * y + p2 * (r2 + 2 * y * y)
        out: np.ndarray = (computed - (m + np.column_stack([dx, dy]))) / self.sigma[:, None]
        return out

    @property
    def _given(self) -> np.ndarray:
        """The control components given (plan-only and height-only points have NaN)."""
        return np.isfinite(self.control_xyz)

    def _sparsity(self) -> sp.csr_matrix:
        m, p, k = len(self.centres0), len(self.points0), len(self.xy)
        rows, cols = [], []
        for comp in range(2):
            r = 2 * np.arange(k) + comp
            for j in range(3):
                rows += [r, r, r]
                cols += [3 * self.photo + j, 3 * (m + self.photo) + j, 6 * m + 3 * self.point + j]
            for j in range(len(self.camera)):
                rows.append(r)
                cols.append(np.full(k, 6 * m + 3 * p + j))
        n_c = int(self._given.sum())
        rows.append(2 * k + np.arange(n_c))
        point, axis = np.nonzero(self._given)
        cols.append(6 * m + 3 * self.control_point[point] + axis)
        n_g = int(self._centred.sum())
        rows.append(2 * k + n_c + np.arange(n_g))
        photo, axis = np.nonzero(self._centred)
        cols.append(3 * (m + photo) + axis)
        r_all, c_all = np.concatenate(rows), np.concatenate(cols)
        return sp.csr_matrix(
            (np.ones(r_all.size), (r_all, c_all)), shape=(2 * k + n_c + n_g, self.n_unknowns)
        )

    def solve(self, iterations: int = 10, tolerance: float = 1e-9) -> ReferenceBundle:
        n, m = self.n_unknowns, len(self.centres0)
        v = np.zeros(n)
        sparsity = self._sparsity()
        seen = np.zeros(len(self.points0), bool)
        seen[self.point] = True
        free = np.ones(n, bool)
        free[6 * m : 6 * m + 3 * len(self.points0)] = np.repeat(seen, 3)
        for _ in range(iterations):
            r = self.residuals(v)
            jac = approx_derivative(self.residuals, v, "3-point", sparsity=sparsity, f0=r)
            jac = sp.csc_matrix(jac)[:, free]
            normal = (jac.T @ jac).tocsc()
            step = splu(normal).solve(-(jac.T @ r))
            v[free] += step
            if np.max(np.abs(step)) < tolerance:
                break
        r = self.residuals(v)
        self.solution, self.normal = v, (normal, free)
        self.redundancy = r.size - int(free.sum())
        self.sigma0 = float(np.sqrt(r @ r / self.redundancy))
        return self

    def point_std(self, index: int) -> np.ndarray:
        """Standard deviations (frame axes, m) of point ``index``."""
        normal, free = self.normal
        col = np.cumsum(free) - 1
        start = 6 * len(self.centres0) + 3 * index
        lu = splu(normal)
        unit = np.zeros((normal.shape[0], 3))
        unit[col[start : start + 3], np.arange(3)] = 1.0
        q = np.column_stack([lu.solve(unit[:, a]) for a in range(3)])
        return np.sqrt(np.diag(q[col[start : start + 3]])) * self.sigma0


def from_block(result: Any, control_sigma: tuple[float, float, float] | None = None,
               image_sigma: float | None = None, camera: tuple[str, ...] = (),
               used: np.ndarray | None = None) -> ReferenceBundle:  # fmt: skip
    """The reference of a block result with a local CRS (its frame is the
    site system), started from its (refined) solution."""
    obs, ctrl = result.observations, result.control
    keep = np.all(np.isfinite(result.points[obs.point]), axis=1)
    if used is not None:
        keep &= used
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    kinds = [str(getattr(k, "value", k)) for k in ctrl.kind]
    full = [i for i, k in enumerate(kinds) if k != "check" and ctrl.point_ids[i] in lookup]
    sigma = obs.sigma if image_sigma is None else np.full(obs.sigma.shape, image_sigma)
    csig = np.column_stack([ctrl.sigma_xy, ctrl.sigma_xy, ctrl.sigma_h])[full]
    if control_sigma is not None:
        csig = np.broadcast_to(np.asarray(control_sigma), csig.shape).copy()
    origin = np.mean(result.photo_centres, axis=0)
    given = ctrl.xyz[full] - origin
    given[[kinds[i] == "height" for i in full], :2] = np.nan
    given[[kinds[i] == "plan" for i in full], 2] = np.nan
    return ReferenceBundle(
        xy=obs.xy[keep], sigma=sigma[keep], photo=obs.photo[keep], point=obs.point[keep],
        c=obs.principal_distance, centres0=result.photo_centres - origin,
        rotations0=matrix_from_opk(result.photo_opk),
        points0=np.nan_to_num(result.points - origin),
        control_point=np.array([lookup[ctrl.point_ids[i]] for i in full], dtype=np.intp),
        control_xyz=given, control_sigma=csig, camera=camera,
    )  # fmt: skip


def check_errors(ref: ReferenceBundle, result: Any) -> dict[str, np.ndarray]:
    """Given minus adjusted (m) of each check point the reference determines."""
    _, _, points, _ = ref.unpack(ref.solution)
    origin = np.mean(result.photo_centres, axis=0)
    lookup = {pid: i for i, pid in enumerate(result.observations.point_ids)}
    out = {}
    for i, pid in enumerate(result.control.point_ids):  # a few dozen check points
        k = lookup.get(pid)
        if str(getattr(result.control.kind[i], "value", result.control.kind[i])) != "check":
            continue
        if k is not None and np.any(ref.point == k):
            out[pid] = result.control.xyz[i] - origin - points[k]
    return out


def rmse(errors: dict[str, np.ndarray], leave_out: tuple[str, ...] = ()) -> tuple[float, float]:
    e = np.array([v for k, v in errors.items() if k not in leave_out])
    plan = float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2)))
    return plan, float(np.sqrt(np.mean(e[:, 2] ** 2)))


def _used_rays(result: Any) -> np.ndarray:
    """The rays the refinement kept (its image rejections named by point and photo)."""
    obs = result.observations
    used = np.ones(len(obs.photo), bool)
    photos = {p: j for j, p in enumerate(obs.photo_ids)}
    points = {p: j for j, p in enumerate(obs.point_ids)}
    for r in result.rejections:
        if r.stage == "bundle" and r.applied:
            used &= ~((obs.point == points[r.point]) & (obs.photo == photos[r.photos[0]]))
    return used


def _read_rows(path: Path) -> dict[str, dict[str, str]]:
    import csv

    with open(path, newline="") as f:
        return {r[next(iter(r))]: r for r in csv.DictReader(f)}


def _table(rows: dict[str, dict[str, str]], ids: list[str], cols: tuple[str, ...]) -> np.ndarray:
    return np.array([[float(rows[i][c] or "nan") for c in cols] for i in ids])


def _rmse(errors: np.ndarray) -> str:
    """Plan / height RMSE (m) of E, N, H errors (N, 3)."""
    plan = np.sqrt(np.mean(errors[:, 0] ** 2 + errors[:, 1] ** 2))
    return f"{plan:.4f} / {np.sqrt(np.mean(errors[:, 2] ** 2)):.4f}"


@dataclass
class TruthComparison:
    """A refinement against a simulation's truth (:func:`compare_with_truth`).

    ``cost_*``: the weighted sum of squares of the refinement's rays and
    control at the truth, at the refinement's solution and at the
    reference's solution from the truth; ``largest_point_difference_m``
    between the two solutions; ``point_z_rms``, ``centre_z_rms`` (3,) the RMS
    over points and centres of (adjusted - true) / own sigma per frame axis;
    ``point_error`` (P, 3) adjusted - true in the frame (m); ``reference``."""

    cost_truth: float
    cost_ours: float
    cost_reference: float
    largest_point_difference_m: float
    point_z_rms: np.ndarray
    centre_z_rms: np.ndarray
    point_error: np.ndarray
    reference: ReferenceBundle


def compare_with_truth(
    result: Any, points_true: np.ndarray, centres_true: np.ndarray, rotations_true: np.ndarray
) -> TruthComparison:
    """A run's refinement (``result.refined``, its frame) against the truth
    given in that frame: points (P, 3), centres (M, 3), rotations image ->
    frame (M, 3, 3); and a reference solved by Gauss-Newton from the truth to
    1e-12 on the refinement's rays, control and sigmas (plan-only and
    height-only control completed by the refinement's point, as it does)."""
    from strip_aerotri.frames import TangentWorkFrame

    refined, obs, ctrl = result.refined, result.strip.observations, result.control
    frame = TangentWorkFrame(result.ground.crs, refined.frame)
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    rows = [r for r in refined.control_index if not ctrl.is_check[r]]
    idx = np.array([lookup[ctrl.point_ids[r]] for r in rows], dtype=np.intp)
    given_crs = ctrl.xyz[rows]
    adjusted_crs = frame.from_work(refined.points_frame[idx])
    target = frame.to_work(np.where(np.isnan(given_crs), adjusted_crs, given_crs))
    target[~ctrl.uses_xy[rows], :2] = np.nan
    target[~ctrl.uses_h[rows], 2] = np.nan
    sig = np.column_stack([ctrl.sigma_xy[rows], ctrl.sigma_xy[rows], ctrl.sigma_h[rows]])
    used = refined.image_used
    origin = np.mean(centres_true, axis=0)
    ref = ReferenceBundle(
        xy=obs.xy[used], sigma=obs.sigma[used], photo=obs.photo[used], point=obs.point[used],
        c=obs.principal_distance, centres0=centres_true - origin, rotations0=rotations_true,
        points0=points_true - origin, control_point=idx, control_xyz=target - origin,
        control_sigma=sig,
    )  # fmt: skip
    cost_truth = float(np.sum(ref.residuals(np.zeros(ref.n_unknowns)) ** 2))
    ref.solve(iterations=20, tolerance=1e-12)
    _, _, pts_ref, _ = ref.unpack(ref.solution)
    m, p = len(centres_true), len(points_true)
    # our solution in the reference's unknowns: rotation vectors of R_ours R_trueᵀ
    ours = ref.solution.copy()
    turn = refined.photo_rotations_frame @ np.swapaxes(rotations_true, 1, 2)
    ours[: 3 * m] = Rotation.from_matrix(turn).as_rotvec().ravel()
    ours[3 * m : 6 * m] = (refined.photo_centres_frame - centres_true).ravel()
    ours[6 * m : 6 * m + 3 * p] = np.nan_to_num(refined.points_frame - points_true).ravel()
    seen = np.isin(np.arange(p), ref.point)
    err = refined.points_frame - points_true
    return TruthComparison(
        cost_truth=cost_truth,
        cost_ours=float(np.sum(ref.residuals(ours) ** 2)),
        cost_reference=float(ref.sigma0**2 * ref.redundancy),
        largest_point_difference_m=float(
            np.max(np.abs(refined.points_frame[seen] - (pts_ref[seen] + origin)))
        ),
        point_z_rms=np.sqrt(np.mean((err[seen] / refined.point_std[seen]) ** 2, axis=0)),
        centre_z_rms=np.sqrt(
            np.mean(((refined.photo_centres_frame - centres_true) / refined.centre_std) ** 2, 0)
        ),
        point_error=err,
        reference=ref,
    )


def external(folder: Path) -> None:
    """Our refinement of an external strip (a folder with strip.toml and
    ``truth/``) against the truth, and a reference bundle solved from the
    truth in the refinement's own tangent frame on the same observations."""
    from strip_aerotri.frames import TangentWorkFrame, enu_residuals
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    with tempfile.TemporaryDirectory() as tmp:
        for name in ("strip.toml", "control.csv", "image_points.csv"):
            (Path(tmp) / name).write_bytes((folder / name).read_bytes())
        toml = Path(tmp) / "strip.toml"
        toml.write_text(toml.read_text() + '\n[adjustment]\nrefine = "bundle"\n')
        result = run_project(load_project(toml))
    refined, obs = result.refined, result.strip.observations
    frame = TangentWorkFrame(result.ground.crs, refined.frame)
    truth_pts = _read_rows(folder / "truth" / "points_truth.csv")
    truth_photos = _read_rows(folder / "truth" / "photos_truth.csv")
    control = _read_rows(folder / "control.csv")
    ids = list(obs.point_ids)
    centres_crs = _table(truth_photos, list(obs.photo_ids), ("X", "Y", "Z"))
    opk = np.radians(_table(truth_photos, list(obs.photo_ids), ("omega", "phi", "kappa")))
    cmp = compare_with_truth(
        result,
        frame.to_work(_table(truth_pts, ids, ("X", "Y", "H"))),
        frame.to_work(centres_crs),
        frame.work_from_enu(centres_crs) @ matrix_from_opk(opk),
    )
    used = refined.image_used
    print(f"{folder.name}: {used.sum()} of {used.size} rays used, {len(refined.rejections)} "
          f"rejections, sigma0 {refined.sigma0:.4f}, redundancy {refined.redundancy}")  # fmt: skip
    # check points: against the control file and against the truth (E, N, H)
    check = [i for i, pid in enumerate(ids) if control.get(pid, {}).get("type") == "check"]
    ours = refined.points[check]
    given = _table(control, [ids[i] for i in check], ("X", "Y", "H"))
    true_crs = _table(truth_pts, [ids[i] for i in check], ("X", "Y", "H"))
    crs = result.ground.crs
    against = (enu_residuals(crs, given, ours), enu_residuals(crs, true_crs, ours))
    own = enu_residuals(crs, given, true_crs)
    print(f"  check RMSE plan / height (m): against control.csv {_rmse(against[0])}, "
          f"against the truth {_rmse(against[1])}; "
          f"control.csv's own error (given - truth) {_rmse(own)}")  # fmt: skip
    err = cmp.point_error
    print(f"  all points - truth, frame X / Y / Z: mean {np.round(np.mean(err, 0), 4)}, "
          f"RMS {np.round(np.sqrt(np.mean(err**2, 0)), 4)} m; divided by their own sigma: "
          f"RMS {np.round(cmp.point_z_rms, 2)}; centres divided by their own sigma: RMS "
          f"{np.round(cmp.centre_z_rms, 2)}")  # fmt: skip
    print(f"  cost (weighted sum of squares): truth {cmp.cost_truth:.3f}, "
          f"ours {cmp.cost_ours:.6f}, Gauss-Newton from the truth to 1e-12 "
          f"{cmp.cost_reference:.6f} (sigma0 {cmp.reference.sigma0:.4f}); "
          f"ours - that solution: largest point difference "
          f"{cmp.largest_point_difference_m * 1e6:.3f} µm")  # fmt: skip
    _, _, pts_ref, _ = cmp.reference.unpack(cmp.reference.solution)
    ref_check = frame.from_work(pts_ref[check] + np.mean(frame.to_work(centres_crs), axis=0))
    print(f"  the reference's check RMSE: against control.csv "
          f"{_rmse(enu_residuals(crs, given, ref_check))}, "
          f"against the truth {_rmse(enu_residuals(crs, true_crs, ref_check))}")  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.importers.writer import write_project
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="the FC300X data folder")
    parser.add_argument(
        "--external", nargs="+", type=Path, default=(),
        help="strips with a truth/ folder (../shared/data/external-strips/*): compare "
        "the refinement with the truth and a reference solved from the truth instead",
    )  # fmt: skip
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.external:
        for folder in args.external:
            external(folder)
        return
    with tempfile.TemporaryDirectory() as tmp:
        write_project(import_uav_fc300x(args.data), tmp, force=True)
        toml = Path(tmp) / "strip.toml"
        toml.write_text(toml.read_text() + '\n[adjustment]\nrefine = "bundle"\n')
        result = run_project(load_project(toml))
    used = _used_rays(result)
    ref = from_block(result, used=used).solve()
    errors = check_errors(ref, result)
    names = np.array(result.control.point_ids)[result.control_index]
    check = result.is_check
    engine = dict(zip(names[check], result.control_residuals[check], strict=True))
    print(f"sigma0: engine {result.refined_sigma0:.4f}, reference {ref.sigma0:.4f}")
    print("check point   engine E/N/H (m)          reference E/N/H (m)       ref. sd E/N/H (m)")
    lookup = {pid: i for i, pid in enumerate(result.observations.point_ids)}
    for pid, e in sorted(errors.items(), key=lambda kv: int(kv[0]) if kv[0].isdigit() else 0):
        a, b = np.array2string(engine[pid], precision=3), np.array2string(e, precision=3)
        sd = np.array2string(ref.point_std(lookup[pid]), precision=3)
        print(f"{pid:>8}  {a:>24}  {b:>24}  {sd}")
    (p_all, h_all), (p_13, h_13) = rmse(errors), rmse(errors, ("14", "78"))
    print(
        f"RMSE plan/height: reference {p_all:.4f} / {h_all:.4f}, without 14 and 78 "
        f"{p_13:.4f} / {h_13:.4f}"
    )
    for label, kw in (
        ("control sigma 0.01 / 0.015 m", {"control_sigma": (0.01, 0.01, 0.015)}),
        ("control sigma 0.04 / 0.06 m", {"control_sigma": (0.04, 0.04, 0.06)}),
        ("image sigma 0.6 um", {"image_sigma": 0.0006}),
        ("camera c x0 y0", {"camera": ("c", "x0", "y0")}),
        ("camera k1 k2 p1 p2", {"camera": ("k1", "k2", "p1", "p2")}),
        ("camera all ten", {"camera": CAMERA_TERMS}),
    ):
        other = from_block(result, used=used, **kw).solve()  # type: ignore[arg-type]
        e = check_errors(other, result)
        print(f"{label:32s} sigma0 {other.sigma0:.3f}  RMSE %.4f / %.4f  without 14, 78 "
              "%.4f / %.4f" % (*rmse(e), *rmse(e, ("14", "78"))))  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
