"""cli.memory.keep_freed_memory: glibc's thresholds set for the stripaero
process, so that arrays freed and allocated again are not fresh pages."""

from __future__ import annotations

import os
import sys

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
