"""The control checks of plausibility.py, computed for every photo at once,
against the same rules written photo by photo (a loop over photos with an
SVD and two complex least-squares fits each; the pairs by np.triu_indices).
"""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.observations import ImageObservations
from strip_aerotri.plausibility import (
    _MIRROR_RATIO,
    _pairs_within_runs,
    _plan_fit_residuals,
    control_distance_problems,
    control_handedness_problems,
)


def _fit_one(image: np.ndarray, ground: np.ndarray) -> float:
    a = image - image.mean(axis=0)
    b = ground - ground.mean(axis=0)
    za = a[:, 0] + 1j * a[:, 1]
    zb = b[:, 0] + 1j * b[:, 1]
    scale = np.vdot(za, zb) / np.vdot(za, za)
    resid = zb - scale * za
    return float(np.vdot(resid, resid).real / max(np.vdot(zb, zb).real, 1e-300))


def _votes_by_loop(image: np.ndarray, ground: np.ndarray, group: np.ndarray) -> tuple[int, int]:
    mirror = proper_votes = 0
    for g in np.unique(group):
        sel = group == g
        if sel.sum() < 3:
            continue
        sv = np.linalg.svd(ground[sel] - ground[sel].mean(axis=0), compute_uv=False)
        if not sv[1] > 0.1 * sv[0]:
            continue
        proper = _fit_one(image[sel], ground[sel])
        mirrored = _fit_one(image[sel] * np.array([1.0, -1.0]), ground[sel])
        if mirrored < _MIRROR_RATIO * proper:
            mirror += 1
        elif proper < _MIRROR_RATIO * mirrored:
            proper_votes += 1
    return mirror, proper_votes


def _photos(seed: int, n_photos: int = 40) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Groups of 1-7 points; some on a line, some mirrored, some noise only."""
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 8, n_photos)
    group = np.repeat(np.arange(n_photos), sizes)
    image = rng.normal(size=(group.size, 2))
    angle = rng.uniform(0, 2 * np.pi, n_photos)[group]
    scale = rng.uniform(50, 500, n_photos)[group]
    z = (image[:, 0] + 1j * image[:, 1]) * scale * np.exp(1j * angle)
    kind = rng.integers(0, 4, n_photos)[group]
    z = np.where(kind == 1, z.conj(), z)  # mirrored photos
    z = np.where(kind == 2, rng.normal(size=group.size) * 100 + 0j, z)  # on one line
    z = np.where(
        kind == 3, rng.normal(size=group.size) * 100 + 1j * rng.normal(size=group.size) * 100, z
    )
    ground = np.column_stack([z.real, z.imag]) + rng.normal(scale=0.01, size=(group.size, 2))
    return image, ground + 5e5, group


@pytest.mark.parametrize("seed", range(12))
def test_every_photos_fits_and_votes_match_the_loop(seed: int) -> None:
    image, ground, group = _photos(seed)
    n = int(group.max()) + 1
    proper, mirrored, spread = _plan_fit_residuals(group, n, image, ground)
    for g in range(n):
        sel = group == g
        if sel.sum() < 2:
            continue
        assert proper[g] == pytest.approx(_fit_one(image[sel], ground[sel]), rel=1e-9, abs=1e-15)
        flipped = image[sel] * np.array([1.0, -1.0])
        assert mirrored[g] == pytest.approx(_fit_one(flipped, ground[sel]), rel=1e-9, abs=1e-15)
        sv = np.linalg.svd(ground[sel] - ground[sel].mean(axis=0), compute_uv=False)
        assert spread[g] == pytest.approx((sv[1] / sv[0]) ** 2, rel=1e-6, abs=1e-12)
    counts = np.bincount(group, minlength=n)
    tells = (counts >= 3) & (spread > 0.01)
    mirror = tells & (mirrored < _MIRROR_RATIO * proper)
    votes = (int(mirror.sum()), int((tells & ~mirror & (proper < _MIRROR_RATIO * mirrored)).sum()))
    assert votes == _votes_by_loop(image, ground, group)
    assert votes[0] > 0 and votes[1] > 0  # the data hold both kinds of photo


def _observations(image: np.ndarray, group: np.ndarray) -> ImageObservations:
    n = group.size
    photos = [f"{g:03d}" for g in range(int(group.max()) + 1)]
    return ImageObservations.from_ids(
        [photos[g] for g in group],
        [f"P{i:04d}" for i in range(n)],
        image,
        principal_distance=100.0,
        photo_ids=photos,
    )


def _point_index(obs: ImageObservations, n: int) -> np.ndarray:
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    return np.array([lookup[f"P{i:04d}"] for i in range(n)], dtype=np.intp)


def test_handedness_votes_as_the_loop_and_swapped_axes_are_named() -> None:
    image, ground, group = _photos(3, n_photos=60)
    obs = _observations(image, group)
    point = _point_index(obs, group.size)
    mirror, proper = _votes_by_loop(image, ground, group)
    assert bool(control_handedness_problems(obs, point, ground)) == (mirror > proper)
    # a proper similarity everywhere: no problem; its X and Y swapped: mirrored
    turned = (image[:, 0] + 1j * image[:, 1]) * 150.0 * np.exp(0.7j)
    right = np.column_stack([turned.real, turned.imag]) + 4e5
    assert control_handedness_problems(obs, point, right) == []
    (message,) = control_handedness_problems(obs, point, right[:, ::-1], file="control.csv")
    assert message.startswith("control.csv: the control is mirrored")


@pytest.mark.parametrize("labels", [[], [7], [1, 1], [0, 0, 0, 2, 5, 5, 5, 5, 9], [3] * 6 + [4]])
def test_pairs_within_runs_are_triu_indices_run_by_run(labels: list[int]) -> None:
    lab = np.asarray(labels, dtype=np.intp)
    expected: list[np.ndarray] = []
    start = 0
    for size in (
        np.diff(np.r_[0, np.flatnonzero(np.r_[lab[1:] != lab[:-1], True]) + 1]) if lab.size else []
    ):
        expected.append(start + np.stack(np.triu_indices(int(size), 1)))
        start += int(size)
    a, b = _pairs_within_runs(lab)
    want = np.concatenate(expected, axis=1) if expected else np.zeros((2, 0), dtype=np.intp)
    np.testing.assert_array_equal(np.stack([a, b]), want)


def test_distance_check_finds_the_far_point() -> None:
    image, ground, group = _photos(5, n_photos=30)
    # a consistent strip: ground = image at one scale, no mirroring
    ground = image * 200.0 + 5e5
    obs = _observations(image, group)
    point = _point_index(obs, group.size)
    ids = [f"P{i:04d}" for i in range(group.size)]
    assert control_distance_problems(obs, point, ground, ids) == []
    far = ground.copy()
    # a point on a photo with company, moved 1000 km
    k = int(np.flatnonzero(np.bincount(group)[group] >= 3)[0])
    far[k] += 1e6
    (message,) = control_distance_problems(obs, point, far, ids)
    assert f"'{ids[k]}'" in message
