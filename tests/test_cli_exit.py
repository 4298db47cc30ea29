"""The console script's end (cli.main.main): the exit status of the command,
the exit handlers run and the output flushed, then os._exit without the
interpreter's teardown; the ordinary exit under a tracer or with another
thread still running."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from _cli_process import python_subprocess
from strip_aerotri.cli import main as cli_main


def _main(*args: str, prelude: str = "") -> subprocess.CompletedProcess[str]:
    code = f"import sys; {prelude}sys.argv = ['stripaero', *sys.argv[1:]]; " + (
        "from strip_aerotri.cli.main import main; main()"
    )
    return python_subprocess(code, *args)


def test_statuses_and_messages_are_those_of_the_command(tmp_path: Path) -> None:
    ok = _main("--version")
    assert ok.returncode == 0 and "stripaero, version" in ok.stdout
    missing = _main("check", str(tmp_path / "missing.toml"))
    assert missing.returncode == 1
    assert missing.stderr.startswith("stripaero: error: ") and "missing.toml" in missing.stderr
    usage = _main("--no-such-option")
    assert usage.returncode == 2 and "No such option" in usage.stderr


def test_exit_handlers_run_and_the_output_is_complete() -> None:
    """An atexit handler (a coverage tool's) still runs, after the command's
    output; the whole help text arrives through the pipe."""
    prelude = "import atexit; atexit.register(lambda: print('handler ran', file=sys.stderr)); "
    done = _main("docs", prelude=prelude)
    assert done.returncode == 0
    assert done.stderr.strip().endswith("handler ran")
    want = CliRunner().invoke(cli_main.cli, ["docs"]).output
    assert done.stdout == want


def test_the_process_ends_at_once_only_when_it_is_safe(monkeypatch: pytest.MonkeyPatch) -> None:
    """os._exit with the status after the exit handlers when nothing else
    runs; nothing (the ordinary exit follows) under a tracer or while a
    non-daemon thread runs."""
    import atexit

    calls: list[object] = []
    monkeypatch.setattr(os, "_exit", lambda status: calls.append(status))
    monkeypatch.setattr(atexit, "_run_exitfuncs", lambda: calls.append("handlers"))
    monkeypatch.setattr(sys, "gettrace", lambda: None)
    monkeypatch.setattr(sys, "getprofile", lambda: None)
    cli_main._end_now(SystemExit(3))
    cli_main._end_now(SystemExit(None))
    assert calls == ["handlers", 3, "handlers", 0]

    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    try:
        cli_main._end_now(SystemExit(0))
    finally:
        release.set()
        worker.join()
    monkeypatch.setattr(sys, "gettrace", lambda: print)  # a tracer is set
    cli_main._end_now(SystemExit(0))
    assert calls == ["handlers", 3, "handlers", 0]
