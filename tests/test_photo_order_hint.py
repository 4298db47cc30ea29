"""Photos listed out of flight order, told by their common points
(``plausibility.photo_order_hint``), in ``stripaero check`` and ``run``.

Found by the catalogue fuzz (``benchmarks/fuzz_inputs.py``): with the film
example's photos listed odd ones first, ``run`` stopped on "pair 1011-1002:
0 point(s) measured on both photos" and ``check`` listed 15 pair and
control problems, neither naming the order; with two photos swapped,
``check`` said only that two pairs share no tie point.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import strip_aerotri as sa
from _shuffled import shuffled_block
from strip_aerotri.cli.main import cli
from strip_aerotri.plausibility import photo_order_hint
from strip_aerotri.project import load_project

ROOT = Path(__file__).resolve().parents[1]
FILM = ROOT / "examples" / "film-strip"
SHARED = ROOT.parent / "shared" / "data"
SHUFFLED = [f"{1000 + i}" for i in (1, 3, 5, 7, 9, 11, 2, 4, 6, 8, 10, 12)]


def _common_by_sets(obs: sa.ImageObservations) -> dict[tuple[str, str], int]:
    seen: dict[str, set[int]] = {}
    for photo, point in zip(obs.photo.tolist(), obs.point.tolist(), strict=True):
        seen.setdefault(obs.photo_ids[photo], set()).add(point)
    return {(a, b): len(seen[a] & seen[b]) for a in seen for b in seen if a != b}


def _projects() -> list[Path]:
    found = [FILM / "strip.toml", ROOT / "examples" / "drone-corridor" / "strip.toml"]
    found += sorted(SHARED.glob("external-strips/*/strip.toml"))
    return found


@pytest.mark.parametrize("path", _projects(), ids=lambda p: p.parent.name)
def test_photos_in_flight_order_get_no_hint_even_when_every_pair_is_asked(path: Path) -> None:
    obs = load_project(path).observations
    seq = np.arange(obs.n_photos)
    assert photo_order_hint(obs, seq, None, 5) == (-1, "")
    assert photo_order_hint(obs, seq, seq[:-1], 5) == (-1, "")


def test_the_fc300x_strips_get_no_hint(tmp_path: Path) -> None:
    data = SHARED / "uav-block-fc300x"
    if not data.is_dir():
        pytest.skip("the FC300X data are not beside the repository")
    result = CliRunner().invoke(
        cli, ["import", "uav-fc300x", str(data), "--out", str(tmp_path / "p")]
    )
    assert result.exit_code == 0, result.output
    project = load_project(tmp_path / "p" / "strip.toml")
    obs = project.observations
    index = {p: i for i, p in enumerate(obs.photo_ids)}
    for spec in project.strips:
        seq = np.array([index[p] for p in spec.photo_ids])
        assert photo_order_hint(obs, seq, np.arange(seq.size - 1), 5) == (-1, "")


def test_a_shuffled_list_is_named_with_counts_from_sets() -> None:
    obs = load_project(FILM / "strip.toml").observations
    index = {p: i for i, p in enumerate(obs.photo_ids)}
    pair, hint = photo_order_hint(obs, [index[p] for p in SHUFFLED], None, 5)
    assert (SHUFFLED[pair], SHUFFLED[pair + 1]) == ("1011", "1002")  # the first pair with none
    common = _common_by_sets(obs)
    named = re.findall(r"'(\d+)' next to '(\d+)' \((\d+)\) and '(\d+)' \((\d+)\)", hint)
    # each photo of the failing pair belongs between its neighbours in the flight
    assert {(p, a, b) for p, a, _, b, _ in named} == {
        ("1011", "1010", "1012"),
        ("1002", "1001", "1003"),
    } or {(p, b, a) for p, a, _, b, _ in named} == {
        ("1011", "1010", "1012"),
        ("1002", "1001", "1003"),
    }, hint
    for photo, a, count_a, b, count_b in named:
        assert (int(count_a), int(count_b)) == (common[(photo, a)], common[(photo, b)])


def _without(obs: sa.ImageObservations, drop: np.ndarray) -> sa.ImageObservations:
    keep = ~drop
    return sa.ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo[keep], obs.point[keep], obs.xy[keep],
        obs.sigma[keep], obs.principal_distance,
    )  # fmt: skip


def test_a_photo_with_few_points_is_not_taken_for_the_order() -> None:
    """Photo 1007 over water keeps 4 of its points: both its pairs fail, but
    by its points it still lies between 1006 and 1008."""
    obs = load_project(FILM / "strip.toml").observations
    on_1007 = np.flatnonzero(obs.photo == obs.photo_ids.index("1007"))
    few = _without(obs, np.isin(np.arange(obs.photo.size), on_1007[4:]))
    assert photo_order_hint(few, np.arange(few.n_photos), None, 5) == (-1, "")


def test_an_order_the_points_cannot_tell_gets_no_hint() -> None:
    """Photo 1007 loses every point it shares with 1006: by the counts alone
    1006, 1008, 1007, 1009 is an order that gives every pair five points, and
    the hint names it (the run's relative orientation then tells).  With
    1006 also sharing only three points with 1008, no order does: no hint."""
    obs = load_project(FILM / "strip.toml").observations
    photo = {p: obs.photo == obs.photo_ids.index(p) for p in ("1006", "1007", "1008")}
    on_1006, on_1008 = obs.point[photo["1006"]], obs.point[photo["1008"]]
    drop = photo["1007"] & np.isin(obs.point, on_1006)
    pair, hint = photo_order_hint(_without(obs, drop), np.arange(obs.n_photos), None, 5)
    assert pair == 5 and "'1007' next to '1008'" in hint, hint
    shared = np.intersect1d(on_1006, on_1008)
    drop |= photo["1006"] & np.isin(obs.point, shared[3:])
    weak = _without(obs, drop)
    assert photo_order_hint(weak, np.arange(weak.n_photos), None, 5) == (-1, "")


def _film(tmp_path: Path, photos: list[str]) -> Path:
    folder = tmp_path / "p"
    shutil.copytree(FILM, folder, ignore=shutil.ignore_patterns("out"))
    toml = folder / "strip.toml"
    listed = ", ".join(f'"{p}"' for p in photos)
    toml.write_text(
        re.sub(r"^photos = \[.*\]$", f"photos = [{listed}]", toml.read_text("utf-8"), flags=re.M),
        "utf-8",
    )
    return folder


def test_check_and_run_name_a_shuffled_order(tmp_path: Path) -> None:
    folder = _film(tmp_path, SHUFFLED)
    run = CliRunner().invoke(cli, ["run", str(folder / "strip.toml")])
    assert run.exit_code == 1
    (line,) = run.stderr.splitlines()
    assert "pair 1011-1002: fewer than 5 points" in line and "out of flight order" in line, line
    assert len(line) < 500
    check = CliRunner().invoke(cli, ["check", str(folder / "strip.toml")])
    assert check.exit_code == 1
    assert any("out of flight order" in ln for ln in check.stderr.splitlines()), check.stderr
    assert not (folder / "out").exists()


def test_two_swapped_photos_are_named_by_check_and_run(tmp_path: Path) -> None:
    """Two photos swapped: check, which stops at the tie points, names them by
    their common points; the run by its relative orientation."""
    photos = [f"{1000 + i}" for i in range(1, 13)]
    photos[6], photos[7] = photos[7], photos[6]
    folder = _film(tmp_path, photos)
    check = CliRunner().invoke(cli, ["check", str(folder / "strip.toml")])
    assert check.exit_code == 1
    hints = [ln for ln in check.stderr.splitlines() if "out of flight order" in ln]
    assert len(hints) == 1 and "'1008' next to" in hints[0], check.stderr
    run = CliRunner().invoke(cli, ["run", str(folder / "strip.toml")])
    assert run.exit_code == 1
    (line,) = run.stderr.splitlines()
    assert "pair 1008-1007" in line and "in flight order" in line, line


def test_a_block_strip_out_of_order_is_named_with_its_strip(tmp_path: Path) -> None:
    toml = shuffled_block(tmp_path)
    run = CliRunner().invoke(cli, ["run", str(toml)])
    assert run.exit_code == 1
    (line,) = run.stderr.splitlines()
    assert "strip 'S2'" in line and "out of flight order" in line, line
    check = CliRunner().invoke(cli, ["check", str(toml)])
    assert any(
        "strip 'S2'" in ln and "out of flight order" in ln for ln in check.stderr.splitlines()
    ), check.stderr


def test_check_and_run_give_one_hint_with_a_photo_step(tmp_path: Path) -> None:
    """With ``photo_step = 2`` the models are formed on every other photo:
    ``check`` and ``run`` judge the order on those model photos alike and
    give the same hint (the run used to skip it and stop on the pair's
    points lying on one line)."""
    folder = tmp_path / "drone"
    made = CliRunner().invoke(
        cli, ["-q", "simulate", "drone", "--photos", "16", "--out", str(folder)]
    )
    assert made.exit_code == 0, made.output
    toml = folder / "strip.toml"
    in_order = toml.read_text("utf-8").replace("[adjustment]\n", "[adjustment]\nphoto_step = 2\n")
    shuffled = [f"{1000 + i}" for i in (*range(1, 17, 2), *range(2, 17, 2))]
    listed = "photos = [" + ", ".join(f'"{p}"' for p in shuffled) + "]"
    toml.write_text(re.sub(r"^photos = \[.*\]$", listed, in_order, flags=re.M), "utf-8")
    run = CliRunner().invoke(cli, ["run", str(toml)])
    assert run.exit_code == 1
    (line,) = run.stderr.splitlines()
    assert "pair 1009-1013: fewer than 5 points" in line, line
    hint = line[line.index("the photos seem listed out of flight order") :]
    check = CliRunner().invoke(cli, ["check", str(toml)])
    assert check.exit_code == 1
    assert any(ln.endswith(hint) for ln in check.stderr.splitlines()), (hint, check.stderr)
    assert not (folder / "out").exists()
    # in flight order with the same step, neither says anything of the order
    toml.write_text(in_order, "utf-8")
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, ["-q", command, str(toml)])
        assert result.exit_code == 0, (command, result.stderr)
        assert "flight order" not in result.stderr


@pytest.mark.parametrize("seed", range(6))
def test_consecutive_common_counts_as_sets_do(seed: int) -> None:
    """consecutive_common (numpy alone) against sets of points per photo, on
    random incidences with repeated pairs, empty photos and the last photo
    observing the next point's first key (point * n + n - 1 + 1)."""
    from strip_aerotri.plausibility import consecutive_common

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 30))
    m = int(rng.integers(0, 400))
    row = rng.integers(0, n, size=m)
    point = rng.integers(0, int(rng.integers(1, 60)), size=m)
    row[: m // 10] = n - 1  # the last photo: its key + 1 is the next point's first photo
    sets = [set(point[row == k].tolist()) for k in range(n)]
    expected = [len(sets[k] & sets[k + 1]) for k in range(n - 1)]
    got = consecutive_common(row, point, n)
    assert got.shape == (n - 1,)
    assert got.tolist() == expected


def test_consecutive_common_on_a_project_matches_its_common_points() -> None:
    obs = load_project(FILM / "strip.toml").observations
    common = _common_by_sets(obs)
    from strip_aerotri.plausibility import consecutive_common

    got = consecutive_common(obs.photo, obs.point, obs.n_photos)
    ids = obs.photo_ids
    assert got.tolist() == [common[(ids[k], ids[k + 1])] for k in range(obs.n_photos - 1)]
    assert got.min() > 0
