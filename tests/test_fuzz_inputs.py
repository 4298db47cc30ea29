"""The catalogue of input mistakes (``benchmarks/fuzz_inputs.py``), each
applied to the film example and run through ``stripaero check`` and
``stripaero run`` in-process: every answer keeps the rules of its entry
(exit code, one error line naming the culprit, no traceback, inputs
unchanged, the earlier result folder as it was after a failure, a complete
one after a success).  ``python benchmarks/fuzz_inputs.py`` runs the same
catalogue on both examples in fresh interpreters.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import fuzz_inputs  # noqa: E402

FILM = ROOT / "examples" / "film-strip"


def _in_process(args: list[str]) -> fuzz_inputs.Answer:
    result = CliRunner().invoke(cli, args)
    return fuzz_inputs.Answer(result.exit_code, result.stderr)


@pytest.fixture(scope="module")
def earlier(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A result folder of the unmutated example."""
    out = tmp_path_factory.mktemp("earlier") / "out"
    result = CliRunner().invoke(cli, ["-qq", "run", str(FILM / "strip.toml"), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture
def fast_report(monkeypatch: pytest.MonkeyPatch) -> None:
    """No matplotlib figures (most of a successful run's time)."""
    from strip_aerotri.report import outputs

    build = outputs.build_outputs
    monkeypatch.setattr(outputs, "build_outputs", lambda r, **kw: build(r, html=False, **kw))


@pytest.mark.parametrize("mutation", fuzz_inputs.MUTATIONS, ids=lambda m: m.name)
def test_the_answer_to_each_mistake(
    mutation: fuzz_inputs.Mutation, earlier: Path, tmp_path: Path, fast_report: None
) -> None:
    results = fuzz_inputs.fuzz_one(FILM, mutation, tmp_path, _in_process, earlier)
    broken = {c: results[c] for c in ("check", "run") if results[c]}
    assert not broken, (broken, results.get("run said"), results.get("check said"))


def test_the_judge_finds_broken_answers() -> None:
    """The oracle itself: each rule, broken once, is reported."""
    fail = fuzz_inputs.Mutation("x", fuzz_inputs.FAIL, lambda p: None, (("needle",),))
    ok = fuzz_inputs.Mutation("y", fuzz_inputs.OK, lambda p: None)
    before = {"strip.toml": "a", "out": "<dir>", "out/points.csv": "b"}
    good = fuzz_inputs.Answer(1, "stripaero: error: the needle\n")
    assert fuzz_inputs.judge(fail, "run", good, before, before, "out") == []
    cases = {
        "exit 0, expected fail": (fail, fuzz_inputs.Answer(0, ""), before),
        "a traceback": (fail, fuzz_inputs.Answer(1, "Traceback (most recent):\n"), before),
        "2 error lines": (
            fail, fuzz_inputs.Answer(1, "stripaero: error: needle\nstripaero: error: b\n"), before
        ),
        "does not name needle": (fail, fuzz_inputs.Answer(1, "stripaero: error: hay\n"), before),
        "an input file changed": (fail, good, {**before, "strip.toml": "changed"}),
        "the result folder changed": (fail, good, {**before, "out/points.csv": "half"}),
        "stray files": (fail, good, {**before, ".out-tmp": "<dir>"}),
        "an incomplete result": (ok, fuzz_inputs.Answer(0, ""), before),
        "stray stderr lines": (ok, fuzz_inputs.Answer(0, "oops\n"), before),
    }  # fmt: skip
    for rule, (mutation, answer, after) in cases.items():
        broken = fuzz_inputs.judge(mutation, "run", answer, before, after, "out")
        assert any(rule in b for b in broken), (rule, broken)
