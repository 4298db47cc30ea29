"""The report's second process (report/aside.py): the same value as in
process, errors reported here, Ctrl-C ending both, no stray process."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.report.aside import FORK_ENV, Standby, aside, fork_allowed

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux only")

PARENT = os.getpid()


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, dead but not reaped, counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def _started(tmp_path: Path, source: str, note: Path) -> tuple[subprocess.Popen[bytes], int]:
    """Run ``source`` as a script in its own process group (as a terminal's
    job) and wait until its child has written its pid to ``note``."""
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(source))
    proc = subprocess.Popen(
        [sys.executable, str(script), str(note)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while not (note.exists() and note.read_text()) and time.monotonic() < deadline:
        time.sleep(0.02)
    return proc, int(note.read_text())


def _where() -> tuple[int, np.ndarray]:
    return os.getpid(), np.arange(100_000, dtype=np.float64) ** 0.5


def test_the_value_comes_from_a_child_and_equals_the_value_here(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    assert fork_allowed()
    with aside(_where) as pending:
        pid, values = pending.result()
    assert pid != PARENT  # drawn in a second process
    assert np.array_equal(values, _where()[1])
    assert pending.result()[0] == pid  # asked again: the same value, no second call


def test_no_fork_when_disabled_or_other_threads_run(monkeypatch):
    monkeypatch.setenv(FORK_ENV, "0")
    with aside(_where) as pending:
        assert pending.result()[0] == PARENT
    monkeypatch.delenv(FORK_ENV)
    stop = threading.Event()
    worker = threading.Thread(target=stop.wait)
    worker.start()
    try:
        assert not fork_allowed()
        with aside(_where) as pending:
            assert pending.result()[0] == PARENT
    finally:
        stop.set()
        worker.join()


def _fails() -> int:
    raise ValueError("figure 2: no axes")


def test_an_error_in_the_child_is_raised_here():
    with aside(_fails) as pending, pytest.raises(ValueError, match="figure 2: no axes"):
        pending.result()


def _fails_in_the_child_only() -> int:
    if os.getpid() != PARENT:
        raise MemoryError
    return 7


def _killed_in_the_child() -> int:
    if os.getpid() != PARENT:
        os.kill(os.getpid(), signal.SIGKILL)
    return 8


def test_a_child_that_fails_or_dies_is_replaced_by_the_call_here():
    with aside(_fails_in_the_child_only) as pending:
        assert pending.result() == 7
    with aside(_killed_in_the_child) as pending:
        assert pending.result() == 8


def _sleeps_and_names_itself(path: str) -> int:
    Path(path).write_text(str(os.getpid()))
    time.sleep(60)
    return 0


def test_leaving_the_block_kills_and_reaps_the_child(tmp_path):
    note = tmp_path / "pid"
    started = time.monotonic()
    with pytest.raises(RuntimeError), aside(lambda: _sleeps_and_names_itself(str(note))):
        while not note.exists() or not note.read_text():
            time.sleep(0.01)
        raise RuntimeError("the run failed")
    assert time.monotonic() - started < 10
    assert not _alive(int(note.read_text()))


_SCRIPT = """
import os, sys, time
from pathlib import Path
from strip_aerotri.report.aside import aside

def work():
    Path(sys.argv[1]).write_text(str(os.getpid()))
    time.sleep(60)
    return 1

print("before the fork", end="")  # buffered: written once, by the parent
with aside(work) as pending:
    pending.result()
"""


def test_ctrl_c_stops_both_processes_at_once(tmp_path):
    note = tmp_path / "pid"
    proc, child = _started(tmp_path, _SCRIPT, note)
    sent = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C sends: the whole group
    out, err = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 1.0
    assert proc.returncode != 0 and b"KeyboardInterrupt" in err
    assert out == b"before the fork"
    assert not _alive(child)


def test_sigint_to_the_parent_alone_ends_the_child_too(tmp_path):
    note = tmp_path / "pid"
    proc, child = _started(tmp_path, _SCRIPT, note)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 5
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not _alive(child)


def test_the_page_drawn_aside_equals_the_page_drawn_here(monkeypatch):
    """report.html and every other file of a run, byte for byte, with the
    figures drawn in a second process and in this one."""
    from strip_aerotri import simulate_strip, triangulate
    from strip_aerotri.report.outputs import build_outputs

    sim = simulate_strip(9, preset="drone", seed=3)
    result = triangulate(sim.observations, sim.control, sim.crs)
    monkeypatch.delenv(FORK_ENV, raising=False)
    forked = build_outputs(result)
    monkeypatch.setenv(FORK_ENV, "0")
    here = build_outputs(result)
    assert forked.keys() == here.keys()
    stamp = re.compile(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")
    for name in here:
        assert stamp.sub(b"", forked[name]) == stamp.sub(b"", here[name]), name
    assert forked["report.html"].count(b"data:image/png;base64,") == 4


def _prepare() -> None:
    os.environ["STRIPAERO_TEST_PREPARED"] = str(os.getpid())


def _job(scale: float, values: np.ndarray) -> tuple[int, str | None, np.ndarray]:
    return os.getpid(), os.environ.get("STRIPAERO_TEST_PREPARED"), scale * values


def test_a_standby_prepares_then_does_the_job_sent_to_it(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    values = np.linspace(0.0, 1.0, 50_001)
    with Standby(_prepare) as standby:
        with standby.submit(_job, 2.0, values) as pending:
            pid, prepared, doubled = pending.result()
    assert pid != PARENT and prepared == str(pid)  # prepared in the child that did the job
    assert "STRIPAERO_TEST_PREPARED" not in os.environ
    assert np.array_equal(doubled, 2.0 * values)


def test_a_standby_without_fork_or_with_a_job_that_does_not_pickle_calls_here(monkeypatch):
    monkeypatch.setenv(FORK_ENV, "0")
    with Standby(_prepare) as standby, standby.submit(_job, 1.0, np.ones(3)) as pending:
        assert pending.result()[0] == PARENT
    monkeypatch.delenv(FORK_ENV)
    with Standby(_prepare) as standby:
        local = lambda: PARENT  # noqa: E731  # a lambda does not pickle
        with standby.submit(local) as pending:
            assert pending.result() == PARENT


def _first() -> tuple[int, np.ndarray]:
    return os.getpid(), np.arange(300_000, dtype=np.float64)  # 2.4 MB: more than a pipe holds


def _prepare_with(first: tuple[int, np.ndarray]) -> None:
    os.environ["STRIPAERO_TEST_PREPARED"] = f"{first[0]}:{first[1].size}"


def _first_fails_in_the_child_only() -> tuple[int, np.ndarray]:
    if os.getpid() != PARENT:
        raise ValueError("in the child")
    return PARENT, np.zeros(2)


def test_a_standby_sends_first_s_value_then_prepares_with_it_then_does_the_job(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    values = np.linspace(0.0, 1.0, 11)
    with Standby(_prepare_with, first=_first) as standby:
        pid, first = standby.first_result()  # type: ignore[misc]
        assert standby.first_result()[1] is first  # type: ignore[index]  # read once
        with standby.submit(_job, 3.0, values) as pending:
            job_pid, prepared, tripled = pending.result()
    assert pid != PARENT and job_pid == pid  # the same child, first then the job
    assert prepared == f"{pid}:300000"  # prepared with first's value
    assert np.array_equal(first, np.arange(300_000, dtype=np.float64))
    assert np.array_equal(tripled, 3.0 * values)
    assert "STRIPAERO_TEST_PREPARED" not in os.environ


def test_a_standby_s_first_failing_in_the_child_or_without_fork_is_called_here(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    with Standby(_prepare_with, first=_first_fails_in_the_child_only) as standby:
        assert standby.first_result()[0] == PARENT  # type: ignore[index]
        with standby.submit(_job, 1.0, np.ones(2)) as pending:
            assert pending.result()[0] not in (PARENT, None)  # the child still does the job
    monkeypatch.setenv(FORK_ENV, "0")
    with Standby(_prepare_with, first=_first) as standby:
        assert standby.first_result()[0] == PARENT  # type: ignore[index]
    with Standby(_prepare) as standby, pytest.raises(ValueError, match="without a first"):
        standby.first_result()


def _names_itself(path: str) -> None:
    Path(path).write_text(str(os.getpid()))


def test_a_standby_given_no_job_is_killed_and_reaped(tmp_path):
    note = tmp_path / "pid"
    with Standby(partial(_names_itself, str(note))):
        deadline = time.monotonic() + 30
        while not (note.exists() and note.read_text()) and time.monotonic() < deadline:
            time.sleep(0.01)
    assert not _alive(int(note.read_text()))


_STANDBY_SCRIPT = """
import os, sys, time
from functools import partial
from pathlib import Path
from strip_aerotri.report.aside import Standby

def prepare():
    Path(sys.argv[1]).write_text(str(os.getpid()))

with Standby(prepare):
    time.sleep(60)  # the adjustment
"""


@pytest.mark.parametrize("whom", ["group", "parent"])
def test_ctrl_c_during_the_adjustment_ends_the_standby_too(tmp_path, whom):
    note = tmp_path / "pid"
    proc, child = _started(tmp_path, _STANDBY_SCRIPT, note)
    sent = time.monotonic()
    if whom == "group":
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 1.0
    assert b"KeyboardInterrupt" in err
    deadline = time.monotonic() + 5
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not _alive(child)


def test_stripaero_run_writes_the_same_folder_with_and_without_its_second_process(
    tmp_path, monkeypatch
):
    from click.testing import CliRunner

    from strip_aerotri import simulate_strip
    from strip_aerotri.cli.main import cli

    toml = simulate_strip(12, preset="drone", seed=4).write_project(tmp_path / "p")
    folders = {}
    for fork in ("1", "0"):
        monkeypatch.setenv(FORK_ENV, fork)
        out = tmp_path / f"out-{fork}"
        done = CliRunner().invoke(cli, ["-q", "run", str(toml), "--out", str(out)])
        assert done.exit_code == 0, done.output
        folders[fork] = out
    names = sorted(p.name for p in folders["1"].iterdir())
    assert names == sorted(p.name for p in folders["0"].iterdir())
    assert "report.html" in names
    stamp = re.compile(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")
    import json

    stages = json.loads((folders["1"] / "report.json").read_text())["timings_s"]
    assert stages
    # the stages' seconds: in report.json and in the page's table of timings
    words = b"|".join(re.escape(k.encode()) for k in stages)
    timing = re.compile(
        rb'("timings_s": \{[^}]*\})|(<td class=.l.>(' + words + rb")</td><td>[\d.]+)"
    )
    for name in names:
        a, b = ((folders[f] / name).read_bytes() for f in ("1", "0"))
        if name == ".stripaero-result":
            continue
        assert timing.sub(b"", stamp.sub(b"", a)) == timing.sub(b"", stamp.sub(b"", b)), name


_AT_FORK_SCRIPT = """
import os, signal, sys, time
from strip_aerotri.report.aside import Standby

def ctrl_c_inside_the_fork():
    os.register_at_fork(after_in_parent=lambda: os.kill(os.getpid(), signal.SIGINT))

ctrl_c_inside_the_fork()
try:
    with Standby(lambda: time.sleep(60)) as standby:
        time.sleep(5)  # the adjustment: must not be reached
        print("went on")
except KeyboardInterrupt:
    print("interrupted")
"""


def test_a_ctrl_c_during_the_fork_is_not_lost(tmp_path):
    """A SIGINT that lands in Python's at-fork hooks is raised after the
    fork, not printed as "Exception ignored" and dropped."""
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(_AT_FORK_SCRIPT))
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.stdout.strip() == "interrupted", (done.stdout, done.stderr)
    assert "Exception ignored" not in done.stderr


_MODULES_SCRIPT = """
import sys
from strip_aerotri.cli.main import cli
try:
    cli(["-q", "run", sys.argv[1], "--out", sys.argv[2]])
except SystemExit as exc:
    assert not exc.code, exc.code
print(*(name in sys.modules for name in ("matplotlib", "scipy.stats")))
"""


@pytest.mark.parametrize(("fork", "matplotlib_here"), [("1", False), ("0", True)])
def test_the_run_itself_imports_neither_matplotlib_nor_scipy_stats(
    tmp_path, monkeypatch, fork, matplotlib_here
):
    """matplotlib is loaded by the drawing process only (in the run's own
    process with STRIPAERO_FORK=0), scipy.stats by neither."""
    from strip_aerotri import simulate_strip

    toml = simulate_strip(10, preset="drone", seed=6).write_project(tmp_path / "p")
    script = tmp_path / "modules.py"
    script.write_text(textwrap.dedent(_MODULES_SCRIPT))
    env = {**os.environ, FORK_ENV: fork}
    done = subprocess.run(
        [sys.executable, str(script), str(toml), str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-2:] == [str(matplotlib_here), "False"]
    assert (tmp_path / "out" / "report.html").read_text().count("data:image/png") == 4


def test_the_figures_are_drawn_half_in_a_second_process(monkeypatch):
    """draw_figures hands the parallaxes and the ties to a forked process
    (one figure each, their drawer's pid here) and draws them itself when
    forking is off; the page is the same (the test above)."""
    import strip_aerotri.report.html as html
    from strip_aerotri import simulate_strip, triangulate
    from strip_aerotri.report.figures import figure_data
    from strip_aerotri.report.record import model_records

    sim = simulate_strip(9, preset="drone", seed=3)
    result = triangulate(sim.observations, sim.control, sim.crs)
    data = figure_data(result, model_records(result))
    for name in ("figure_layout", "figure_residuals", "figure_parallax", "figure_ties"):
        monkeypatch.setattr(html, name, lambda _data: str(os.getpid()))
    monkeypatch.delenv(FORK_ENV, raising=False)
    drawn = html.draw_figures(data)
    assert drawn.layout == drawn.residuals == str(os.getpid())
    assert drawn.parallax == drawn.ties != str(os.getpid())
    monkeypatch.setenv(FORK_ENV, "0")
    here = html.draw_figures(data)
    assert {here.layout, here.residuals, here.parallax, here.ties} == {str(os.getpid())}
