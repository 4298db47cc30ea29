"""The lock of a result folder: exclusive, released, stale locks taken over,
others' never removed."""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import pytest

from strip_aerotri.report.files import OutputError
from strip_aerotri.report.lock import FolderLock, lock_path


def test_one_holder_at_a_time_and_released_on_exit(tmp_path: Path):
    target = tmp_path / "deep" / "out"
    with FolderLock(target) as lock:
        assert lock.path == lock_path(target) == tmp_path / "deep" / ".out.lock"
        held = lock.path.read_text().split()
        assert held[0] == str(os.getpid()) and held[1] == socket.gethostname()
        with pytest.raises(OutputError, match="being written by another stripaero run"):
            FolderLock(target).acquire()
    assert not lock_path(target).exists()


def test_released_when_the_block_raises(tmp_path: Path):
    target = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt), FolderLock(target):
        raise KeyboardInterrupt
    assert not lock_path(target).exists()


def test_a_lock_of_another_host_is_not_taken_over(tmp_path: Path):
    target = tmp_path / "out"
    lock_path(target).write_text("1 some-other-host 2026-01-01T00:00:00+00:00\n")
    with pytest.raises(OutputError, match="process 1 on some-other-host"):
        FolderLock(target).acquire()
    assert lock_path(target).exists()


def test_an_unreadable_lock_is_stale_only_when_old(tmp_path: Path):
    """An empty lock file may be one being written this instant: refused; an
    old one (a crash between creating and writing it) is taken over."""
    target = tmp_path / "out"
    path = lock_path(target)
    path.write_text("")
    with pytest.raises(OutputError, match="a process that is starting"):
        FolderLock(target).acquire()
    old = time.time() - 3600
    os.utime(path, (old, old))
    with FolderLock(target):
        assert path.read_text().split()[0] == str(os.getpid())
    assert not path.exists()


def test_release_leaves_a_lock_that_is_no_longer_ours(tmp_path: Path):
    target = tmp_path / "out"
    lock = FolderLock(target)
    lock.acquire()
    lock.path.write_text("999999 elsewhere 2026-01-01T00:00:00+00:00\n")
    lock.release()
    assert lock.path.exists()
