"""The allocator's thresholds (issue 35): set once per process with mallopt on glibc, skipped elsewhere."""

from __future__ import annotations

import ctypes
import importlib
import sys

import pytest

from rs30x_sniff import allocator, cli


class FakeLibc:
    """A C library whose mallopt records what it is told (and accepts it, as glibc does: 1)."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int]] = []

        def mallopt(option: int, value: int) -> int:
            self.calls.append((option, value))
            return 1

        self.mallopt = mallopt


@pytest.fixture
def fresh(monkeypatch):
    """allocator as a new process has it (nothing set yet), put back as it was afterwards."""
    importlib.reload(allocator)
    yield allocator
    importlib.reload(allocator)


def test_the_thresholds_are_set_once(fresh):
    libc = FakeLibc()
    assert fresh.keep_large_buffers(libc) is True
    assert libc.calls == list(fresh.SETTINGS)
    assert fresh.keep_large_buffers(libc) is False
    assert libc.calls == list(fresh.SETTINGS)


def test_a_command_sets_them_once_however_often_main_runs(fresh, monkeypatch, capsys):
    libc = FakeLibc()
    monkeypatch.setattr(fresh, "glibc", lambda: libc)
    assert cli.main(["rules", "--isolated"]) == 0
    assert cli.main(["rules", "--isolated"]) == 0
    assert libc.calls == list(fresh.SETTINGS)


def test_help_sets_nothing(fresh, monkeypatch, capsys):
    libc = FakeLibc()
    monkeypatch.setattr(fresh, "glibc", lambda: libc)
    assert cli.main(["--help"]) == 0
    assert libc.calls == []


def test_skipped_off_linux(fresh, monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    assert fresh.glibc() is None
    assert fresh.keep_large_buffers() is False


def test_skipped_on_a_c_library_that_is_not_glibc(fresh, monkeypatch):
    class Musl:  # a mallopt that would ignore glibc's options, and no gnu_get_libc_version
        mallopt = staticmethod(lambda option, value: 0)

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr(ctypes, "CDLL", lambda name: Musl())
    assert fresh.glibc() is None
    assert fresh.keep_large_buffers() is False


def test_a_refused_option_is_said_in_the_result(fresh):
    libc = FakeLibc()
    libc.mallopt = lambda option, value: 0
    assert fresh.keep_large_buffers(libc) is False


@pytest.mark.skipif(allocator.glibc() is None, reason="glibc only: this C library is not glibc")
def test_glibc_accepts_the_settings(fresh):
    assert fresh.keep_large_buffers() is True
