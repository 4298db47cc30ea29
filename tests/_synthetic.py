"""A minimal synthetic strip for unit tests of strip formation.

Independent of :mod:`strip_aerotri.simulate` on purpose: a flat-earth
Cartesian world, collinearity written out here, scipy for the rotations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from strip_aerotri.observations import ImageObservations


@dataclass
class Synthetic:
    observations: ImageObservations
    points: np.ndarray  # (P, 3) truth in observations.point_ids order
    centres: np.ndarray  # (M, 3)
    rotations: np.ndarray  # (M, 3, 3) image -> world


def make_strip(
    n_photos: int = 8,
    *,
    noise_mm: float = 0.0,
    seed: int = 1,
    c: float = 152.0,
    height: float = 1200.0,
    base: float = 368.0,
    attitude_sd_deg: float = 1.5,
    relative_rotation_deg: float | None = None,
    relief: float = 40.0,
    half_format: float = 115.0,
) -> Synthetic:
    """Vertical photos along world X, points on a grid with relief."""
    rng = np.random.default_rng(seed)
    centres = np.column_stack(
        [
            np.arange(n_photos) * base,
            rng.normal(0, 5, n_photos),
            height + rng.normal(0, 5, n_photos),
        ]
    )
    if relative_rotation_deg is None:
        angles = rng.normal(0, attitude_sd_deg, (n_photos, 3))
    else:
        angles = rng.uniform(-relative_rotation_deg, relative_rotation_deg, (n_photos, 3))
    rotations = Rotation.from_euler("XYZ", angles, degrees=True).as_matrix()
    xs = np.arange(-base, (n_photos + 1) * base, base / 3)
    ys = np.linspace(-0.6 * height, 0.6 * height, 7)
    gx, gy = np.meshgrid(xs, ys)
    world = np.column_stack(
        [
            gx.ravel() + rng.normal(0, 20, gx.size),
            gy.ravel() + rng.normal(0, 20, gx.size),
            rng.normal(0, relief, gx.size),
        ]
    )
    photo, point, xy = [], [], []
    for i in range(n_photos):  # loop over photos: building test data only
        v = (world - centres[i]) @ rotations[i]
        x = -c * v[:, 0] / v[:, 2]
        y = -c * v[:, 1] / v[:, 2]
        seen = np.flatnonzero(
            (np.abs(x) < half_format) & (np.abs(y) < half_format) & (v[:, 2] < 0)
        )
        photo += [f"{1000 + i}"] * seen.size
        point += [f"P{j:05d}" for j in seen]
        xy.append(np.column_stack([x[seen], y[seen]]))
    xy = np.vstack(xy) + rng.normal(0, noise_mm, (len(photo), 2))
    obs = ImageObservations.from_ids(
        photo,
        point,
        xy,
        c,
        photo_ids=[f"{1000 + i}" for i in range(n_photos)],
        sigma=noise_mm if noise_mm > 0 else 0.005,
    )
    truth = world[[int(p[1:]) for p in obs.point_ids]]
    return Synthetic(obs, truth, centres, rotations)


def best_fit_similarity(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Source points mapped onto target by the least-squares similarity (Umeyama)."""
    cs, ct = source.mean(0), target.mean(0)
    a, b = source - cs, target - ct
    u, s, vt = np.linalg.svd(b.T @ a)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ d @ vt
    scale = np.trace(np.diag(s) @ d) / np.sum(a * a)
    return ct + scale * a @ r.T


def without_ties(obs: ImageObservations, model: int) -> ImageObservations:
    """The observations with every point of the triple overlap of photos
    model - 1, model, model + 1 taken off photo model + 1: model ``model``
    shares no tie point with the one before."""
    on = [set(obs.point[obs.photo == k].tolist()) for k in range(obs.n_photos)]
    triple = on[model - 1] & on[model] & on[model + 1]
    keep = ~((obs.photo == model + 1) & np.isin(obs.point, list(triple)))
    return ImageObservations.from_ids(
        np.asarray(obs.photo_ids)[obs.photo[keep]],
        np.asarray(obs.point_ids)[obs.point[keep]],
        obs.xy[keep],
        obs.principal_distance,
        photo_ids=obs.photo_ids,
        sigma=obs.sigma[keep],
    )
