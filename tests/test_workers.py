"""Worker threads of the engine's kernels (``_threads.compute_workers``,
``split_map``): the pieces are shared, the results are bit for bit those of
one thread, errors and Ctrl-C end both threads, no thread outlives a block.

The bundle's pieces are made small here (blocks of 64 rows) so that a
small strip splits into many of them, as a 1000-photo strip does at the
default size."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri import _threads
from strip_aerotri._threads import (
    WORKERS_VARIABLE,
    compute_workers,
    split_map,
    worker_count,
)
from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.bundle.refine import refine_bundle
from strip_aerotri.errors import ConfigError
from strip_aerotri.geometry import _normal_entries, collinearity
from strip_aerotri.options import SelfCalibration
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip


@pytest.fixture
def two_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two threads whatever the machine's cores and load, and small pieces."""
    monkeypatch.setattr(_threads, "_usable_cores", lambda: 2)
    monkeypatch.setattr(_threads, "MIN_PARALLEL_SIZE", 0)
    monkeypatch.setattr(_normal_entries, "BLOCK", 64)
    monkeypatch.setattr(collinearity, "_BLOCK", 64)
    monkeypatch.setenv(WORKERS_VARIABLE, "2")


# ---------------------------------------------------------------- the rules


@pytest.mark.parametrize(
    ("text", "cores", "load", "others", "size", "expected"),
    [
        ("", 2, 0.0, 0, 100_000, 2),
        ("", 8, 0.0, 0, 100_000, 2),  # two at most
        ("", 1, 0.0, 0, 100_000, 1),  # one CPU for this process
        ("", 2, 0.0, 0, 1_000, 1),  # small: the hand-over would not pay
        ("", 2, 3.0, 2, 100_000, 1),  # loaded: the other core is taken
        ("", 2, 3.0, None, 100_000, 1),  # loaded, and the moment unknown
        ("", 2, 1.9, 0, 100_000, 2),  # the load of this process's own past work
        ("", 2, 0.5, 3, 100_000, 2),  # a burst of others: the load average is low
        ("", 2, 1.0, 1, 100_000, 1),  # one CPU-bound process beside this one
        ("1", 2, 0.0, 0, 100_000, 1),
        ("2", 2, 3.0, 2, 100_000, 2),  # asked for: the load is not read
        ("4", 1, 0.0, 0, 100_000, 1),  # never more than the CPUs
    ],
)
def test_the_number_of_threads(
    monkeypatch: pytest.MonkeyPatch, text: str, cores: int, load: float, others: int | None,
    size: int, expected: int,
) -> None:  # fmt: skip
    monkeypatch.setenv(WORKERS_VARIABLE, text)
    monkeypatch.setattr(_threads, "_usable_cores", lambda: cores)
    monkeypatch.setattr(_threads, "_busy_cores", lambda: load)
    monkeypatch.setattr(_threads, "_others_running", lambda: others)
    assert worker_count(size) == expected


def test_the_moments_count_is_read_from_the_system() -> None:
    others = _threads._others_running()
    assert others is None or others >= 0


@pytest.mark.parametrize("text", ["0", "-1", "two", "1.5"])
def test_a_bad_number_of_threads_is_one_line_naming_the_variable(
    monkeypatch: pytest.MonkeyPatch, text: str
) -> None:
    monkeypatch.setenv(WORKERS_VARIABLE, text)
    with pytest.raises(ConfigError, match=f"^environment variable {WORKERS_VARIABLE}="):
        worker_count(100_000)


# ---------------------------------------------------------------- split_map


def test_split_map_keeps_the_order_and_uses_both_threads(two_workers: None) -> None:
    names: set[str] = set()
    # The first two items meet: each thread holds one until the other has
    # taken its own, so both threads work whatever the machine's load (a
    # worker started first could otherwise take every item).
    both_in = threading.Barrier(2, timeout=30.0)

    def square(i: int) -> int:
        names.add(threading.current_thread().name)
        if i < 2:
            both_in.wait()
        np.linalg.qr(np.ones((60, 60)))  # work that releases the interpreter
        return i * i

    before = threading.active_count()
    with compute_workers(10**6) as n:
        assert n == 2
        assert split_map(square, list(range(200))) == [i * i for i in range(200)]
    assert threading.active_count() == before  # the worker ended with the block
    assert threading.main_thread().name in names
    assert any(name.startswith("strip_aerotri-worker") for name in names)


def test_split_map_combines_in_the_items_order(two_workers: None) -> None:
    seen: list[int] = []
    with compute_workers(10**6):
        out = split_map(lambda i: i, list(range(300)), seen.append)
    assert out == []
    assert seen == list(range(300))


def test_a_sum_in_turn_is_the_same_whichever_thread_is_late(two_workers: None) -> None:
    """Floating-point sums into one array, combined in the items' order: the
    same bits as one thread's loop, with either thread held back at random."""
    rng = np.random.default_rng(2345)
    parts = [rng.normal(size=500) * 10.0 ** rng.integers(-8, 8) for _ in range(60)]
    delays = rng.uniform(0.0, 0.004, size=60)
    serial = np.zeros(500)
    for x in parts:
        serial += x

    def late(i: int) -> np.ndarray:
        time.sleep(float(delays[i]))
        return parts[i]

    total = np.zeros(500)

    def add(x: np.ndarray) -> None:
        total[:] += x

    with compute_workers(10**6):
        split_map(late, list(range(60)), add)
    np.testing.assert_array_equal(total, serial)


def test_split_map_without_a_block_is_the_loop() -> None:
    assert split_map(str, [1, 2, 3]) == ["1", "2", "3"]
    seen: list[str] = []
    split_map(str, [1, 2], seen.append)
    assert seen == ["1", "2"]


def test_a_split_map_inside_an_item_runs_serially_and_ends(two_workers: None) -> None:
    """An item that calls split_map itself (in the calling thread) must not
    wait for the one worker, which waits for that item's turn to combine."""
    seen: list[int] = []
    failures: list[BaseException] = []

    def item(i: int) -> int:
        inner = split_map(lambda j: j * i, list(range(4)))
        time.sleep(0.001)
        return sum(inner)

    def outer() -> None:
        try:
            with compute_workers(10**6):
                split_map(item, list(range(40)), seen.append)
        except BaseException as exc:  # raised in the test's thread below
            failures.append(exc)

    thread = threading.Thread(target=outer, daemon=True)
    thread.start()
    thread.join(timeout=20.0)
    assert not thread.is_alive(), "split_map inside an item did not end"
    assert not failures
    assert seen == [6 * i for i in range(40)]


def test_nested_blocks_share_the_outer_worker(two_workers: None) -> None:
    before = threading.active_count()
    with compute_workers(10**6) as outer, compute_workers(10**6) as inner:
        assert (outer, inner) == (2, 2)
        split_map(abs, [-1, -2, -3])
        assert threading.active_count() <= before + 1
    assert threading.active_count() == before


@pytest.mark.parametrize("combine", [False, True])
def test_an_error_in_either_thread_is_raised_and_stops_both(
    two_workers: None, combine: bool
) -> None:
    taken: list[int] = []
    at_error: list[int] = []  # items taken when the error was raised

    def fail_at(i: int) -> int:
        taken.append(i)
        if i == 7:
            at_error.append(len(taken))
            raise ValueError("item 7")
        np.linalg.qr(np.ones((40, 40)))
        return i

    before = threading.active_count()
    with pytest.raises(ValueError, match="item 7"), compute_workers(10**6):
        split_map(fail_at, list(range(10_000)), (lambda r: None) if combine else None)
    assert threading.active_count() == before
    # after the error the other thread ends its current item and takes no other
    # (a margin for the failing thread held back by the system before it says so)
    assert len(taken) < at_error[0] + 500 < 10_000


def test_a_keyboard_interrupt_in_the_calling_thread_stops_the_worker(two_workers: None) -> None:
    taken: list[int] = []
    at_interrupt: list[int] = []

    def item(i: int) -> int:
        taken.append(i)
        if threading.current_thread() is threading.main_thread() and i > 20:
            at_interrupt.append(len(taken))
            raise KeyboardInterrupt
        np.linalg.qr(np.ones((40, 40)))
        return i

    with pytest.raises(KeyboardInterrupt), compute_workers(10**6):
        split_map(item, list(range(10_000)))
    # the worker ends its current item (a margin for this thread held back by
    # the system before it says so)
    assert len(taken) < at_interrupt[0] + 500 < 10_000


# ------------------------------------------------------- the same results


def _assert_identical(a: object, b: object, where: str = "") -> None:
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        for f in dataclasses.fields(a):
            if f.name == "timings":
                continue
            _assert_identical(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=where)  # NaN == NaN, bit for bit
    elif isinstance(a, float) and np.isnan(a):
        assert isinstance(b, float) and np.isnan(b), where
    elif isinstance(a, (tuple, list)) and a and not isinstance(a[0], str):
        assert len(a) == len(b), where  # type: ignore[arg-type]
        for i, (x, y) in enumerate(zip(a, b)):  # type: ignore[call-overload]
            _assert_identical(x, y, f"{where}[{i}]")
    else:
        assert a == b, where


def _threads_forming_rows(monkeypatch: pytest.MonkeyPatch) -> set[str]:
    """The names of the threads that form the rows' products from now on: by
    the general kernel (a border) or the photos' own (`unit_shift` rows)."""
    names: set[str] = set()

    def seen(function):  # type: ignore[no-untyped-def]
        def traced(*args, **kwargs):  # type: ignore[no-untyped-def]
            names.add(threading.current_thread().name)
            time.sleep(0.0005)  # pieces long enough for the worker to start and take some
            return function(*args, **kwargs)

        return traced

    monkeypatch.setattr(_normal_entries, "_summed", seen(_normal_entries._summed))
    monkeypatch.setattr(_normal_entries, "_lower_gram", seen(_normal_entries._lower_gram))
    return names


@pytest.mark.parametrize(
    "case", ["blunders", "self-calibration"]
)
def test_two_threads_give_the_results_of_one_bit_for_bit(
    monkeypatch: pytest.MonkeyPatch, two_workers: None, case: str
) -> None:
    """Rejections over several rounds (the snooping), and a border of camera
    parameters (the self-calibration's dense rows): every array of the
    result equal to the last bit."""
    sim = simulate_strip(
        30, preset="drone", crs="local", seed=2, control="every_k_models", control_every=10,
        image_blunders=4 if case == "blunders" else 0,
    )  # fmt: skip
    result = triangulate(
        sim.observations, sim.control, sim.crs, blunders=BlunderOptions(action="off")
    )
    spec = SelfCalibration(("k1", "k2", "p1")) if case == "self-calibration" else None

    def run():  # type: ignore[no-untyped-def]
        return refine_bundle(result, self_calibration=spec)

    names = _threads_forming_rows(monkeypatch)
    two = run()
    assert any(name.startswith("strip_aerotri-worker") for name in names)
    monkeypatch.setenv(WORKERS_VARIABLE, "1")
    one = run()
    if case == "blunders":
        assert len(one.rejections) >= 4
    else:
        assert one.self_calibration is not None
    _assert_identical(two, one)


def test_a_bad_number_of_threads_stops_a_refined_run_in_one_line(tmp_path: Path) -> None:
    from strip_aerotri import simulate_strip

    toml = simulate_strip(4, seed=1).write_project(tmp_path / "p")
    text = toml.read_text(encoding="utf-8")
    toml.write_text(text.replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n', 1))
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    done = subprocess.run(
        [sys.executable, "-c", code, "run", str(toml)],
        capture_output=True,
        text=True,
        env={**os.environ, WORKERS_VARIABLE: "two"},
        timeout=300,
        check=False,
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip() == (
        f"stripaero: error: environment variable {WORKERS_VARIABLE}='two': expected a positive "
        "number of threads (unset it for the default: two where a second core is free)"
    )
    assert not (toml.parent / "out").exists()


def test_the_ground_stage_on_two_threads_gives_the_results_of_one(
    monkeypatch: pytest.MonkeyPatch, two_workers: None
) -> None:
    """The engine's kernels open the threads themselves outside the bundle
    (every model at once): the strip method's result to the last bit."""
    sim = simulate_strip(
        30, preset="drone", crs="local", seed=2, control="every_k_models", control_every=10,
        image_blunders=2,
    )  # fmt: skip
    names = _threads_forming_rows(monkeypatch)
    two = triangulate(sim.observations, sim.control, sim.crs)
    assert any(name.startswith("strip_aerotri-worker") for name in names)
    monkeypatch.setenv(WORKERS_VARIABLE, "1")
    one = triangulate(sim.observations, sim.control, sim.crs)
    for name in ("points", "photo_centres", "photo_opk"):
        np.testing.assert_array_equal(getattr(two, name), getattr(one, name), err_msg=name)
    assert [r.describe() for r in two.rejections] == [r.describe() for r in one.rejections]
