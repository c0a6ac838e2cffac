"""Shared test helpers: feed a decoder every way a stream can arrive, and the repository's paths."""

from __future__ import annotations

import os
import signal
import tempfile
import time
from pathlib import Path

import pytest

from rs30x_sniff.decode.framing import FrameDecoder
from rs30x_sniff.protocol.wire import byte_time

ROOT = Path(__file__).resolve().parent.parent
# The memory maps' cache (protocol.map_cache) of the tests and of the commands they start: a directory of this run's,
# never the user's own.
os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="rs30x-sniff-tests-cache-")
CAPTURES = ROOT / "captures"
# A run under `nohup` starts with SIGHUP ignored, and every command it starts would inherit that (and rightly
# keep running on a hang-up). A handler of ours instead: this run still outlives its terminal, and the commands
# the tests start begin with the default (exec resets a caught signal), as from a terminal.
if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) == signal.SIG_IGN:
    signal.signal(signal.SIGHUP, lambda signum, frame: None)


@pytest.fixture(autouse=True)
def no_github_step_summary(monkeypatch):
    """Tests run in GitHub Actions too: a test's --format github must not append to the job's real summary."""
    monkeypatch.delenv("GITHUB_STEP_SUMMARY", raising=False)


def h(text: str) -> bytes:
    """Bytes from hex text as the manual prints it: 'FA AF 01 ...'."""
    return bytes.fromhex(text)


def decode_chunks(chunks, baud: int = 115200, **kw):
    dec = FrameDecoder(baud, **kw)
    out = []
    for data, t in chunks:
        out += dec.feed(data, t)
    return out + dec.close()


def split_timed(data: bytes, cuts: list[int], t0: float | None, baud: int = 115200):
    """Cut ``data`` at ``cuts``; each chunk's time is t0 + its offset in byte times (consistent)."""
    bt = byte_time(baud)
    bounds = [0, *sorted(set(c for c in cuts if 0 < c < len(data))), len(data)]
    return [(data[a:b], None if t0 is None else t0 + a * bt) for a, b in zip(bounds, bounds[1:]) if b > a]


def assert_same_events(a, b) -> None:
    """Events equal in kind and every field; times equal to within float rounding (1 ns)."""
    assert len(a) == len(b), (a, b)
    for x, y in zip(a, b):
        assert type(x) is type(y), (x, y)
        assert x._replace(t_start=None, t_end=None) == y._replace(t_start=None, t_end=None)
        for tx, ty in ((x.t_start, y.t_start), (x.t_end, y.t_end)):
            assert (tx is None) == (ty is None) and (tx is None or abs(tx - ty) < 1e-9), (x, y)


def decode_three_ways(data: bytes, t0: float | None = None, **kw):
    """Decode whole, byte by byte, and in uneven chunks; assert the events agree and return them."""
    whole = decode_chunks(split_timed(data, [], t0), **kw)
    bytewise = decode_chunks(split_timed(data, list(range(1, len(data))), t0), **kw)
    uneven = decode_chunks(split_timed(data, list(range(3, len(data), 7)), t0), **kw)
    assert_same_events(bytewise, whole)
    assert_same_events(uneven, whole)
    return whole


@pytest.fixture
def manual_examples() -> Path:
    return CAPTURES / "manual-examples.hex"


@pytest.fixture
def utc(monkeypatch):
    """Local time is UTC while the test runs (an absolute time is shown as the local time of day)."""
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()
