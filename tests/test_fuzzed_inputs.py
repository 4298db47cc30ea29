"""Inputs found by fuzzing the project reader and the run: each must end in
one error line (exit 1) naming its culprit, quickly, never in a hang, a
traceback, a "result", or more than one stderr line.

The projects are simulated (``stripaero simulate``) and then damaged as the
fuzzer did.  Cases that hung (a named pipe, ``/dev/zero``) run in a
subprocess with a timeout, so that a regression fails instead of hanging.
"""

from __future__ import annotations

import csv
import io
import os
import re
import subprocess
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from _cli_process import cli_subprocess
from strip_aerotri._text import MAX_ECHO, clean, shorten
from strip_aerotri.cli.main import cli

#: The floor of a message line: under 500 characters.
MAX_LINE_CHARS = 500


def invoke(*args: str | Path):
    return CliRunner().invoke(cli, [str(a) for a in args])


def one_error(result, *pieces: str) -> str:
    """The one error line of a failed command, holding every piece."""
    assert result.exit_code == 1, (result.exit_code, result.output[-2000:])
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr[:2000]
    (line,) = lines
    assert line.startswith("stripaero: error: "), line
    assert not line.startswith("stripaero: error: unexpected "), line
    assert len(line) < MAX_LINE_CHARS, len(line)
    for piece in pieces:
        assert piece in line, (piece, line)
    return line


def both_fail(project: Path, *pieces: str) -> None:
    """``check`` and ``run`` each end in one error line holding ``pieces``."""
    for command in ("check", "run"):
        one_error(invoke(command, project / "strip.toml"), *pieces)


def simulate(folder: Path, *args: str) -> Path:
    result = invoke("simulate", *args, "--out", folder, "-q")
    assert result.exit_code == 0, result.output
    return folder


@pytest.fixture(scope="module")
def film_files(tmp_path_factory) -> dict[str, bytes]:
    folder = simulate(tmp_path_factory.mktemp("film") / "p", "film", "--photos", "6")
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.fixture
def film(tmp_path, film_files) -> Path:
    folder = tmp_path / "film"
    folder.mkdir()
    for name, data in film_files.items():
        (folder / name).write_bytes(data)
    return folder


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def set_cell(path: Path, row: int, column: str, value: str) -> None:
    """Cell ``column`` of data row ``row`` (0 = the first after the header)."""
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))
    rows[row + 1][rows[0].index(column)] = value
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_text(buffer.getvalue(), encoding="utf-8")


def one_error_of(proc: subprocess.CompletedProcess[str], *pieces: str) -> str:
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-2000:])
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr[:2000]
    assert lines[0].startswith("stripaero: error: "), lines[0]
    assert not lines[0].startswith("stripaero: error: unexpected "), lines[0]
    assert len(lines[0]) < MAX_LINE_CHARS
    for piece in pieces:
        assert piece in lines[0], (piece, lines[0])
    return lines[0]


# --------------------------------------------------------------------------- 1. hangs


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
@pytest.mark.parametrize("name", ["strip.toml", "image_points.csv", "control.csv"])
def test_a_named_pipe_is_refused_without_blocking(film, name):
    (film / name).unlink()
    os.mkfifo(film / name)  # no writer: opening it for reading blocks forever
    for command in ("check", "run"):
        proc = cli_subprocess(command, film / "strip.toml", timeout=30)
        one_error_of(proc, f"{film / name}:", "named pipe (FIFO)", "not a regular file")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_as_control_file_is_refused_before_reading(film):
    (film / "control.csv").unlink()
    (film / "control.csv").symlink_to("/dev/zero")  # reading it never ends
    proc = cli_subprocess("check", film / "strip.toml", timeout=30)
    one_error_of(proc, "control.csv", "[control] file", "a device, not a regular file")


def test_a_folder_named_as_a_file_is_refused(film):
    (film / "control.csv").unlink()
    (film / "control.csv").mkdir()
    both_fail(film, "control.csv", "is a folder, not a file")


def test_a_file_beyond_the_size_limit_is_refused(film, monkeypatch):
    from strip_aerotri.project import csvfiles

    monkeypatch.setattr(csvfiles, "MAX_CSV_BYTES", 1000)
    both_fail(film, "image_points.csv", "larger than the 1000 bytes")


def test_a_huge_strip_name_is_refused_at_once(tmp_path):
    block = simulate(tmp_path / "b", "drone", "--strips", "2", "--photos", "4")
    edit(block / "strip.toml", 'name = "S1"', 'name = "' + "N" * 1_000_000 + '"')
    started = time.perf_counter()
    both_fail(block, "[[strips]] #1 name", "a name of 1000000 characters", "at most 200")
    assert time.perf_counter() - started < 20.0  # figures of it took minutes


def test_the_longest_strip_name_runs_with_its_figures(tmp_path):
    """200 characters (the limit) with an escape sequence's worth of text:
    the run draws it shortened in the legend and is done in seconds."""
    block = simulate(tmp_path / "b", "drone", "--strips", "2", "--photos", "4")
    edit(block / "strip.toml", 'name = "S1"', 'name = "' + "N" * 200 + '"')
    started = time.perf_counter()
    result = invoke("run", block / "strip.toml")
    assert result.exit_code == 0, result.output
    assert time.perf_counter() - started < 30.0
    assert "N" * 200 in (block / "out" / "report.json").read_text(encoding="utf-8")


# --------------------------------------------------------------------------- 2. false successes


def test_a_check_point_at_y_1e308_is_implausible_in_check_and_run(film):
    rows = list(csv.reader(io.StringIO((film / "control.csv").read_text(encoding="utf-8"))))
    row = next(i for i, r in enumerate(rows[1:]) if r[rows[0].index("type")] == "check")
    point = rows[row + 1][0]
    set_cell(film / "control.csv", row, "Y", "1e308")
    both_fail(film, f"control.csv:{row + 2}: point '{point}'", "implausible coordinates")
    assert not (film / "out").exists()


@pytest.mark.parametrize(
    ("column", "value", "rule"),
    [
        ("H", "250000", "H beyond"),
        ("X", "-4e9", "X or Y beyond"),
        ("Y", "+5e7", "from the median of the plan coordinates"),
    ],
    ids=["height", "huge-X", "far-from-the-rest"],
)
def test_coordinates_far_outside_the_project_are_implausible(film, column, value, rule):
    set_cell(film / "control.csv", 0, column, value)
    both_fail(film, "control.csv:2:", "implausible coordinates", rule)


def test_a_check_point_400_km_away_is_implausible(film):
    """Found by the fuzz test: a check point at X = 1e5 instead of ~5e5 (UTM)
    is inside every absolute bound and within 1000 times the control's
    spread, and the run printed "RMSE plan 56692.928 m" with exit 0.  On its
    photos it is 200 times farther from the other plan points than the
    photos show at the strip's scale (legit projects stay under 1.5)."""
    rows = list(csv.reader(io.StringIO((film / "control.csv").read_text(encoding="utf-8"))))
    row = next(i for i, r in enumerate(rows[1:]) if r[rows[0].index("type")] == "check")
    point = rows[row + 1][0]
    set_cell(film / "control.csv", row, "X", "1e5")
    both_fail(film, f"control.csv: point '{point}'", "implausible coordinates", "farther")
    assert not (film / "out").exists()


def test_a_point_outside_the_projection_domain_is_implausible(film):
    # UTM 34N cannot take an easting of 9e7 m back to longitude and latitude
    set_cell(film / "control.csv", 0, "X", "9e7")
    both_fail(film, "control.csv:2:", "implausible coordinates")


def test_a_gnss_centre_far_away_is_implausible(film):
    """GNSS centres follow the control's rules (their Z is a height too)."""
    rows = list(csv.reader(io.StringIO((film / "control.csv").read_text(encoding="utf-8"))))
    full = [r for r in rows[1:] if r[rows[0].index("type")] == "full"]
    listed = re.search(r"photos = \[([^\]]*)\]", (film / "strip.toml").read_text("utf-8"))
    assert listed is not None
    photos = re.findall(r'"([^"]+)"', listed.group(1))
    lines = ["photo,X,Y,Z"] + [
        f"{p},{full[0][1]},{full[0][2]},{float(full[0][3]) + 1200.0}" for p in photos[:6]
    ]
    lines[3] = f"{photos[2]},{full[0][1]},-4e9,1500"
    (film / "gnss.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    edit(film / "strip.toml", "[control]", '[gnss]\nfile = "gnss.csv"\n\n[control]')
    edit(film / "strip.toml", "[adjustment]", '[adjustment]\nrefine = "bundle"')
    both_fail(film, f"gnss.csv:4: photo '{photos[2]}' at X, Y, Z", "implausible coordinates")


def test_a_photo_whose_points_are_collinear_is_an_error_naming_it(tmp_path):
    # the fuzzer's case: every point of the last drone photo at x = 3.000 mm;
    # the run gave phi = 36.6 deg (truth -0.1) and exit 0
    drone = simulate(tmp_path / "d", "drone", "--seed", "2")
    path = drone / "image_points.csv"
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))
    last = rows[1:][-1][0]
    x = rows[0].index("x")
    for r in rows[1:]:
        if r[0] == last:
            r[x] = "3.000"
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_text(buffer.getvalue(), encoding="utf-8")
    one_error(invoke("run", drone / "strip.toml"), f"photo {last}:", "nearly on one line")
    assert not (drone / "out").exists()


def test_a_block_with_mirrored_control_is_refused_without_blunder_tests(tmp_path):
    """Found by the fuzz test: a block's run checked for control in degrees
    only, so with ``[blunders] action = "off"`` control with X and Y swapped
    ran to a result (RMSE 0.4 m plan, 1.4 m height, exit 0); ``check`` said
    it was mirrored."""
    block = simulate(tmp_path / "b", "drone", "--strips", "3", "--photos", "4", "--seed", "3")
    path = block / "control.csv"
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))
    for r in rows[1:]:
        r[1], r[2] = r[2], r[1]
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_text(buffer.getvalue(), encoding="utf-8")
    with (block / "strip.toml").open("a", encoding="utf-8") as stream:
        stream.write('\n[blunders]\naction = "off"\n')
    both_fail(block, "control.csv", "the control is mirrored against the photos")
    assert not (block / "out").exists()


# --------------------------------------------------------------------------- 3. one line


def test_all_control_at_1e308_prints_no_numpy_warning(film):
    rows = list(csv.reader(io.StringIO((film / "control.csv").read_text(encoding="utf-8"))))
    for r in rows[1:]:
        r[1] = r[1] and "1e308"
        r[2] = r[2] and "1e308"
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    (film / "control.csv").write_text(buffer.getvalue(), encoding="utf-8")
    for command in ("check", "run"):  # a subprocess: pytest records warnings in-process
        one_error_of(cli_subprocess(command, film / "strip.toml"), "implausible coordinates")


def test_numpy_warnings_are_not_printed_by_the_cli(monkeypatch):
    """A floating-point warning raised inside a command is not echoed."""
    import warnings

    import numpy as np

    from strip_aerotri.cli import check as check_module

    def overflowing(project_file, out):  # the command body, replaced
        with np.errstate(over="warn"):
            np.array([1e308]) * 10.0
        raise click_exit()

    import click

    def click_exit():
        return click.exceptions.Exit(0)

    monkeypatch.setattr(check_module.check, "callback", overflowing)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = invoke("check", "x.toml")
    assert result.exit_code == 0
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


@pytest.mark.parametrize("command", ["check", "run"])
def test_out_naming_an_existing_file_is_one_line(film, tmp_path, command):
    target = tmp_path / "a-file"
    target.write_text("keep me", encoding="utf-8")
    result = invoke(command, film / "strip.toml", "--out", target)
    one_error(result, str(target), "is a file")
    assert target.read_text(encoding="utf-8") == "keep me"


# --------------------------------------------------------------------------- 4. named culprits


@pytest.mark.parametrize(
    "value",
    ["[" * 1000 + "]" * 1000, "{a=" * 1000 + "1" + "}" * 1000, "[" * 20 + "1" + "]" * 20],
    ids=["arrays-1000", "tables-1000", "arrays-20"],
)
def test_toml_nested_too_deep(film, value):
    with (film / "strip.toml").open("a", encoding="utf-8") as stream:
        stream.write(f"\n[report]\nmap_scale = {value}\n")
    both_fail(film, "strip.toml", "nested more than 8 deep")


def test_a_dotted_key_of_50000_parts(film):
    text = (film / "strip.toml").read_text(encoding="utf-8")
    (film / "strip.toml").write_text(".".join(["a"] * 50_000) + " = 1\n" + text, "utf-8")
    started = time.perf_counter()
    both_fail(film, "strip.toml:1:", "dotted key of more than 16 parts")
    assert time.perf_counter() - started < 10.0  # tomllib: 5 s at 20 000 parts, quadratic


def test_a_long_word_in_toml_is_not_taken_for_a_dotted_key(film):
    """The dotted-key scan is linear: a 1 MB bare word costs no more than a
    pass (a scan restarting inside the word would be quadratic)."""
    from strip_aerotri.project.loader import _DOTTED_KEY

    started = time.perf_counter()
    assert _DOTTED_KEY.search("N" * 1_000_000 + " " + "a.b " * 1000) is None
    assert time.perf_counter() - started < 2.0
    assert _DOTTED_KEY.search("x = 1\n" + ".".join(["k"] * 17) + " = 2") is not None
    assert _DOTTED_KEY.search("[a.b.c]\nphotos = ['1.2.3']") is None


def test_a_point_id_of_100000_characters(film):
    set_cell(film / "image_points.csv", 0, "point", "P" * 100_000)
    both_fail(film, "image_points.csv:2: column 'point'", "an id of 100000 characters")


def test_an_id_with_a_control_character(film):
    set_cell(film / "control.csv", 0, "point", "P\x1b[31mX")
    line = one_error(invoke("check", film / "strip.toml"), "control.csv:2", "control character")
    assert "\x1b" not in line


def test_a_photo_id_too_long_in_strip_toml(film):
    edit(film / "strip.toml", 'photos = ["', 'photos = ["' + "9" * 300 + '", "')
    both_fail(film, "[strip] photos", "an id of 300 characters")


@pytest.mark.parametrize(
    ("line", "key"),
    [
        ("\n[blunders]\nalpha = 5e-324\n", "[blunders] alpha"),
        ("\n[blunders]\nalpha = 1e-13\n", "[blunders] alpha"),
    ],
)
def test_alpha_beyond_its_range(film, line, key):
    with (film / "strip.toml").open("a", encoding="utf-8") as stream:
        stream.write(line)
    both_fail(film, key, "expected a number from 1e-12 to 1")


@pytest.mark.parametrize("value", ["1e-320", "1.2e29", "11.0", "1e-7"])
def test_image_sigma_beyond_its_range_in_strip_toml(film, value):
    edit(
        film / "strip.toml",
        'file = "image_points.csv"',
        f'file = "image_points.csv"\nsigma_mm = {value}',
    )
    both_fail(film, "[images] sigma_mm", "expected a number from 1e-06 to 10 mm")


@pytest.mark.parametrize("value", ["1e-320", "1.2e29"])
def test_image_sigma_beyond_its_range_in_the_column(film, value):
    set_cell(film / "image_points.csv", 2, "sigma", value)
    both_fail(film, "image_points.csv:4: column 'sigma'", "expected a number from 1e-06 to 10 mm")


def test_control_sigma_beyond_its_range(film):
    set_cell(film / "control.csv", 1, "sigma_h", "1e-300")
    both_fail(film, "control.csv:3: column 'sigma_h'", "expected a number from 1e-06")


def test_a_sane_sigma_still_runs(film):
    edit(
        film / "strip.toml",
        'file = "image_points.csv"',
        'file = "image_points.csv"\nsigma_mm = 0.004',
    )
    result = invoke("check", film / "strip.toml")
    assert result.exit_code == 0, result.output


def test_a_nul_byte_in_the_images_file(film):
    edit(film / "strip.toml", 'file = "image_points.csv"', 'file = "image_\\u0000points.csv"')
    both_fail(film, "[images] file", "control character")


# --------------------------------------------------------------------------- 5. minor


def test_a_huge_value_is_shortened_in_the_message(film):
    set_cell(film / "control.csv", 0, "X", "x" * 10_000_000)
    line = one_error(invoke("check", film / "strip.toml"), "control.csv:2: column 'X'")
    assert "characters)" in line


def test_nul_and_escape_sequences_are_not_echoed(film):
    set_cell(film / "control.csv", 0, "X", "\x1b[2J\x1b[31m12\x00x")
    line = one_error(invoke("run", film / "strip.toml"), "control.csv:2: column 'X'")
    assert "\x1b" not in line and "\x00" not in line
    assert "'12x'" in line


def test_shorten():
    assert shorten("P0001") == "P0001"
    long = shorten("a" * 10_000_000)
    assert len(long) <= MAX_ECHO and "(99999" in long and long.startswith("aaa")
    assert shorten("x" * 1000, 30) == "xxxxxx…(989 characters)…xxxxx"
    assert clean("a\x1b[1;31mb\x1b]c\x00d\x7fe\tf\ng") == "abcde\tf\ng"
    assert shorten("\x1b[31m" + "y" * 500, 20).startswith("y")


def test_the_option_rules_hold_the_ranges_for_the_library_too():
    """The loader's ranges are the option rules of options.py (one place)."""
    from strip_aerotri.options import RULES, BlunderOptions, OptionError

    with pytest.raises(OptionError, match="alpha: expected a number from 1e-12 to 1"):
        BlunderOptions(alpha=5e-324)
    with pytest.raises(OptionError, match="sigma_mm: expected a number from 1e-06 to 10 mm"):
        RULES[("images", "sigma_mm")](1.2e29)
    with pytest.raises(OptionError, match="sigma_h_m: expected a number from 1e-06 to 1e"):
        RULES[("control", "sigma_h_m")](1e-320)
    assert RULES[("imu", "sigma_deg")](0.005) == 0.005


def test_a_crs_given_as_multi_line_wkt_is_still_read(film):
    """Line breaks are refused in names, ids and paths only: a CRS's WKT spans lines."""
    import pyproj

    wkt = pyproj.CRS("EPSG:32634").to_wkt(pretty=True)
    assert "\n" in wkt
    edit(film / "strip.toml", 'crs = "EPSG:32634"', f'crs = """{wkt}"""')
    result = invoke("check", film / "strip.toml")
    assert result.exit_code == 0, result.output


def test_running_out_of_memory_is_one_line(film, monkeypatch):
    """The last resort: a MemoryError is told in words, not as "unexpected"."""
    from strip_aerotri import project

    def exhausted(path):
        raise MemoryError

    monkeypatch.setattr(project, "load_project", exhausted)
    one_error(invoke("check", film / "strip.toml"), "out of memory")


def test_a_control_point_no_photo_observes_is_left_out_whatever_its_coordinates(film):
    """formats.md: an unobserved control point is a warning, not an error;
    the plausibility rules judge the points the photos observe."""
    with (film / "control.csv").open("a", encoding="utf-8") as stream:
        stream.write("FARAWAY,1e308,4e7,9e6,full,,\n")
    result = invoke("check", film / "strip.toml")
    assert result.exit_code == 0, result.output
    assert "'FARAWAY'" in result.stderr and "not observed" in result.stderr


def test_collinear_ratio_against_a_dense_svd():
    """collinear_ratio (per pair, from 2 x 2 scatter eigenvalues) equals the
    ratio of the singular values of each pair's centred normalised points."""
    import numpy as np

    from strip_aerotri.strip.relative import collinear_ratio

    rng = np.random.default_rng(2345)
    counts = np.array([6, 9, 5, 12])
    pair = np.repeat(np.arange(4), counts)
    image = np.column_stack(
        [
            rng.uniform(-100, 100, pair.size),
            rng.uniform(-100, 100, pair.size),
            -np.full(pair.size, 152.0),
        ]
    )
    image[pair == 2, 0] = 3.0  # pair 2: every point on the line x = 3 mm
    image[pair == 3, 1] = 0.5 * image[pair == 3, 0] + rng.normal(0, 0.05, 12)  # nearly on a line
    got = collinear_ratio(image, pair, 5)  # pair 4 has no points
    for m in range(4):
        uv = image[pair == m, :2] / 152.0
        s = np.linalg.svd(uv - uv.mean(axis=0), compute_uv=False)
        assert got[m] == pytest.approx(s[1] / s[0], rel=1e-9, abs=1e-12)
    assert got[2] == 0.0 and got[3] < 1e-2 < got[0]
    assert np.isnan(got[4])


def test_a_distortion_coefficient_beyond_any_lens(film):
    """Found by the fuzz test: k1 = 1e308 overflowed the distortion polynomial."""
    with (film / "strip.toml").open("a", encoding="utf-8") as stream:
        stream.write("\n[distortion]\nk1 = 1e308\n")
    both_fail(film, "[distortion] k1", "expected a number from -1e+06 to 1e+06")
