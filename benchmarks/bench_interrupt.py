"""How fast ``stripaero run`` stops on Ctrl-C (SIGINT), at several moments of a run.

Usage::

    python benchmarks/bench_interrupt.py                  # 1000-photo drone strip
    python benchmarks/bench_interrupt.py --photos 300 --at 0.5 1 2
    python benchmarks/bench_interrupt.py --strips 10 --photos 300 --at 2 5 10 20
    python benchmarks/bench_interrupt.py --project path/to/strip.toml

Writes a simulated drone project (about 100 points per photo, as
``bench_scale.py``) unless ``--project`` is given, times one full run, then
starts the run again for every moment of ``--at`` (seconds after the start),
sends SIGINT there and measures the time until the process has exited: the
time a user waits after pressing Ctrl-C.  The stage the run was in is the
last progress line it printed.  The exit code is shown as it is (the
command's own handling of Ctrl-C decides it).  Last, the same wait for an
idle process with the run's imports: the interpreter's own share.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scale import write_case  # noqa: E402


def _drain(stream: object, lines: list[str]) -> None:
    for line in stream:  # type: ignore[attr-defined]
        lines.append(line.rstrip())


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupt_at(cmd: list[str], delay: float) -> tuple[float | None, int, str]:
    """Run ``cmd``, send SIGINT after ``delay`` s; (seconds from the signal to
    the exit or None when it had ended first, exit code, last progress line)."""
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        # as from a terminal: a shell's background job would inherit SIGINT ignored
        preexec_fn=_default_sigint,
    )
    lines: list[str] = []
    reader = threading.Thread(target=_drain, args=(proc.stderr, lines), daemon=True)
    reader.start()
    try:
        proc.wait(timeout=delay)
        return None, proc.returncode, lines[-1] if lines else ""
    except subprocess.TimeoutExpired:
        pass
    stage = lines[-1] if lines else "(starting)"
    sent = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    waited = time.perf_counter() - sent
    reader.join(timeout=5)
    return waited, proc.returncode, stage


#: A process with the run's imports, idle in Python: its exit after SIGINT is
#: the interpreter's own share of every wait below.
_IDLE = (
    "import time, numpy, scipy.sparse.linalg, strip_aerotri.cli.main\n"
    "print('ready', flush=True)\n"
    "time.sleep(600)"
)


def idle_exit(repeat: int = 3) -> list[float]:
    """Seconds from SIGINT to the exit of an idle process with the same imports."""
    waits = []
    for _ in range(repeat):
        proc = subprocess.Popen(
            [sys.executable, "-c", _IDLE],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            preexec_fn=_default_sigint,
        )
        assert proc.stdout is not None
        proc.stdout.readline()
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        waits.append(time.perf_counter() - sent)
    return waits


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=1000, help="photos (of each strip)")
    parser.add_argument("--strips", type=int, default=1)
    parser.add_argument("--refine", action="store_true", help='refine = "bundle"')
    parser.add_argument("--project", type=Path, help="an existing strip.toml instead")
    parser.add_argument(
        "--at", type=float, nargs="+", default=None, help="seconds after the start"
    )
    args = parser.parse_args(argv)
    exe = shutil.which("stripaero")
    if exe is None:
        sys.exit("stripaero is not installed (pip install .)")
    with tempfile.TemporaryDirectory() as tmp:
        toml = args.project
        if toml is None:
            toml = write_case(Path(tmp), args.strips, args.photos, refine=args.refine)
        cmd = [exe, "-v", "run", str(toml), "--out", str(Path(tmp) / "out")]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        total = time.perf_counter() - t0
        print(f"{toml}: full run {total:.2f} s (exit {done.returncode}); load {os.getloadavg()}")
        moments = args.at or [round(f * total, 2) for f in (0.1, 0.25, 0.4, 0.55, 0.7, 0.85)]
        worst = 0.0
        for delay in moments:
            waited, code, stage = interrupt_at(cmd, delay)
            if waited is None:
                print(f"  SIGINT at {delay:6.2f} s: the run had ended (exit {code})")
                continue
            worst = max(worst, waited)
            print(f"  SIGINT at {delay:6.2f} s: exit {code} after {waited:.2f} s  [{stage}]")
        print(f"longest wait after Ctrl-C: {worst:.2f} s; load {os.getloadavg()}")
        idle = ", ".join(f"{w:.2f}" for w in idle_exit())
        print(f"an idle process with the same imports exits {idle} s after SIGINT")


if __name__ == "__main__":
    main()
