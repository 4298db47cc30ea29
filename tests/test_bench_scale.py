"""benchmarks/bench_scale.py: its quick mode runs and prints every column
(no timing is asserted: the floors are read from the full run)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).parents[1] / "benchmarks"
sys.path.insert(0, str(BENCH))
from bench_scale import parse_case, slope  # noqa: E402


def _bench(script: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run a benchmark script with this interpreter's installed ``stripaero`` first on PATH."""
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return subprocess.run(
        [sys.executable, str(BENCH / script), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=300,
        check=False,
    )


def test_quick_mode_prints_sizes_times_memory_and_the_slope(tmp_path: Path) -> None:
    done = _bench("bench_scale.py", "--quick", "--json", "r.json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert out.startswith("load average at start: ")
    row = re.compile(r"^(\S+)\s+(\d+)\s+(\d+)\s+1\s+([\d.]+)\s+(\d+)\s", re.M)
    rows = {m[1]: m.groups() for m in row.finditer(out)}
    assert set(rows) == {"strip-30-bundle", "block-2x10", "strip-15", "strip-30"}
    assert rows["block-2x10"][1] == "20"
    for _, photos, obs, wall, peak in rows.values():
        assert int(obs) > 50 * int(photos)  # about 100 image points per photo
        assert float(wall) > 0 and int(peak) > 30  # a real child's time and memory (MB)
    assert "bundle " in out  # report.json's stage timings of the refinement
    assert re.search(r"slope log\(time\) / log\(photos\), BLAS 1: -?[\d.]+ over 15-30", out)
    assert (tmp_path / "r.json").exists()


def test_case_names() -> None:
    assert parse_case("strip-1000") == (1, 1000, False)
    assert parse_case("block-10x300-bundle") == (10, 300, True)
    with pytest.raises(ValueError, match="strip-M"):
        parse_case("stripe-10")


def test_slope_of_a_power_law() -> None:
    photos = [100, 300, 1000, 3000]
    assert slope(photos, [2e-3 * p**1.07 for p in photos]) == pytest.approx(1.07)


def test_band_benchmark_quick_mode_and_its_bandwidth_rule() -> None:
    from bench_band import half_band, time_band

    # a strip: the overlap window on either side; a block numbered across
    # its strips: the window times the strips (docs/scaling.md)
    assert half_band(1) == 6 * 5 - 1
    assert half_band(20) == 6 * (4 * 20 + 20 + 1) - 1
    factor, solve, mb = time_band(600, 29, repeat=1)
    assert factor > 0 and solve > 0 and mb == 30 * 600 * 8 / 1e6
    done = _bench("bench_band.py", "--quick", "--repeat", "1")
    assert done.returncode == 0, done.stderr
    assert re.search(r"^\s+20 x 500\s+10000\s+60000\s+605 factor\s+[\d.]+ s", done.stdout, re.M)


def test_a_project_from_elsewhere_runs_as_a_case(tmp_path: Path) -> None:
    from strip_aerotri import simulate_strip

    toml = simulate_strip(6, preset="film", seed=2).write_project(tmp_path / "elsewhere")
    case = f"strip-1000={toml}"
    done = _bench("bench_scale.py", "--project", case, "--threads", "1", "--no-curve")
    assert done.returncode == 0, done.stderr
    # the project's own size, the case's floor ratio (1.5 s), no output in its folder
    assert re.search(r"^strip-1000\s+6\s+\d+\s+1\s+[\d.]+\s+\d+\s+[\d.]+\s", done.stdout, re.M)
    assert not (toml.parent / "out").exists()
    bad = _bench("bench_scale.py", "--project", "strip-1000")
    assert bad.returncode == 1 and "expected CASE=STRIP_TOML" in bad.stderr


def test_interrupt_benchmark_sends_sigint_and_times_the_exit() -> None:
    from bench_interrupt import idle_exit, interrupt_at

    code = "import sys, time\nprint('working', file=sys.stderr, flush=True)\ntime.sleep(60)"
    waited, exit_code, stage = interrupt_at([sys.executable, "-c", code], 1.0)
    assert waited is not None and waited < 30  # SIGINT reached a 60 s sleep
    assert exit_code == -2  # Python's uncaught KeyboardInterrupt ends by SIGINT
    assert stage == "working"  # the last progress line before the signal
    finished, exit_code, _ = interrupt_at([sys.executable, "-c", "pass"], 20.0)
    assert finished is None and exit_code == 0
    assert len(idle_exit(repeat=1)) == 1


def test_a_run_past_the_timeout_is_shown_without_a_result(tmp_path: Path) -> None:
    done = _bench(
        "bench_scale.py", "--cases", "strip-12", "--curve", "6", "12", "--timeout", "0.01",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    stopped = r"^strip-12\s+12\s+\d+\s+1\s+no result: stopped after 0.01 s$"
    assert re.search(stopped, done.stdout, re.M)
    assert "slope, BLAS 1: not computed (a run gave no result)" in done.stdout


def test_the_ground_benchmark_counts_solutions_and_iterations(tmp_path: Path) -> None:
    """benchmarks/bench_ground.py on two small strips: one row per strip with
    its determinations, one solution (a clean strip: nothing rejected) of a
    few iterations, no groups (a strip this short starts from J's
    similarity), then the slope."""
    done = _bench("bench_ground.py", "--photos", "15", "30", "--keep", str(tmp_path))
    assert done.returncode == 0, done.stderr
    number, seconds = r"\s+(\d+)", r"\s+[\d.]+"
    row = re.compile(
        rf"^\s*(\d+){number}{seconds}{seconds}{number}{number}{number}{number}{number}"
        r"\s+\d+\s+\d+$",
        re.M,
    )
    rows = {int(m[1]): [int(g) for g in m.groups()[1:]] for m in row.finditer(done.stdout)}
    assert sorted(rows) == [15, 30], done.stdout
    for determinations, solutions, iterations, groups, group_iterations, rejected in rows.values():
        assert determinations > 0 and solutions == 1 and rejected == 0
        assert 1 <= iterations <= 10
        assert groups == 0 and group_iterations == 0
    assert rows[30][0] > rows[15][0]
    assert "slope log(CPU) / log(photos): " in done.stdout
    assert (tmp_path / "strip-30.pkl").exists()  # kept for the next run
