"""strip_aerotri.project imports check and run on first use (PEP 562): the
names stay public, and ``stripaero run`` has neither imported before it forks
its loading child, nor scipy.special at all."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import strip_aerotri.project as project_module
from strip_aerotri.project import check as check_module
from strip_aerotri.project import run as run_module

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "drone-corridor" / "strip.toml"


def test_the_lazy_names_are_their_modules() -> None:
    assert project_module.check_project is check_module.check_project
    assert project_module.CheckReport is check_module.CheckReport
    assert project_module.run_project is run_module.run_project
    assert project_module.project_options is run_module.project_options
    assert {"check_project", "CheckReport", "run_project", "project_options"} <= set(
        dir(project_module)
    )
    assert set(project_module.__all__) <= set(dir(project_module))
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        project_module.no_such_name  # noqa: B018


def _modules_after(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode in (0, 3), out.stderr
    return out.stdout


def test_what_a_run_imports_before_its_fork_leaves_check_and_run() -> None:
    code = (
        "import sys\n"
        "from strip_aerotri.cli import main\n"
        "from strip_aerotri.project import output_folder, load_project, Project\n"
        "from strip_aerotri.cli.loading import loaded\n"
        "print('IMPORTED', [m for m in ('strip_aerotri.project.check',"
        " 'strip_aerotri.project.run') if m in sys.modules])\n"
        "from strip_aerotri.project import run_project, check_project\n"
        "print('THEN', [m for m in ('strip_aerotri.project.check',"
        " 'strip_aerotri.project.run') if m in sys.modules])\n"
    )
    out = _modules_after(code)
    assert "IMPORTED []" in out
    assert "THEN ['strip_aerotri.project.check', 'strip_aerotri.project.run']" in out


def test_a_run_imports_no_scipy_special(tmp_path: Path) -> None:
    """The tolerances' chance without scipy (tests/test_binomial_tail.py)."""
    code = (
        "import atexit, os, sys\n"
        "pid = os.getpid()\n"
        "def said():\n"
        "    if os.getpid() == pid:\n"
        "        print('SCIPY', sorted({m.split('.')[1] for m in sys.modules"
        " if m.startswith('scipy.')} & {'special', 'stats', 'linalg'}))\n"
        "atexit.register(said)\n"
        "from strip_aerotri.cli.main import main\n"
        f"sys.argv = ['stripaero', '-q', 'run', {str(EXAMPLE)!r}, '--out', {str(tmp_path)!r}]\n"
        "main()\n"
    )
    assert "SCIPY ['linalg']\n" in _modules_after(code)
