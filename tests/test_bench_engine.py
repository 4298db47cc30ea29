"""benchmarks/bench_engine.py: one small case runs and its snooping finds
every simulated blunder and nothing else, in few adjustments."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_engine


def test_small_strip_with_blunders() -> None:
    r = bench_engine.run(40, seed=2, blunders=4)
    assert r["blunders"] == 4
    assert r["found"] == 4 and r["other"] == 0
    assert r["rounds"] <= 3  # one or two rejecting rounds and one to confirm
    assert 0.8 < r["sigma0"] < 1.2
    assert r["cpu"] > 0.0 and r["observations"] > 40 * 80


def test_command_line_prints_the_table(capsys) -> None:  # type: ignore[no-untyped-def]
    bench_engine.main(["--photos", "20", "30"])
    out = capsys.readouterr().out
    assert "log-log slope of CPU time against photos" in out
    assert out.count("\n") >= 5
