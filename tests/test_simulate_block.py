"""Block simulator: collinearity truth, strip layout, side overlaps, control, project files.

The block simulator is the ground truth of the block constructions, so these
tests check it against oracles written here: a dense collinearity projection
of every point into every photo, the planned geometry of the block (strip
spacing ``(1 - side_overlap)`` x footprint, flight directions) and the
project format of formats.md ("A block of strips"), read back with tomllib
and csv only (the loader does not read ``[[strips]]`` yet).
"""

from __future__ import annotations

import csv
import math
import time
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.observations import ControlType
from strip_aerotri.simulate import (
    CAMERAS,
    PRESETS,
    BlockStrip,
    Camera,
    LocalFrame,
    SimulatedBlock,
    SimulatedStrip,
    SimulationTruth,
    StripPreset,
    camera_preset,
    simulate_block,
    simulate_strip,
)

# formats.md, "A block of strips": the tables and keys a block's strip.toml may hold.
BLOCK_TOML_KEYS = {
    "project": {"name"},
    "strips": {"name", "photos"},
    "camera": {"principal_distance_mm", "principal_point_mm"},
    "images": {"file"},
    "control": {"file", "crs"},
    "adjustment": {
        "route",
        "polynomial",
        "relative_orientation",
        "intersection",
        "scale_transfer",
        "models",
        "block",
    },
    "output": {"directory"},
}


def _block(**kwargs) -> SimulatedBlock:
    args = {"n_strips": 3, "n_photos_per_strip": 8, "seed": 3} | kwargs
    return simulate_block(**args)


def _project_all(block: SimulatedBlock) -> tuple[np.ndarray, np.ndarray]:
    """Every point in every photo (collinearity written out here): image xy
    (photos, points, 2) and whether it is in front and inside the format."""
    truth = block.truth
    c = block.observations.principal_distance
    d = truth.points_local[None, :, :] - truth.photo_centres_local[:, None, :]
    v = np.einsum("mji,mpj->mpi", truth.photo_rotations_local, d)  # v = R.T (X - S)
    xy = np.stack([-c * v[..., 0] / v[..., 2], -c * v[..., 1] / v[..., 2]], axis=-1)
    half = np.array(block.preset.format_mm) / 2.0
    inside = (v[..., 2] < 0) & np.all(np.abs(xy) <= half, axis=-1)
    return xy, inside


def _plan(block: SimulatedBlock, xyz: np.ndarray) -> np.ndarray:
    """Local ENU points -> (along the block's heading, to its right), metres."""
    h = math.radians(block.truth.heading_deg)
    ahead = np.array([math.sin(h), math.cos(h)])
    right = np.array([math.cos(h), -math.sin(h)])
    return np.column_stack([xyz[:, :2] @ ahead, xyz[:, :2] @ right])


def _strip_sees(block: SimulatedBlock) -> np.ndarray:
    """(strips, points): the point is observed on a photo of the strip."""
    obs = block.observations
    seen = np.zeros((len(block.strips), obs.n_points), dtype=bool)
    seen[block.photo_strip[obs.photo], obs.point] = True
    return seen


def _roles(block: SimulatedBlock) -> dict[str, list[int]]:
    index = {p: i for i, p in enumerate(block.observations.point_ids)}
    out: dict[str, list[int]] = {k.value: [] for k in ControlType}
    for pid, kind in zip(block.control.point_ids, block.control.kind, strict=True):
        out[kind.value].append(index[pid])
    return out


# ---------------------------------------------------------------------------
# The package keeps its public names


def test_the_package_keeps_every_public_name_of_the_strip_simulator():
    import strip_aerotri as sa
    from strip_aerotri import simulate

    for name in (
        "CAMERAS",
        "PRESETS",
        "Camera",
        "LocalFrame",
        "SimulatedStrip",
        "SimulationTruth",
        "StripPreset",
        "camera_preset",
        "simulate_strip",
    ):
        assert name in simulate.__all__
    assert (CAMERAS, PRESETS, Camera, LocalFrame) == (
        simulate.CAMERAS,
        simulate.PRESETS,
        simulate.Camera,
        simulate.LocalFrame,
    )
    assert sa.simulate_strip is simulate_strip
    assert sa.SimulatedStrip is SimulatedStrip
    assert sa.SimulationTruth is SimulationTruth
    assert sa.StripPreset is StripPreset
    assert sa.PRESETS is PRESETS
    assert isinstance(camera_preset("oneinch"), StripPreset)
    assert {"simulate_block", "SimulatedBlock", "BlockStrip"} <= set(simulate.__all__)


# ---------------------------------------------------------------------------
# Collinearity and visibility


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"preset": "drone", "side_overlap": 0.2, "n_strips": 4, "n_photos_per_strip": 12},
        {"flight": "same", "side_overlap": 0.6, "crs": "EPSG:4326", "heading_deg": -20.0},
        {"preset": camera_preset("ff35", forward_overlap=0.8), "crs": "local"},
    ],
    ids=["film", "drone-20", "film-same-60-geographic", "ff35-local"],
)
def test_observations_are_every_visible_pair_of_the_truth(kwargs):
    block = _block(image_noise_mm=0.0, **kwargs)
    obs = block.observations
    xy, inside = _project_all(block)
    np.testing.assert_allclose(obs.xy, xy[obs.photo, obs.point], rtol=0, atol=1e-12)
    # every photo that sees a point has an observation of it, and no other does
    got = np.zeros_like(inside)
    got[obs.photo, obs.point] = True
    np.testing.assert_array_equal(got, inside)
    assert np.bincount(obs.point, minlength=obs.n_points).min() >= 2


def test_photo_and_point_ids():
    block = _block(n_strips=4, n_photos_per_strip=12)
    obs = block.observations
    names = tuple(s.name for s in block.strips)
    assert names == ("S1", "S2", "S3", "S4")
    assert block.strip_photo_ids[1] == tuple(f"S2_{j:02d}" for j in range(1, 13))
    # one observation file for the block: the strips' photos, strip after strip
    assert obs.photo_ids == sum(block.strip_photo_ids, ())
    assert len(set(obs.photo_ids)) == len(obs.photo_ids) == 48
    assert obs.point_ids == tuple(f"P{i:05d}" for i in range(1, obs.n_points + 1))
    assert all(isinstance(s, BlockStrip) for s in block.strips)
    assert block.truth.photo_centres_local.shape == (48, 3)
    assert block.truth.points_local.shape == (obs.n_points, 3)
    for k, strip in enumerate(block.strips):
        rows = slice(12 * k, 12 * (k + 1))
        np.testing.assert_array_equal(
            strip.photo_centres_local, block.truth.photo_centres_local[rows]
        )
        np.testing.assert_array_equal(
            strip.photo_rotations_local, block.truth.photo_rotations_local[rows]
        )


# ---------------------------------------------------------------------------
# Strips: spacing and flight direction


@pytest.mark.parametrize("side_overlap", [0.2, 0.3, 0.45, 0.6])
def test_strips_are_parallel_at_the_side_overlap_spacing(side_overlap):
    block = _block(n_strips=4, side_overlap=side_overlap)
    pre = block.preset
    spacing = (1.0 - side_overlap) * pre.format_mm[1] * pre.scale_m_per_mm
    offsets = np.array([s.offset_m for s in block.strips])
    np.testing.assert_allclose(np.diff(offsets), spacing, rtol=1e-12)
    assert offsets.mean() == pytest.approx(0.0, abs=1e-9)  # block centred on the origin
    for strip in block.strips:
        across = _plan(block, strip.photo_centres_local)[:, 1]
        # centres wander within +- position_wander_m about the planned axis
        assert np.abs(across - strip.offset_m).max() <= pre.position_wander_m + 1.0


@pytest.mark.parametrize("flight", ["serpentine", "same"])
def test_flight_direction_of_every_strip(flight):
    block = _block(n_strips=4, flight=flight, heading_deg=75.0)
    expected = [flight == "serpentine" and k % 2 == 1 for k in range(4)]
    assert [s.reversed for s in block.strips] == expected
    for strip, back in zip(block.strips, expected, strict=True):
        assert strip.heading_deg == (255.0 if back else 75.0)
        along = _plan(block, strip.photo_centres_local)[:, 0]
        steps = np.diff(along)
        # flight order: photo 1 at the start of this strip's own flight
        assert np.all(steps < 0) if back else np.all(steps > 0)
        # each photo's x axis (image -> local: first column of R) points along its flight
        x_axis = _plan(block, strip.photo_rotations_local[:, :, 0])[:, 0]
        assert np.all(x_axis < -0.99) if back else np.all(x_axis > 0.99)


def test_serpentine_and_same_plan_the_same_nadirs():
    back = _block(flight="serpentine", image_noise_mm=0.0)
    same = _block(flight="same", image_noise_mm=0.0)
    a = np.sort(_plan(back, back.strips[1].photo_centres_local)[:, 0])
    b = np.sort(_plan(same, same.strips[1].photo_centres_local)[:, 0])
    base = back.preset.base_m
    np.testing.assert_allclose(a, b, atol=2 * back.preset.position_wander_m)
    np.testing.assert_allclose(np.diff(a), base, atol=2 * back.preset.position_wander_m)


# ---------------------------------------------------------------------------
# Common points of the side overlaps


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"side_overlap": 0.2},
        {"side_overlap": 0.6, "flight": "same"},
        {"preset": "drone", "n_strips": 4, "n_photos_per_strip": 15, "side_overlap": 0.4},
        {"preset": "drone", "n_strips": 4, "n_photos_per_strip": 15, "side_overlap": 0.2},
    ],
    ids=["film-30", "film-20", "film-60-same", "drone-40", "drone-20"],
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_model_has_common_points_with_the_next_strip(kwargs, seed):
    block = _block(seed=seed, **kwargs)
    obs = block.observations
    m = len(block.strips[0].photo_ids)
    seen = _strip_sees(block)
    on_photo = np.zeros((obs.n_photos, obs.n_points), dtype=bool)
    on_photo[obs.photo, obs.point] = True
    for k in range(len(block.strips) - 1):
        for j in range(m - 1):
            a, b = k * m + j, k * m + j + 1
            # a model of strip k (photos a, b) and the next strip share >= 3 points
            # (the block constructions need 3 per model to join strips)
            assert (on_photo[a] & on_photo[b] & seen[k + 1]).sum() >= 3, (k, j)
        # and from the other side: every model of strip k + 1 sees common points of strip k
        for j in range(m - 1):
            a, b = (k + 1) * m + j, (k + 1) * m + j + 1
            assert (on_photo[a] & on_photo[b] & seen[k]).sum() >= 3, (k + 1, j)


def test_common_points_lie_in_the_side_overlap_and_spread_along_it():
    block = _block(n_strips=4, n_photos_per_strip=10, side_overlap=0.3)
    pre = block.preset
    plan = _plan(block, block.truth.points_local)
    width = pre.format_mm[1] * pre.scale_m_per_mm
    seen = _strip_sees(block)
    stations = (np.arange(10) - 4.5) * pre.base_m
    for k in range(3):
        common = seen[k] & seen[k + 1]
        assert common.sum() == len(block.common_points(k, k + 1))
        middle = 0.5 * (block.strips[k].offset_m + block.strips[k + 1].offset_m)
        # inside the side overlap band (0.3 x width), with room for tilts and wander
        assert np.abs(plan[common, 1] - middle).max() < 0.15 * width + 0.1 * width
        # some at every station (planned nadir) of the block
        nearest = np.abs(plan[common, 0][:, None] - stations[None, :]).argmin(axis=1)
        assert set(Counter(nearest.tolist())) == set(range(10))
        assert min(Counter(nearest.tolist()).values()) >= 3
    # strips two apart do not overlap at 30 % side overlap: nothing in common
    assert not (seen[0] & seen[2]).any()
    assert block.common_points(0, 2) == ()


def test_more_side_points_per_zone_give_more_common_points():
    few = _block(side_points_per_zone=1)
    many = _block(side_points_per_zone=4)
    assert len(many.common_points(0, 1)) > len(few.common_points(0, 1))


# ---------------------------------------------------------------------------
# Control


def test_perimeter_control_runs_around_the_block():
    block = _block(n_strips=4, n_photos_per_strip=13, control="perimeter", control_every=3)
    pre = block.preset
    plan = _plan(block, block.truth.points_local)
    roles = _roles(block)
    offsets = np.array([s.offset_m for s in block.strips])
    end = 6 * pre.base_m  # the first and last stations are at -+ 6 bases
    half_base = 0.5 * pre.base_m
    full = plan[roles["full"]]
    at_end = np.abs(np.abs(full[:, 0]) - end) < half_base
    on_edge = np.abs(full[:, 1]) > offsets.max()  # beyond the outer strips' axes
    assert np.all(at_end | on_edge)
    # the outer edges: full points at stations 0, 3, 6, 9, 12 on both sides
    for side in (-1.0, 1.0):
        edge = full[side * full[:, 1] > offsets.max()]
        assert edge.shape[0] == 5
        np.testing.assert_allclose(
            np.sort(edge[:, 0]), (np.arange(0, 13, 3) - 6) * pre.base_m, atol=half_base
        )
    # both ends: one full point in each of the 3 side overlaps, and both edges
    for sign in (-1.0, 1.0):
        assert np.sum(np.abs(full[:, 0] - sign * end) < half_base) == 3 + 2
    # heights: chains across the block in every side overlap, inside the block
    height = plan[roles["height"]]
    assert height.shape[0] == 3 * 3  # stations 3, 6, 9 in 3 side overlaps
    middles = 0.5 * (offsets[:-1] + offsets[1:])
    gap = np.abs(height[:, 1][:, None] - middles[None, :]).min(axis=1)
    assert gap.max() < 0.25 * (1 - block.side_overlap) * pre.format_mm[1] * pre.scale_m_per_mm
    assert np.all(np.abs(height[:, 0]) < end - half_base)
    # check points are inside: never at the first or last station
    check = plan[roles["check"]]
    assert check.shape[0] > 50
    assert np.all(np.abs(check[:, 0]) < end - half_base)
    assert not roles["plan"]


def test_corner_control_is_four_corners_and_heights_across_the_middle():
    block = _block(n_strips=3, n_photos_per_strip=9, control="corners")
    roles = _roles(block)
    plan = _plan(block, block.truth.points_local)
    full = plan[roles["full"]]
    assert full.shape[0] == 4
    assert sorted(np.sign(full[:, 0] * full[:, 1]).tolist()) == [-1.0, -1.0, 1.0, 1.0]
    height = plan[roles["height"]]
    assert height.shape[0] == 2 + 2  # two outer edges, two side overlaps
    assert np.abs(height[:, 0]).max() < 0.5 * block.preset.base_m


def test_without_gruber_rows_the_outer_side_overlaps_carry_the_corners():
    block = _block(control="corners", gruber_y_mm=())
    assert sum(k is ControlType.FULL for k in block.control.kind) == 4
    assert set(block.control.point_ids) <= set(block.common_points(0, 1)) | set(
        block.common_points(1, 2)
    )


@pytest.mark.parametrize("layout", ["ends", "fig4", "every_k_models", "dense", "weak"])
def test_a_strip_layout_gives_every_strip_its_own_control(layout):
    n, m = 3, 9
    block = _block(n_strips=n, n_photos_per_strip=m, control=layout)
    alone = simulate_strip(m, control=layout, seed=3)
    count = Counter(k.value for k in alone.control.kind if k is not ControlType.CHECK)
    got = Counter(k.value for k in block.control.kind if k is not ControlType.CHECK)
    seen = _strip_sees(block)
    index = {p: i for i, p in enumerate(block.observations.point_ids)}
    used = [index[p] for p, k in zip(block.control.point_ids, block.control.kind, strict=True)]
    used = [p for p, k in zip(used, block.control.kind, strict=True) if k is not ControlType.CHECK]
    for kind, number in count.items():
        # as many per strip as a strip alone has (a shared point counts once)
        assert n * number - 2 <= got[kind] <= n * number, kind
    for k in range(n):
        assert seen[k, used].sum() >= sum(count.values()), k


def test_control_is_the_truth_plus_noise_and_check_points_are_exact():
    block = _block(crs="EPSG:32634", control_noise_m=0.05)
    index = {p: i for i, p in enumerate(block.observations.point_ids)}
    rows = np.array([index[p] for p in block.control.point_ids])
    truth = block.truth.points_crs[rows]
    xyz = block.control.xyz
    kinds = np.array([k.value for k in block.control.kind])
    check = kinds == "check"
    np.testing.assert_array_equal(xyz[check], truth[check])
    full = kinds == "full"
    diff = (xyz[full] - truth[full]).ravel()
    assert 0.0 < np.abs(diff).max() < 5 * 0.05  # noise of 5 cm, within 5 sigma
    assert np.all(np.isnan(xyz[kinds == "height", :2]))
    np.testing.assert_array_equal(block.control.sigma_xy, 0.05)


def test_n_check_takes_a_random_subset_of_check_points():
    block = _block(n_check=7)
    assert sum(k is ControlType.CHECK for k in block.control.kind) == 7


# ---------------------------------------------------------------------------
# Noise, blunders, seeds


def test_image_noise_has_the_requested_standard_deviation():
    block = _block(n_strips=4, n_photos_per_strip=12, image_noise_mm=0.004)
    obs = block.observations
    xy, _ = _project_all(block)
    resid = obs.xy - xy[obs.photo, obs.point]
    assert resid.size > 2000
    # the sample sd of k normal values has relative sd 1/sqrt(2k) < 2 %: allow 3
    assert abs(resid.std() / 0.004 - 1.0) < 0.06
    np.testing.assert_array_equal(obs.sigma, 0.004)


def test_blunders_change_only_the_rows_they_name():
    clean = _block()
    dirty = _block(image_blunders=4, control_blunders=2)
    rows = np.array(dirty.truth.blunder_observations)
    assert rows.size == 4
    moved = np.flatnonzero(np.any(clean.observations.xy != dirty.observations.xy, axis=1))
    np.testing.assert_array_equal(moved, rows)
    assert np.hypot(*(dirty.observations.xy - clean.observations.xy)[rows].T).min() >= 0.05
    bad = np.array(dirty.truth.blunder_control)
    assert bad.size == 2
    before, after = clean.control.xyz, dirty.control.xyz
    same = (before == after) | (np.isnan(before) & np.isnan(after))
    changed = np.flatnonzero(~same.all(axis=1))
    np.testing.assert_array_equal(changed, bad)


def test_equal_seeds_give_equal_blocks():
    a, b, c = _block(seed=5), _block(seed=5), _block(seed=6)
    np.testing.assert_array_equal(a.observations.xy, b.observations.xy)
    np.testing.assert_array_equal(a.truth.points_local, b.truth.points_local)
    assert a.control.point_ids == b.control.point_ids
    assert not np.array_equal(a.truth.points_local[:10], c.truth.points_local[:10])


def test_truth_arrays_are_read_only():
    block = _block()
    with pytest.raises(ValueError, match="read-only"):
        block.truth.points_local[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        block.strips[0].photo_centres_local[0, 0] = 1.0


# ---------------------------------------------------------------------------
# Arguments


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_strips": 1}, "Expected `n_strips` to be an integer >= 2"),
        ({"n_photos_per_strip": 1}, "Expected `n_photos_per_strip` to be an integer >= 2"),
        ({"side_overlap": 0.1}, r"Expected `side_overlap` within \[0.2, 0.6\]"),
        ({"side_overlap": 0.7}, r"Expected `side_overlap` within \[0.2, 0.6\]"),
        ({"flight": "zigzag"}, "Expected `flight` to be one of"),
        ({"control": "everywhere"}, "Expected `control` to be one of"),
        ({"control_every": 0}, "Expected `control_every` >= 1"),
        ({"side_points_per_zone": 0}, "Expected `side_points_per_zone` >= 1"),
        ({"preset": "corridor"}, "a block has none"),
        ({"crs": "FOO"}, "Expected `crs` to be a CRS pyproj knows"),
        ({"bogus_parameter": 1}, "Unknown simulation parameter"),
    ],
)
def test_bad_arguments_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _block(**kwargs)


def test_a_corridor_without_its_road_is_a_film_block():
    block = _block(preset="corridor", line=False)
    assert block.preset.line is False
    assert block.observations.n_points > 100


# ---------------------------------------------------------------------------
# Project files (formats.md, "A block of strips")


def _read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


@pytest.mark.parametrize("flight", ["serpentine", "same"])
def test_the_block_project_files_follow_the_format(tmp_path, flight):
    block = _block(n_strips=4, n_photos_per_strip=7, flight=flight)
    toml_path = block.write_project(tmp_path)
    assert toml_path == tmp_path / "strip.toml"
    with toml_path.open("rb") as fh:
        doc = tomllib.load(fh)

    # only keys of the format; a block has [[strips]] and never [strip]
    assert "strip" not in doc
    for table, keys in BLOCK_TOML_KEYS.items():
        entries = doc.get(table, [])
        for entry in entries if isinstance(entries, list) else [entries]:
            assert set(entry) <= keys, table
    assert set(doc) <= set(BLOCK_TOML_KEYS)
    assert doc["adjustment"] == {"block": "models"}
    assert doc["camera"]["principal_distance_mm"] == block.preset.principal_distance_mm
    assert doc["control"] == {"file": "control.csv", "crs": "EPSG:32634"}
    assert doc["images"] == {"file": "image_points.csv"}

    strips = doc["strips"]
    assert [s["name"] for s in strips] == ["S1", "S2", "S3", "S4"]
    assert [tuple(s["photos"]) for s in strips] == list(block.strip_photo_ids)
    photos = [p for s in strips for p in s["photos"]]
    assert len(photos) == len(set(photos)) == 28  # a photo id in one strip only

    columns, rows = _read_csv(tmp_path / "image_points.csv")
    assert columns[:4] == ["photo", "point", "x", "y"]
    assert {r["photo"] for r in rows} == set(photos)
    strip_of = {p: k for k, s in enumerate(strips) for p in s["photos"]}
    points_of: list[set[str]] = [set() for _ in strips]
    for r in rows:
        points_of[strip_of[r["photo"]]].add(r["point"])
    for k in range(3):
        # adjacent strips share many points: at least 3 per model of the strip
        assert len(points_of[k] & points_of[k + 1]) >= 3 * 6
    # the serpentine's reversed strips list their photos in their own flight order
    back = [s.reversed for s in block.strips]
    assert back == ([False, True, False, True] if flight == "serpentine" else [False] * 4)

    columns, control = _read_csv(tmp_path / "control.csv")
    assert columns[:5] == ["point", "X", "Y", "H", "type"]
    kinds = Counter(r["type"] for r in control)
    assert set(kinds) <= {"full", "plan", "height", "check"}
    assert kinds["full"] >= 4 and kinds["check"] > 0
    seen = {r["point"] for r in rows}
    assert {r["point"] for r in control} <= seen
    for r in control:
        if r["type"] == "height":
            assert r["X"] == r["Y"] == "" and r["H"] != ""


def test_write_project_adjustment_keys(tmp_path):
    block = _block(crs="local")
    block.write_project(
        tmp_path, block="strips", models="independent", polynomial=2, route="projected"
    )
    with (tmp_path / "strip.toml").open("rb") as fh:
        doc = tomllib.load(fh)
    assert doc["adjustment"] == {
        "block": "strips",
        "models": "independent",
        "polynomial": 2,
        "route": "projected",
    }
    assert doc["control"]["crs"] == "local"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"block": "bundle"}, "block: invalid value 'bundle'"),
        ({"models": "free"}, "models: invalid value 'free'"),
        ({"polynomial": 4}, "polynomial: expected 0, 1, 2, 3"),
        ({"polynomial": "auto", "block": "strips"}, "in a block the strips share the control"),
        ({"polynomial": 2, "block": "models"}, 'with block = "models" every model'),
        ({"route": "geocentric"}, "needs a real CRS"),
    ],
)
def test_write_project_refuses_bad_keys(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        _block(crs="local").write_project(tmp_path, **kwargs)


def test_the_name_is_a_comment_even_with_awkward_characters(tmp_path):
    _block().write_project(tmp_path, name='Block "A"\nline two\x7f')
    text = (tmp_path / "strip.toml").read_text(encoding="utf-8")
    assert text.splitlines()[0] == '# Block "A" line two'
    with (tmp_path / "strip.toml").open("rb") as fh:
        assert len(tomllib.load(fh)["strips"]) == 3


# ---------------------------------------------------------------------------
# Speed: vectorised, linear in the number of photos


def test_a_ten_by_hundred_drone_block_is_fast():
    start = time.perf_counter()
    block = simulate_block(10, 100, preset="drone", seed=1)
    elapsed = time.perf_counter() - start
    assert block.observations.n_photos == 1000
    assert min(len(block.common_points(k, k + 1)) for k in range(9)) > 300
    # about 0.1 s on a laptop; a bound far above it catches quadratic work
    assert elapsed < 10.0


# ---------------------------------------------------------------------------
# The command line


def invoke(*args: str | Path):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_cli_writes_a_block(tmp_path):
    folder = tmp_path / "block"
    result = invoke(
        "simulate", "drone", "--strips", "4", "--photos", "10", "--side-overlap", "40",
        "--flight", "same", "--seed", "2", "--out", folder,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "4 strips, 40 photos" in result.output
    with (folder / "strip.toml").open("rb") as fh:
        doc = tomllib.load(fh)
    expected = simulate_block(
        4, 10, preset="drone", side_overlap=0.4, flight="same", seed=2
    ).strip_photo_ids
    assert [tuple(s["photos"]) for s in doc["strips"]] == list(expected)
    assert doc["adjustment"]["block"] == "models"
    _, control = _read_csv(folder / "control.csv")
    assert Counter(r["type"] for r in control)["height"] > 0  # perimeter by default


def test_cli_strip_output_is_the_library_strip(tmp_path):
    """One strip (the default --strips 1) writes what simulate_strip writes."""
    result = invoke("simulate", "film", "--photos", "6", "--seed", "4", "--out", tmp_path / "a")
    assert result.exit_code == 0, result.output
    simulate_strip(6, preset="film", seed=4).write_project(tmp_path / "b")
    for name in ("strip.toml", "image_points.csv", "control.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["film", "--side-overlap", "30"], "--side-overlap describes a block"),
        (["film", "--flight", "same"], "--flight describes a block"),
        (["film", "--control", "perimeter"], "--control perimeter is for a block"),
        (["corridor", "--strips", "3"], "a block has no straight road"),
        (["film", "--strips", "3", "--line"], "a block has no straight road"),
        (["film", "--strips", "3", "--side-overlap", "70"], "--side-overlap"),
    ],
)
def test_cli_block_usage_errors(tmp_path, args, message):
    result = invoke("simulate", *args, "--out", tmp_path / "x")
    assert result.exit_code == 2, result.output
    assert message in result.output
