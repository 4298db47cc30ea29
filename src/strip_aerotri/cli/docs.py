"""``stripaero docs``: the documentation pages shipped with the package.

The pages of the repository's ``docs/`` folder are installed inside the
package as ``strip_aerotri/docs/*.md`` (setup.py); in a source checkout or an
editable install they are read from ``docs/`` beside ``src/``.
"""

from __future__ import annotations

from pathlib import Path

import click

from .options import common_options

__all__ = ["docs", "docs_folder", "page_path"]


def docs_folder() -> Path:
    """The folder of the documentation pages (installed, else the checkout's)."""
    from ..errors import ConfigError

    package = Path(__file__).resolve().parents[1]
    for folder in (package / "docs", package.parents[1] / "docs"):
        if (folder / "cli.md").is_file():
            return folder
    raise ConfigError(
        f"the documentation pages are not installed with this copy of strip_aerotri "
        f"(no docs/ in {package}); reinstall it with pip"
    )


def _topics(folder: Path) -> dict[str, Path]:
    return {p.stem: p for p in sorted(folder.glob("*.md"))}


def page_path(topic: str) -> Path:
    """The page of ``topic`` ("export", "export.md" or "docs/export.md").

    Raises
    ------
    click.BadParameter
        No such page (the message lists the pages).
    """
    pages = _topics(docs_folder())
    name = Path(topic.strip()).name.lower().removesuffix(".md")
    if name not in pages:
        raise click.BadParameter(
            f"no page {topic!r}; the pages are {', '.join(pages)}", param_hint="TOPIC"
        )
    return pages[name]


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return ""


@click.command("docs")
@click.argument("topic", required=False)
@click.option("--path", "show_path", is_flag=True, help="Print the page's file path only.")
@common_options
def docs(topic: str | None, show_path: bool) -> None:
    """Show the documentation installed with the package.

    Without TOPIC, lists the pages and the folder that holds them (Markdown
    files, readable in any editor or browser); with TOPIC, prints the page.

    \b
    Examples:
      stripaero docs                    # the pages and their folder
      stripaero docs project-file       # strip.toml and the CSV files
      stripaero docs export --path      # where export.md is
    """
    if topic is None:
        folder = docs_folder()
        if show_path:
            click.echo(str(folder))
            return
        click.echo(f"Documentation pages in {folder}:")
        pages = _topics(folder)
        width = max(map(len, pages))
        for name, path in pages.items():
            click.echo(f"  {name:<{width}}  {_title(path)}")
        click.echo("Show one with: stripaero docs TOPIC")
        return
    path = page_path(topic)
    click.echo(str(path) if show_path else path.read_text(encoding="utf-8").rstrip("\n"))
