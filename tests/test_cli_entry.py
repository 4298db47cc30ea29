"""A Ctrl-C while ``stripaero`` imports the command line (cli/entry.py): exit
code 130 and one line on stderr, no traceback.

The interrupt is made deterministic: the child process adds an import hook
that sends itself SIGINT when a given module is about to be imported, and
then starts the command as its console script does (the entry point that
pyproject.toml declares) or as ``python -m strip_aerotri`` does.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

from strip_aerotri.cli.entry import INTERRUPTED_STARTING

ROOT = Path(__file__).resolve().parents[1]

_HOOK = """\
import importlib.abc, os, signal, sys

class InterruptAt(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, InterruptAt())
sys.argv = ["stripaero", "--version"]
"""

_SCRIPT = """\
from importlib.metadata import EntryPoint
script = EntryPoint(name="stripaero", value={value!r}, group="console_scripts")
sys.exit(script.load()())
"""

_MODULE = """\
import runpy
runpy.run_module("strip_aerotri", run_name="__main__", alter_sys=True)
"""


def _declared_entry_point() -> str:
    with (ROOT / "pyproject.toml").open("rb") as f:
        value: str = tomllib.load(f)["project"]["scripts"]["stripaero"]
    return value


def _started(module: str, launcher: str) -> subprocess.CompletedProcess[str]:
    start = _SCRIPT.format(value=_declared_entry_point()) if launcher == "script" else _MODULE
    code = textwrap.dedent(_HOOK.format(module=module)) + start
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("launcher", ["script", "module"])
@pytest.mark.parametrize("module", ["click", "numpy", "strip_aerotri.cli.run"])
def test_ctrl_c_while_importing_exits_130_with_one_line(module: str, launcher: str):
    """SIGINT as click, numpy or a command's module is imported (each in the
    first 0.15 s of every command): exit 130, the one line, no traceback."""
    done = _started(module, launcher)
    assert done.returncode == 130, done.stderr
    assert done.stderr == INTERRUPTED_STARTING + "\n"
    assert done.stdout == ""


@pytest.mark.parametrize("launcher", ["script", "module"])
def test_without_an_interrupt_the_command_runs(launcher: str):
    """The same start, the hook never firing: ``stripaero --version``."""
    done = _started("no.such.module", launcher)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("stripaero, version ")
    assert done.stderr == ""
