"""The result folder as a user meets it (subprocesses): a file the run did not
write survives it, exports are kept and named, an unwritable folder is
refused before adjusting, Ctrl-C exits 130 with one line saying which
result the folder holds, and two runs into one folder do not both write."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.report.files import RESULT_MARKER
from strip_aerotri.report.lock import lock_path
from strip_aerotri.simulate import simulate_strip

CLI = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], capture_output=True, text=True, timeout=300
    )


def _start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", CLI, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_strip(14, seed=3).write_project(tmp_path_factory.mktemp("p") / "p")


@pytest.fixture(scope="module")
def slow_project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A project whose run lasts seconds: time for a second run (or a Ctrl-C)
    to arrive while the first one holds its folder, even on a busy machine."""
    return simulate_strip(40, seed=3).write_project(tmp_path_factory.mktemp("slow") / "p")


def _fresh(project: Path, tmp_path: Path) -> Path:
    """A copy of the project with no result folder yet."""
    folder = tmp_path / "proj"
    folder.mkdir()
    for item in project.parent.iterdir():
        if item.is_file():
            (folder / item.name).write_bytes(item.read_bytes())
    return folder / project.name


def test_a_foreign_file_and_an_export_survive_the_next_run(project: Path, tmp_path: Path):
    """notes.txt (the user's) and results.geojson (stripaero export) are kept by
    the next run; the export is named as the previous result's (today both
    are deleted silently)."""
    toml = _fresh(project, tmp_path)
    assert _cli("run", str(toml)).returncode == 0
    out = toml.parent / "out"
    (out / "notes.txt").write_text("field notes\n")
    (out / "mine").mkdir()
    (out / "mine" / "sketch.txt").write_text("x\n")
    exported = _cli("export", "geojson", str(toml))
    assert exported.returncode == 0, exported.stderr
    again = _cli("run", str(toml))
    assert again.returncode == 0, again.stderr
    assert (out / "notes.txt").read_text() == "field notes\n"
    assert (out / "mine" / "sketch.txt").read_text() == "x\n"
    assert (out / "results.geojson").is_file()
    assert "results.geojson kept, but exported from the previous result" in again.stderr
    assert "notes.txt" not in again.stderr  # a user's file is kept without a word
    # a third run still keeps them, and a file of the run is still replaced
    (out / "points.csv").write_text("stale\n")
    assert _cli("run", str(toml)).returncode == 0
    assert (out / "notes.txt").is_file() and (out / "points.csv").read_text() != "stale\n"


def test_a_result_of_an_older_version_keeps_its_foreign_files(project: Path, tmp_path: Path):
    """A marker that lists nothing (older versions): the files those runs wrote
    are replaced, anything else kept."""
    toml = _fresh(project, tmp_path)
    out = toml.parent / "out"
    out.mkdir()
    (out / RESULT_MARKER).write_text("This folder holds results of stripaero.\n")
    (out / "points.csv").write_text("old\n")
    (out / "notes.txt").write_text("keep me\n")
    assert _cli("run", str(toml)).returncode == 0
    assert (out / "notes.txt").read_text() == "keep me\n"
    assert (out / "points.csv").read_text() != "old\n"


_READ_ONLY = Path("/sys/stripaero-test/out")


def _unwritable() -> bool:
    """/sys exists and not even root may make a folder in it (Linux)."""
    try:
        _READ_ONLY.parent.mkdir()
    except OSError:
        return Path("/sys").is_dir()
    _READ_ONLY.parent.rmdir()
    return False


@pytest.mark.skipif(not _unwritable(), reason="needs a folder no one may write into (/sys)")
def test_an_unwritable_out_fails_before_adjusting_and_check_says_so(project: Path):
    """--out under a folder that cannot be written: one line naming the folder,
    before any stage ran (-v shows the stages' lines otherwise); check fails
    with the same line. Today the run adjusts, then fails at the end."""
    run = _cli("-v", "run", str(project), "--out", str(_READ_ONLY))
    assert run.returncode == 1
    errors = [x for x in run.stderr.splitlines() if x.startswith("stripaero: error:")]
    assert len(errors) == 1 and str(_READ_ONLY) in errors[0] and "cannot be written" in errors[0]
    assert "relative orientation" not in run.stderr and "writing the report" not in run.stderr
    check = _cli("check", str(project), "--out", str(_READ_ONLY))
    assert check.returncode == 1 and "cannot be written" in check.stderr


def test_an_export_error_names_the_target_not_a_temporary(project: Path, tmp_path: Path):
    toml = _fresh(project, tmp_path)
    assert _cli("run", str(toml)).returncode == 0
    target = tmp_path / "a-file" / "results.geojson"
    (tmp_path / "a-file").write_text("a file, not a folder\n")
    export = _cli("export", "geojson", str(toml), "-o", str(target))
    assert export.returncode == 1
    assert export.stderr.count("\n") == 1 and str(target) in export.stderr
    assert ".partial" not in export.stderr


def _wait_for(path: Path, proc: subprocess.Popen[str], timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "the run never took its lock"
        time.sleep(0.005)


def test_ctrl_c_exits_130_with_one_line_naming_the_previous_result(
    slow_project: Path, tmp_path: Path
):
    """SIGINT while adjusting: exit 130, one line on stderr saying the folder
    holds the previous result, which is byte for byte what it was; the lock
    is released. Today: exit 1 and "\\nAborted!"."""
    toml = _fresh(slow_project, tmp_path)
    assert _cli("run", str(toml)).returncode == 0
    out = toml.parent / "out"
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    proc = _start("run", str(toml))
    _wait_for(lock_path(out), proc)
    proc.send_signal(signal.SIGINT)
    _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stderr.count("\n") == 1, stderr
    assert stderr.startswith("stripaero: error: interrupted; ")
    assert "holds the previous result, unchanged" in stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert not lock_path(out).exists()
    assert not [p for p in out.parent.iterdir() if ".tmp-" in p.name or ".old-" in p.name]


def test_ctrl_c_after_the_new_result_is_in_place_says_so(
    project: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Ctrl-C in the last moment (after the swap, while printing the summary):
    exit 130, and the line says the folder holds the new result."""
    from strip_aerotri.cli import run as run_module
    from strip_aerotri.cli.main import cli

    def interrupted(*args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "_echo_strip", interrupted)
    toml = _fresh(project, tmp_path)
    result = CliRunner().invoke(cli, ["run", str(toml)])
    assert result.exit_code == 130
    assert "holds the new result" in result.output
    assert (toml.parent / "out" / "report.json").is_file()


def test_a_second_run_into_a_folder_being_written_is_refused(slow_project: Path, tmp_path: Path):
    """Two runs into one folder at once: one succeeds, the other is refused in
    one line naming the lock file; the lock is gone afterwards. Today both
    report success and the last one wins."""
    toml = _fresh(slow_project, tmp_path)
    out = toml.parent / "out"
    first = _start("run", str(toml))
    _wait_for(lock_path(out), first)
    second = _cli("run", str(toml))
    _stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert second.returncode == 1
    assert second.stderr.count("\n") == 1
    assert "being written by another stripaero run" in second.stderr
    assert str(lock_path(out)) in second.stderr
    assert not lock_path(out).exists()
    assert (out / "report.json").is_file()


def test_a_stale_lock_is_taken_over_and_a_live_one_refuses(project: Path, tmp_path: Path):
    """A lock whose process is gone (killed run) does not block the next run;
    one held by a live process does."""
    toml = _fresh(project, tmp_path)
    lock = lock_path(toml.parent / "out")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = socket.gethostname()
    lock.write_text(f"{dead.pid} {host} 2026-01-01T00:00:00+00:00\n")
    run = _cli("run", str(toml))
    assert run.returncode == 0, run.stderr
    assert not lock.exists()
    lock.write_text(f"{os.getpid()} {host} 2026-01-01T00:00:00+00:00\n")
    refused = _cli("run", str(toml))
    assert refused.returncode == 1 and f"process {os.getpid()}" in refused.stderr
    assert lock.exists()  # another's lock is never removed
