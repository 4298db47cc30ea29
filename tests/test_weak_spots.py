"""Weak spots a run must name: a pair with no tie point to its neighbour."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

CLI = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


def _cut_ties(images: Path, k: int) -> tuple[str, str, str]:
    """Remove, on photo k-1, every point also measured on photo k+1: the pairs
    (k-1, k) and (k, k+1) then share no point on all three photos."""
    with images.open(newline="") as f:
        rows = list(csv.DictReader(f))
    photos = sorted({r["photo"] for r in rows})
    before, after = photos[k - 1], photos[k + 1]
    on_after = {r["point"] for r in rows if r["photo"] == after}
    keep = [r for r in rows if not (r["photo"] == before and r["point"] in on_after)]
    with images.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(keep)
    return before, photos[k], after


def test_a_pair_without_ties_to_its_neighbour_warns(tmp_path: Path):
    """Today: "0 tie points, scale ratio 1.00000" under -v and no warning."""
    assert _cli("simulate", "drone", "--out", "d", cwd=tmp_path).returncode == 0
    a, b, c = _cut_ties(tmp_path / "d" / "image_points.csv", 5)
    run = _cli("run", "d/strip.toml", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    warning = next((x for x in run.stderr.splitlines() if "shares no tie point" in x), run.stderr)
    assert warning.startswith("stripaero: warning: ")
    assert f"pair {b}-{c} shares no tie point with pair {a}-{b}" in warning
    assert "comes from the control alone" in warning
    report = (tmp_path / "d" / "out" / "report.json").read_text()
    assert "shares no tie point" in report
