"""``stripaero run`` loads its project in a forked child while it imports
(cli/loading.py): the same project, the same warnings and the same error
line as loading it here."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import strip_aerotri.project as project_module
from strip_aerotri.cli import loading
from strip_aerotri.cli.main import cli
from strip_aerotri.errors import ConfigError, StripAerotriWarning
from strip_aerotri.report.aside import FORK_ENV

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux only")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "film-strip" / "strip.toml"
PARENT = os.getpid()


def _same(a: object, b: object) -> None:
    """``a`` and ``b`` equal field by field (arrays by value, dtype and
    writeability)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b)
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name))
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape
        assert a.flags.writeable == b.flags.writeable
        np.testing.assert_array_equal(a, b)
    elif isinstance(a, tuple | list) and a and not isinstance(a[0], str | int | float):
        assert len(a) == len(b)  # type: ignore[arg-type]
        for x, y in zip(a, b, strict=True):  # type: ignore[call-overload]
            _same(x, y)
    else:
        assert a == b


@pytest.mark.parametrize("fork", ["1", "0"])
def test_the_project_loaded_aside_equals_the_project_loaded_here(monkeypatch, fork):
    monkeypatch.setenv(FORK_ENV, fork)
    caught: list[warnings.WarningMessage] = []
    with loading.loaded(EXAMPLE, caught) as (project, standby):
        _same(project, project_module.load_project(EXAMPLE))
        assert standby is not None  # a strip: the child waits to draw
    assert caught == []
    for name in (*loading.BEFORE_FORK, *loading.RUN_MODULES):
        assert name in sys.modules


@dataclasses.dataclass(frozen=True)
class _Stand:
    """A stand-in project: a block, so that the child prepares no drawing."""

    text: str
    is_block: bool = True


def _loaded_value(path: Path, caught: list[warnings.WarningMessage]) -> str:
    with loading.loaded(path, caught) as (project, standby):
        assert standby is None  # a block: nothing to draw, the child is ended
        return project.text  # type: ignore[attr-defined]


def _warns_in_the_child(path: Path) -> _Stand:
    where = "child" if os.getpid() != PARENT else "here"
    warnings.warn(f"{path.name}: a note from {where}", StripAerotriWarning, stacklevel=2)
    return _Stand(where)


def test_the_warnings_of_the_loading_come_back_from_the_child(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    monkeypatch.setattr(project_module, "load_project", _warns_in_the_child)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        where = _loaded_value(Path("strip.toml"), caught)
    assert where == "child"
    assert [str(w.message) for w in caught] == ["strip.toml: a note from child"]
    assert caught[0].category is StripAerotriWarning


def _fails_in_the_child_only(path: Path) -> _Stand:
    if os.getpid() != PARENT:
        raise ConfigError(f"{path}:3: the child's own message")
    return _Stand("loaded here")


def test_a_failed_child_is_replaced_by_loading_here(monkeypatch):
    monkeypatch.delenv(FORK_ENV, raising=False)
    monkeypatch.setattr(project_module, "load_project", _fails_in_the_child_only)
    assert _loaded_value(Path("strip.toml"), []) == "loaded here"


def test_a_bad_project_reads_as_loaded_here(tmp_path, monkeypatch):
    bad = tmp_path / "strip.toml"
    images = tmp_path / "image_points.csv"
    for name in ("strip.toml", "control.csv", "image_points.csv"):
        (tmp_path / name).write_bytes((EXAMPLE.parent / name).read_bytes())
    lines = images.read_text(encoding="utf-8").splitlines()
    lines[5] = lines[5].rsplit(",", 1)[0] + ",12,5"  # a decimal comma: one field too many
    images.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError) as here:
        project_module.load_project(bad)
    assert "image_points.csv:6:" in str(here.value)
    monkeypatch.delenv(FORK_ENV, raising=False)
    with pytest.raises(ConfigError) as aside_error:
        with loading.loaded(bad, []):
            pass
    assert str(aside_error.value) == str(here.value)
    result = CliRunner().invoke(cli, ["run", str(bad), "--out", str(tmp_path / "out")])
    assert result.exit_code != 0
    assert str(here.value) in result.output
    assert "Traceback" not in result.output


def test_a_run_of_a_strip_imports_neither_matplotlib_nor_scipy_sparse(tmp_path):
    """The run's own process: matplotlib is the drawing child's, scipy.sparse
    only for a pair of photos without common points (plausibility)."""
    code = (
        "import atexit, os, sys\n"
        "pid = os.getpid()\n"
        "def said():\n"
        "    if os.getpid() == pid:\n"
        "        names = ('matplotlib', 'scipy.sparse', 'scipy.linalg')\n"
        "        print('MODULES', ','.join(m for m in names if m in sys.modules))\n"
        "atexit.register(said)\n"
        "from strip_aerotri.cli.main import main\n"
        f"sys.argv = ['stripaero', '-q', 'run', {str(EXAMPLE)!r}, '--out', {str(tmp_path)!r}]\n"
        "main()\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode in (0, 3), out.stderr
    # scipy 1.10 (the minimum version) imports scipy.sparse with scipy.linalg itself
    baseline = subprocess.run(
        [sys.executable, "-c", "import sys, scipy.linalg; print('scipy.sparse' in sys.modules)"],
        capture_output=True, text=True, check=True,
    )
    by_linalg = "scipy.sparse," if baseline.stdout.strip() == "True" else ""
    assert f"MODULES {by_linalg}scipy.linalg\n" in out.stdout
    assert (tmp_path / "report.html").read_text(encoding="utf-8").count("data:image/png") >= 4


def test_the_modules_imported_meanwhile_are_those_a_run_imports_anyway(tmp_path):
    """RUN_MODULES cost nothing a run would not spend: adjusting the film strip
    and building its outputs, without the CLI, imports every one of them."""
    code = (
        "import sys, warnings\n"
        "from strip_aerotri import load_project\n"
        "from strip_aerotri.project.run import run_project\n"
        "from strip_aerotri.report.summary import build_run\n"
        "warnings.simplefilter('ignore')\n"
        f"project = load_project({str(EXAMPLE)!r})\n"
        "build_run(run_project(project), project=project, map_scale=None)\n"
        "from strip_aerotri.cli.loading import BEFORE_FORK, RUN_MODULES\n"
        "print('MISSING', [m for m in (*BEFORE_FORK, *RUN_MODULES) if m not in sys.modules])\n"
    )
    env = dict(os.environ, STRIPAERO_FORK="0")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "MISSING []" in out.stdout


def test_a_real_loading_warning_comes_back_from_the_child(tmp_path, monkeypatch):
    """A GNSS file with a photo the strip does not list: the warning of
    project/tables.py, given in the child, is the caller's as it would be here."""
    import shutil

    folder = tmp_path / "proj"
    shutil.copytree(Path(__file__).parent / "data" / "minimal", folder)
    with (folder / "strip.toml").open("a", encoding="utf-8") as f:
        f.write('\n[adjustment]\nrefine = "bundle"\n\n[gnss]\nfile = "gnss.csv"\n')
    (folder / "gnss.csv").write_text(
        "photo,X,Y,Z\n1201,0.0,0.0,1223.0\n1202,600.0,1.5,1224.25\n"
        "1203,1200.0,-2.0,1222.5\n9001,5.0,5.0,1200.0\n",
        encoding="utf-8",
    )
    toml = folder / "strip.toml"
    with warnings.catch_warnings(record=True) as here:
        warnings.simplefilter("always", StripAerotriWarning)
        project_module.load_project(toml)
    assert [str(w.message) for w in here] == [
        f"{folder / 'gnss.csv'}:5: 1 row(s) of photo(s) not in [strip] photos ignored: '9001'"
    ]
    seen = {}
    for fork in ("1", "0"):
        monkeypatch.setenv(FORK_ENV, fork)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", StripAerotriWarning)
            with loading.loaded(toml, caught) as (project, _):
                assert project.gnss is not None
        seen[fork] = [(str(w.message), w.category, w.filename, w.lineno) for w in caught]
    # as in one process: the message and category of load_project's, the place
    # the one its stacklevel names (load_recorded, which calls it)
    assert seen["1"] == seen["0"]
    assert [item[:2] for item in seen["1"]] == [(str(w.message), w.category) for w in here]
