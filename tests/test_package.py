"""The package's public surface: every name importable, typed, and light to import."""

from __future__ import annotations

import subprocess
import sys

import strip_aerotri


def test_every_public_name_is_a_real_attribute():
    # explicit imports (no lazy module __getattr__): editors and type checkers see them
    assert not hasattr(strip_aerotri, "__getattr__")
    missing = [name for name in strip_aerotri.__all__ if name not in vars(strip_aerotri)]
    assert missing == []
    assert len(set(strip_aerotri.__all__)) == len(strip_aerotri.__all__)


def test_import_loads_neither_scipy_nor_pyproj_nor_matplotlib():
    """The command line starts on numpy alone; the heavy libraries load when used."""
    code = (
        "import sys, strip_aerotri, strip_aerotri.cli.main; "
        "print(','.join(m for m in ('scipy', 'pyproj', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_version_is_the_packages():
    from importlib.metadata import version

    assert strip_aerotri.__version__ == version("strip_aerotri")
