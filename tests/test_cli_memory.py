"""cli.memory.keep_freed_memory: glibc's thresholds set for the stripaero
process, so that arrays freed and allocated again are not fresh pages."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from _cli_process import python_subprocess

_FAULTS = """
import resource, sys
import numpy as np
from strip_aerotri.cli.memory import keep_freed_memory
print(keep_freed_memory())
faults = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_minflt
arrays = [np.ones(2_500_000) for _ in range(4)]  # 4 x 20 MB, then freed
del arrays
before = faults()
arrays = [np.ones(2_500_000) for _ in range(4)]
print(faults() - before)
"""


def _run(env: dict[str, str]) -> tuple[bool, int]:
    done = python_subprocess(_FAULTS, env=env)
    assert done.returncode == 0, done.stderr
    out = done.stdout.split()
    return out[0] == "True", int(out[1])


def _glibc() -> bool:
    try:
        return sys.platform.startswith("linux") and os.confstr("CS_GNU_LIBC_VERSION") is not None
    except (ValueError, OSError):
        return False


@pytest.mark.skipif(not _glibc(), reason="glibc's mallopt only")
def test_freed_arrays_are_reused_without_page_faults() -> None:
    """80 MB allocated again after being freed: almost no page faults (19 531
    pages of fresh memory would each fault)."""
    applied, faults = _run({})
    assert applied
    assert faults < 200


@pytest.mark.skipif(not _glibc(), reason="glibc's mallopt only")
def test_the_users_own_malloc_settings_stand() -> None:
    applied, _ = _run({"MALLOC_TRIM_THRESHOLD_": "1000000"})
    assert not applied


def test_nothing_elsewhere(monkeypatch: pytest.MonkeyPatch) -> None:
    from strip_aerotri.cli import memory

    monkeypatch.setattr(memory.sys, "platform", "darwin")
    assert memory.keep_freed_memory() is False


@pytest.mark.parametrize("owns_process", [False, True])
def test_only_the_stripaero_script_changes_what_is_process_wide(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, owns_process: bool
) -> None:
    """A run called in another program's process (click's CliRunner, a test)
    leaves the allocator and numpy's submodules alone; the script's run
    (``cli.main.main`` sets ``OWNS_PROCESS``) tunes them."""
    from click.testing import CliRunner

    import strip_aerotri as sa
    from strip_aerotri.cli import imports, memory
    from strip_aerotri.cli import run as run_module
    from strip_aerotri.cli.main import cli

    called: list[str] = []

    def kept() -> bool:
        called.append("memory")
        return True

    def deferred() -> tuple[str, ...]:
        called.append("numpy")
        return ()

    monkeypatch.setattr(memory, "keep_freed_memory", kept)
    monkeypatch.setattr(imports, "defer_numpy_submodules", deferred)
    monkeypatch.setattr(run_module, "OWNS_PROCESS", owns_process)
    toml = sa.simulate_strip(6, preset="film", seed=3).write_project(tmp_path / "p")
    done = CliRunner().invoke(cli, ["-q", "run", str(toml), "--out", str(tmp_path / "out")])
    assert done.exit_code == 0, done.output
    assert called == (["memory", "numpy"] if owns_process else [])
