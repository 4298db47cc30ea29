"""``python -m strip_aerotri``: the ``stripaero`` command."""

from __future__ import annotations

from .cli.main import cli

if __name__ == "__main__":
    cli(prog_name="stripaero")
