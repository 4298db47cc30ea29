"""The package's public surface: every name importable, typed, and light to import."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import strip_aerotri


def _type_checking_imports() -> dict[str, str]:
    """Name -> module (".x.y") of the imports under ``if TYPE_CHECKING:`` in
    the package's __init__.py: what editors and type checkers see."""
    tree = ast.parse(Path(strip_aerotri.__file__).read_text(encoding="utf-8"))
    (block,) = [
        n for n in tree.body if isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test)
    ]
    return {
        alias.name: "." * node.level + (node.module or "")
        for node in block.body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    }


def test_every_public_name_is_seen_by_type_checkers_and_imported_on_use():
    """The names are imported under TYPE_CHECKING (editors and type checkers
    see them), and at run time from the same module on first use (PEP 562):
    the same object as the module's own."""
    seen = _type_checking_imports()
    lazy = {name: module for module, names in strip_aerotri._MODULES.items() for name in names}
    assert seen == lazy
    assert sorted(strip_aerotri.__all__) == sorted([*lazy, "__version__"])
    assert len(set(strip_aerotri.__all__)) == len(strip_aerotri.__all__)
    for name, module in lazy.items():
        own = getattr(importlib.import_module(module, "strip_aerotri"), name)
        assert getattr(strip_aerotri, name) is own, name
    assert set(strip_aerotri.__all__) <= set(dir(strip_aerotri))


def test_import_of_the_package_loads_only_what_is_used():
    """``import strip_aerotri`` loads no module of the package until a name
    is used, and then that name's modules; a subpackage is reached by its
    name as before (strip_aerotri.report); an unknown name is an AttributeError."""
    code = (
        "import sys, strip_aerotri as sa\n"
        "before = sorted(m for m in sys.modules if m.startswith('strip_aerotri.'))\n"
        "numpy = 'numpy' in sys.modules\n"
        "sa.critical_value\n"
        "after = sorted(m for m in sys.modules if m.startswith('strip_aerotri.'))\n"
        "print(before, numpy, 'strip_aerotri.blunders' in after,\n"
        "      'strip_aerotri.simulate' in after)\n"
        "print(sa.report.__name__, hasattr(sa, 'no_such_name'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == [
        "['strip_aerotri._version'] False True False",
        "strip_aerotri.report False",
    ]


def test_import_loads_neither_scipy_nor_pyproj_nor_matplotlib():
    """The command line starts without them; the heavy libraries load when used."""
    code = (
        "import sys, strip_aerotri, strip_aerotri.cli.main; "
        "print(','.join(m for m in ('scipy', 'pyproj', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_version_is_the_packages():
    from importlib.metadata import version

    assert strip_aerotri.__version__ == version("strip_aerotri")
