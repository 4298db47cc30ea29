"""benchmarks/bench_figures.py runs on a short strip and prints every
figure's time, the total against the floor, the run's wait and the imports
(no timing is asserted: the floor is read from the full run)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).parents[1] / "benchmarks"


def test_bench_figures_prints_each_figure_the_total_and_the_wait(tmp_path: Path) -> None:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    done = subprocess.run(
        [sys.executable, str(BENCH / "bench_figures.py"), "--photos", "24", "--repeats", "1"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
        check=False,
    )
    assert done.returncode in (0, 1), done.stderr  # 1: the floor not met (a loaded machine)
    out = done.stdout
    assert out.startswith("load average before: ")
    for name in ("figure_layout", "figure_residuals", "figure_parallax", "figure_ties"):
        assert re.search(rf"^  {name}\s+[\d.]+ ms", out, re.M), out
    assert re.search(r"^  total\s+[\d.]+ ms   floor 300 ms: (met|NOT met)$", out, re.M), out
    assert re.search(r"the run waits [+-][\d.]+ s for them$", out, re.M), out
    assert re.search(r"^imports: matplotlib Figure \+ Agg [\d.]+ s, pyplot [\d.]+ s", out, re.M)
    assert list(tmp_path.iterdir()) == []  # nothing left behind
