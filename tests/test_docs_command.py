"""``stripaero docs``: the documentation pages reachable from the command line,
and shipped inside the package (setup.py maps docs/ to strip_aerotri/docs)."""

from __future__ import annotations

import ast
from pathlib import Path

from click.testing import CliRunner

from strip_aerotri.cli.docs import docs_folder
from strip_aerotri.cli.main import cli

ROOT = Path(__file__).parents[1]


def test_every_page_is_listed_and_printed() -> None:
    runner = CliRunner()
    listing = runner.invoke(cli, ["docs"])
    assert listing.exit_code == 0, listing.output
    pages = sorted(p.stem for p in (ROOT / "docs").glob("*.md"))
    assert len(pages) > 10
    for name in pages:
        assert f"  {name} " in listing.output
    page = runner.invoke(cli, ["docs", "export"])
    assert page.output == (ROOT / "docs" / "export.md").read_text(encoding="utf-8")
    path = runner.invoke(cli, ["docs", "docs/Project-File.md", "--path"])
    assert Path(path.output.strip()).read_text() == (ROOT / "docs" / "project-file.md").read_text()


def test_an_unknown_page_names_the_pages() -> None:
    result = CliRunner().invoke(cli, ["docs", "nope"])
    assert result.exit_code == 2
    assert "no page 'nope'" in result.stderr and "project-file" in result.stderr


def test_the_help_points_to_pages_that_exist() -> None:
    """Every page the help names is a page of `stripaero docs`."""
    import re

    text = CliRunner().invoke(cli, ["export", "--help"]).output
    named = re.findall(r"^ +stripaero docs ([a-z-]+) ", text, re.MULTILINE)
    assert named == ["cli", "project-file", "outputs", "troubleshooting"]
    assert all((docs_folder() / f"{n}.md").is_file() for n in named)


def test_setup_ships_the_docs_as_package_data() -> None:
    """setup.py maps the package strip_aerotri.docs to docs/ with its *.md as
    package data (a wheel built from the tree holds strip_aerotri/docs/*.md;
    checked by hand with a non-editable pip install, docs/export.md)."""
    tree = ast.parse((ROOT / "setup.py").read_text(encoding="utf-8"))
    call = next(
        n for n in ast.walk(tree) if isinstance(n, ast.Call) and ast.unparse(n.func) == "setup"
    )
    kw = {k.arg: ast.literal_eval(k.value) for k in call.keywords if k.arg != "packages"}
    assert kw["package_dir"]["strip_aerotri.docs"] == "docs"
    assert kw["package_data"]["strip_aerotri.docs"] == ["*.md"]
    assert kw["package_data"]["strip_aerotri"] == ["py.typed"]
    packages = next(k.value for k in call.keywords if k.arg == "packages")
    assert "'strip_aerotri.docs'" in ast.unparse(packages)
