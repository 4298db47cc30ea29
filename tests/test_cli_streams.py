"""The command line's streams as scripts see them (subprocesses, no terminal)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from strip_aerotri.simulate import simulate_strip

CLI = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"


def test_output_piped_into_a_reader_that_stops_is_no_error(tmp_path: Path):
    """``stripaero run ... | head -1``: no BrokenPipeError, no traceback, exit 0.

    The reader is gone before the first line (its end of the pipe closed), so
    every write fails: the case is certain, not a race with a real ``head``."""
    toml = simulate_strip(8, seed=1).write_project(tmp_path / "p")
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        run = subprocess.run(
            [sys.executable, "-c", CLI, "run", str(toml)],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr and "BrokenPipe" not in run.stderr
    assert (toml.parent / "out" / "report.json").is_file()


def test_a_failing_run_writes_one_line_to_stderr(tmp_path: Path):
    """stderr not a terminal: exactly the one error line (no progress lines)."""
    bad = tmp_path / "strip.toml"
    bad.write_text("x\n")
    run = subprocess.run(
        [sys.executable, "-c", CLI, "run", str(bad)], capture_output=True, text=True
    )
    assert run.returncode == 1
    assert run.stderr.count("\n") == 1 and run.stderr.startswith("stripaero: error: ")


def test_quiet_hides_warnings_and_keeps_the_summary(tmp_path: Path):
    """``-q``: the summary on stdout and nothing on stderr, the warning kept in
    report.json; without it the warning is on stderr; ``-qq``: nothing."""
    import json

    toml = simulate_strip(8, seed=1).write_project(tmp_path / "p")
    control = toml.parent / "control.csv"
    header = control.read_text().splitlines()[0].split(",")
    row = {"point": "NOWHERE", "X": "500000", "Y": "4650000", "H": "300", "type": "check"}
    control.write_text(control.read_text() + ",".join(row.get(c, "") for c in header) + "\n")

    def run(*flags: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-c", CLI, *flags, "run", str(toml)],
            capture_output=True,
            text=True,
            timeout=120,
        )

    loud = run()
    assert loud.returncode == 0 and "NOWHERE" in loud.stderr
    quiet = run("-q")
    assert quiet.returncode == 0 and quiet.stderr == ""
    assert "check points:" in quiet.stdout
    report = json.loads((toml.parent / "out" / "report.json").read_text())
    assert any("NOWHERE" in w for w in report["warnings"])
    silent = run("-qq")
    assert silent.returncode == 0 and silent.stderr == "" and silent.stdout == ""


def test_verbose_levels_of_a_block(tmp_path: Path):
    """A block's run: ``-v`` names every strip and every join, ``-vv`` adds
    every control and check point's residual."""
    from strip_aerotri.simulate import simulate_block

    toml = simulate_block(2, 6, preset="film", seed=3).write_project(tmp_path / "b")

    def run(*flags: str) -> str:
        done = subprocess.run(
            [sys.executable, "-c", CLI, *flags, "run", str(toml)],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        return done.stderr

    once, twice = run("-v"), run("-vv")
    assert "strip S1:" in once and "strips S1 / S2:" in once
    assert "dE, dN, dH" not in once
    assert "check " in twice and "dE, dN, dH" in twice
