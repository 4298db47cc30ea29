"""A simulated 2-strip drone block whose second strip lists its photos out of
flight order, for the tests of the photo-order hint and of the run's lines."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from strip_aerotri.cli.main import cli


def shuffled_block(tmp_path: Path) -> Path:
    """Write the block under ``tmp_path / "block"``; its strip.toml."""
    folder = tmp_path / "block"
    made = CliRunner().invoke(
        cli, ["-q", "simulate", "drone", "--strips", "2", "--photos", "8", "--out", str(folder)]
    )
    assert made.exit_code == 0, made.output
    toml = folder / "strip.toml"
    shuffled = ", ".join(f'"S2_0{i}"' for i in (1, 3, 5, 7, 2, 4, 6, 8))
    text = re.sub(
        r"^photos = \[\"S2_.*\]$", f"photos = [{shuffled}]", toml.read_text("utf-8"), flags=re.M
    )
    toml.write_text(text, encoding="utf-8")
    return toml
