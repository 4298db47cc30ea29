"""``stripaero`` in a subprocess: for inputs that could block the process
reading them (a named pipe, a device), so that a regression fails on a
timeout instead of hanging the test session."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


def cli_subprocess(*args: str | Path, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    """``stripaero ARGS`` in a fresh interpreter (with this one's sys.path)."""
    code = "from strip_aerotri.cli.main import cli; cli()"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    return subprocess.run(
        [sys.executable, "-c", code, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        check=False,
    )


def python_subprocess(
    code: str, *args: str, env: dict[str, str] | None = None, timeout: float = 120.0
) -> subprocess.CompletedProcess[str]:
    """``python -c CODE ARGS`` in a fresh interpreter (with this one's
    sys.path), ``env`` added to the environment."""
    full = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), **(env or {})}
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=full,
        check=False,
    )
