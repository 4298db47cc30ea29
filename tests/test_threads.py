"""BLAS threads during the adjustments (``strip_aerotri._threads``).

The limit is checked where it matters: inside a stage of a real run, in a
fresh process (threadpoolctl's view of the BLAS libraries numpy and scipy
loaded), not by timing.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from strip_aerotri._threads import BLAS_THREADS_VARIABLE, blas_thread_limit, blas_threads
from strip_aerotri.errors import ConfigError

#: Runs a strip (library call, project run, refinement) and a block in a fresh
#: process; every stage named below records the BLAS threads it runs with.
_PROBE = textwrap.dedent(
    """
    import json, sys, warnings
    import scipy.linalg  # both BLAS libraries loaded before the first reading
    from threadpoolctl import threadpool_info

    import strip_aerotri as sa
    import strip_aerotri.block.strips as block_strips
    import strip_aerotri.bundle.variance as variance
    import strip_aerotri.ground.models as ground_models
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.pipeline import triangulate_block

    seen, phase = {}, [""]

    def blas():
        return sorted({d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"})

    def probe(module, name):
        original = getattr(module, name)

        def recorded(*args, **kwargs):
            seen.setdefault(f"{phase[0]}: {name}", blas())
            return original(*args, **kwargs)

        setattr(module, name, recorded)

    probe(ground_models, "adjust_models_to_ground")
    probe(variance, "refine_frame")  # what the bundle refinement runs
    probe(block_strips, "adjust_block")
    before = blas()
    warnings.simplefilter("ignore")
    strip = sa.simulate_strip(8, preset="drone", seed=2)
    phase[0] = "triangulate"
    sa.triangulate(strip.observations, strip.control, strip.crs, refine="bundle")
    project = sa.load_project(strip.write_project(sys.argv[1]))
    phase[0] = "run_project"
    sa.run_project(project)
    block = sa.simulate_block(2, 6, preset="film", seed=3)
    specs = [StripSpec(s.name, s.photo_ids) for s in block.strips]
    phase[0] = "triangulate_block"
    triangulate_block(block.observations, block.control, block.crs, specs)
    print(json.dumps({"before": before, "after": blas(), "seen": seen}))
    """
)


def _probe(tmp_path: Path, **env: str) -> dict[str, object]:
    environ = {k: v for k, v in os.environ.items() if k != BLAS_THREADS_VARIABLE}
    # two threads before the run, whatever the machine, so that a limit shows
    environ.update(OPENBLAS_NUM_THREADS="2", OMP_NUM_THREADS="2", **env)
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, str(tmp_path / "p")],
        capture_output=True,
        text=True,
        env=environ,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    out: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return out


def test_one_blas_thread_inside_every_stage_of_a_run(tmp_path: Path) -> None:
    out = _probe(tmp_path)
    assert out["before"] == [2]
    assert out["seen"] == {
        "triangulate: adjust_models_to_ground": [1],
        "triangulate: refine_frame": [1],  # the bundle refinement
        "run_project: adjust_models_to_ground": [1],
        "triangulate_block: adjust_block": [1],
    }
    assert out["after"] == [2]  # the caller's setting is restored


def test_the_variable_sets_or_lifts_the_limit(tmp_path: Path) -> None:
    three = _probe(tmp_path, **{BLAS_THREADS_VARIABLE: "3"})
    assert set(map(tuple, three["seen"].values())) == {(3,)}  # type: ignore[attr-defined]
    auto = _probe(tmp_path, **{BLAS_THREADS_VARIABLE: "auto"})
    assert set(map(tuple, auto["seen"].values())) == {(2,)}  # type: ignore[attr-defined]


@pytest.mark.parametrize(("text", "expected"), [("", 1), ("1", 1), (" 4 ", 4), ("AUTO", None)])
def test_limit_read_from_the_environment(
    monkeypatch: pytest.MonkeyPatch, text: str, expected: int | None
) -> None:
    monkeypatch.setenv(BLAS_THREADS_VARIABLE, text)
    assert blas_thread_limit() == expected


@pytest.mark.parametrize("text", ["0", "-2", "two", "1.5"])
def test_a_bad_limit_is_one_line_naming_the_variable(
    monkeypatch: pytest.MonkeyPatch, text: str
) -> None:
    monkeypatch.setenv(BLAS_THREADS_VARIABLE, text)
    with pytest.raises(ConfigError, match=f"^environment variable {BLAS_THREADS_VARIABLE}="):
        blas_thread_limit()


def test_interruptible_returns_and_raises_as_the_call() -> None:
    import numpy as np

    from strip_aerotri._threads import interruptible

    a = np.array([[4.0, 2.0], [2.0, 3.0]])
    np.testing.assert_allclose(interruptible(np.linalg.cholesky, a), np.linalg.cholesky(a))
    assert interruptible(divmod, 7, 2) == (3, 1)
    with pytest.raises(np.linalg.LinAlgError):
        interruptible(np.linalg.cholesky, -a)


#: A main thread waiting on a long call into compiled code that releases the
#: interpreter (a matrix product, as LAPACK's calls do): SIGINT must act while
#: the call still runs, not when it returns.  The worker says "computing" as
#: it starts the product.
_WAIT = textwrap.dedent(
    """
    import sys, threading
    import numpy as np
    from strip_aerotri._threads import interruptible

    a = np.random.default_rng(1).standard_normal((1500, 1500))

    def product():
        print("computing", flush=True)
        for _ in range(20):  # seconds of BLAS calls
            a @ a

    try:
        interruptible(product)
    except KeyboardInterrupt:
        busy = any(t.name == "strip_aerotri-compute" for t in threading.enumerate())
        print("interrupted while computing" if busy else "interrupted after", flush=True)
        sys.exit(130)
    """
)


def test_ctrl_c_acts_during_a_long_compiled_call() -> None:
    import signal

    proc = subprocess.Popen(
        [sys.executable, "-c", _WAIT],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
        # as from a terminal: SIGINT not inherited as ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "computing"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert (proc.returncode, out.strip()) == (130, "interrupted while computing"), err


def test_a_bad_limit_stops_stripaero_run_in_one_line(tmp_path: Path) -> None:
    from strip_aerotri import simulate_strip

    toml = simulate_strip(4, seed=1).write_project(tmp_path / "p")
    environ = {**os.environ, BLAS_THREADS_VARIABLE: "lots"}
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    done = subprocess.run(
        [sys.executable, "-c", code, "run", str(toml)],
        capture_output=True,
        text=True,
        env=environ,
        timeout=300,
        check=False,
    )
    assert done.returncode == 1
    assert done.stderr.strip() == (
        f"stripaero: error: environment variable {BLAS_THREADS_VARIABLE}='lots': expected a "
        "positive number of BLAS threads or 'auto' (unset it for the default, one thread)"
    )
    assert not (toml.parent / "out").exists()


def test_the_callers_limit_comes_back_after_an_error_and_after_nesting(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import scipy.linalg  # noqa: F401  (both BLAS libraries loaded)
    from threadpoolctl import threadpool_info, threadpool_limits

    from strip_aerotri._threads import blas_threads, limit_blas_threads

    def blas() -> set[int]:
        return {d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}

    monkeypatch.delenv(BLAS_THREADS_VARIABLE, raising=False)
    if not blas():
        pytest.skip("no BLAS library that threadpoolctl knows")

    @limit_blas_threads
    def fails() -> None:
        assert blas() == {1}
        raise ConfigError("a stage's error")

    with threadpool_limits(limits=2, user_api="blas"):
        with pytest.raises(ConfigError, match="a stage's error"):
            fails()
        assert blas() == {2}
        with blas_threads(3):
            with blas_threads():
                assert blas() == {1}
            assert blas() == {3}
            with blas_threads(None):
                assert blas() == {3}
        assert blas() == {2}


def _wide_band(n: int, w: int, d: int, positive: bool = True):  # type: ignore[no-untyped-def]
    """A random block band (n, w+1, d, d) of a diagonally dominant symmetric
    matrix (positive definite, or not: one entry beside the diagonal in the
    middle ten times the diagonal)."""
    import numpy as np

    from strip_aerotri.geometry._blockband import lapack_to_band

    rng = np.random.default_rng(3)
    ab = rng.uniform(-1.0, 1.0, size=((w + 1) * d, n * d))
    ab[0] = 2.0 * (w + 1) * d
    if not positive:
        ab[1, n * d // 2] = 10.0 * ab[0, n * d // 2]
    return lapack_to_band(ab, n, d)


def test_a_wide_band_is_factored_through_interruptible(monkeypatch: pytest.MonkeyPatch) -> None:
    """The banded Cholesky of a wide block (seconds at 20 x 500) runs through
    _threads.interruptible, with the same factor as a direct call, and its
    failure still names the row."""
    import numpy as np

    import strip_aerotri.geometry._blockband as blockband
    from strip_aerotri._threads import interruptible

    calls: list[str] = []

    def recorded(function, *args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(function.__name__)
        return interruptible(function, *args, **kwargs)

    monkeypatch.setattr(blockband, "interruptible", recorded)
    band = _wide_band(3000, 9, 6)  # N b^2 = 18 000 x 60^2: above the threshold
    through = blockband.factor_band(band)
    assert calls == ["cholesky_banded"]
    monkeypatch.setattr(blockband, "_LONG_FACTOR", float("inf"))
    direct = blockband.factor_band(band)
    assert calls == ["cholesky_banded"]  # a direct call this time
    np.testing.assert_array_equal(through.factor, direct.factor)
    monkeypatch.setattr(blockband, "_LONG_FACTOR", 0.0)
    with pytest.raises(blockband.NotPositiveDefinite):
        blockband.factor_band(_wide_band(50, 2, 6, positive=False))
    assert calls == ["cholesky_banded", "cholesky_banded"]


def test_a_block_inside_one_of_the_same_limit_changes_nothing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Nested entry points (a run enters eight) set the limit once: the inner
    blocks of the same limit leave BLAS alone, another limit inside is set
    and restored, and another thread sets its own."""
    import threading

    import scipy.linalg  # noqa: F401  (both BLAS libraries loaded)
    import threadpoolctl
    from threadpoolctl import threadpool_info

    from strip_aerotri._threads import blas_threads

    def blas() -> set[int]:
        return {d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}

    monkeypatch.delenv(BLAS_THREADS_VARIABLE, raising=False)
    if not blas():
        pytest.skip("no BLAS library that threadpoolctl knows")
    calls: list[int] = []
    real = threadpoolctl.threadpool_limits

    def counted(limits: int, user_api: str) -> object:
        calls.append(limits)
        return real(limits=limits, user_api=user_api)

    monkeypatch.setattr(threadpoolctl, "threadpool_limits", counted)
    with threadpoolctl.threadpool_limits(2, "blas"):
        calls.clear()
        with blas_threads():
            with blas_threads(), blas_threads(1):
                assert blas() == {1}
                with blas_threads(3):
                    assert blas() == {3}
                assert blas() == {1}
            seen: list[set[int]] = []
            worker = threading.Thread(target=lambda: seen.append(_in_limit(blas_threads, blas)))
            worker.start()
            worker.join()
            assert blas() == {1}
        assert blas() == {2}
    assert calls == [1, 3, 1]
    assert seen == [{1}]


def _in_limit(blas_threads, blas):  # type: ignore[no-untyped-def]
    with blas_threads():
        return blas()


def test_a_ctrl_c_while_threadpoolctl_scans_the_libraries_is_not_lost(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """threadpoolctl finds the BLAS libraries through a ctypes callback, where
    a KeyboardInterrupt is printed and dropped: a Ctrl-C landing there let a
    run go on to its end (seen in CI, exit 0 after SIGINT).  It is now held
    over the scan and raised after it, and the limits set are restored."""
    import ctypes
    import os
    import signal

    import threadpoolctl

    events: list[str] = []
    scan = ctypes.CFUNCTYPE(None)

    def interrupted_scan() -> None:  # what dl_iterate_phdr's callback would run
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(100_000):  # the handler runs here, inside the callback
            pass

    class Limits:
        def __init__(self, limits: int, user_api: str) -> None:
            scan(interrupted_scan)()
            events.append("set")

        def __enter__(self) -> Limits:
            return self

        def __exit__(self, *exc: object) -> None:
            events.append("restored")

    monkeypatch.setattr(threadpoolctl, "threadpool_limits", Limits)
    with pytest.raises(KeyboardInterrupt):
        with blas_threads(1):
            events.append("body")
    assert events == ["set", "restored"]
