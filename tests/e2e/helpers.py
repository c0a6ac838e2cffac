"""Pseudo-terminal pairs, a paced simulator writer, and MCAP checks shared by the end-to-end tests."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
import tty

from mcap.reader import make_reader

from rs30x_sniff.decode.framing import decode_all
from rs30x_sniff.sources.mcap_reader import read_mcap_raw
from rs30x_sniff.sim import run
from rs30x_sniff.sim.port import play


class Pty:
    """A pty pair: the simulator writes the master, the sniffer opens the slave by its path."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        # Raw mode before anyone opens it: no echo back to the master, no line editing.
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)

    def write_sim(self, name: str, duration: float | None = None, seed: int = 0, baud: int = 115200) -> bytes:
        """Play a scenario onto the master at its baud-rate pacing; the bytes sent."""
        chunks = list(run(name, duration=duration, seed=seed, baud=baud))
        play(chunks, lambda b: os.write(self.master, b))
        return b"".join(d for d, _ in chunks)

    def master_silent(self, wait: float = 0.2) -> bool:
        """True if nothing arrived at the master: the sniffer wrote no byte to the port."""
        readable, _, _ = select.select([self.master], [], [], wait)
        return not readable

    def close_master(self) -> None:
        if self.master >= 0:
            os.close(self.master)
            self.master = -1

    def close(self) -> None:
        self.close_master()
        try:
            os.close(self.slave)
        except OSError:
            pass


def cli(*args: str, **kw) -> subprocess.Popen:
    """``rs30x-sniff ARGS`` as a child process with piped output."""
    return subprocess.Popen([sys.executable, "-m", "rs30x_sniff", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, **kw)


def wait_for(path, proc: subprocess.Popen, timeout: float = 15.0) -> None:
    """Wait until ``proc`` has created ``path`` (it opens the port first, then the file)."""
    end = time.monotonic() + timeout
    while not os.path.exists(path):
        if proc.poll() is not None:
            raise AssertionError(f"exited early: {proc.returncode} {proc.stderr.read().decode()}")
        if time.monotonic() > end:
            raise AssertionError(f"{path} never appeared")
        time.sleep(0.02)
    time.sleep(0.1)


def _holders(path: str) -> set[int]:
    """The processes (other than this one) with ``path`` open, read from /proc."""
    target = os.path.realpath(path)
    found = set()
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                if os.readlink(f"/proc/{pid}/fd/{fd}") == target:
                    found.add(int(pid))
                    break
            except OSError:
                continue
    return found


def wait_opened(path, proc: subprocess.Popen, timeout: float = 30.0) -> None:
    """Wait until some process but this one holds the port ``path`` open (the sniffer or its reader process),
    instead of a fixed sleep: on a loaded machine a reader process can take seconds to start, and pyserial
    flushes the input when it opens, so bytes written before would be lost to the test, not to the sniffer."""
    if not os.path.isdir("/proc/self/fd"):
        time.sleep(1.5)
        return
    end = time.monotonic() + timeout
    while not _holders(str(path)):
        if proc.poll() is not None:
            raise AssertionError(f"exited early: {proc.returncode} {proc.stderr.read().decode()}")
        if time.monotonic() > end:
            raise AssertionError(f"{path} was never opened")
        time.sleep(0.02)
    time.sleep(0.2)  # opened; its input flushed just after


def recorded_bytes(path) -> bytes:
    return b"".join(d for d, _ in read_mcap_raw(str(path)))


def assert_finalized_mcap(path) -> dict[str, int]:
    """The file has a summary and footer (finished, not merely readable); message counts per topic."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, f"{path} has no summary: not finalized"
        counts = summary.statistics.channel_message_counts
        return {summary.channels[cid].topic: n for cid, n in counts.items()}


def events(data: bytes) -> list[tuple[str, bytes]]:
    """Kind and bytes of every frame event, timing left out (live arrival times differ)."""
    return [(e.kind, e.raw) for e in decode_all([(data, None)])]
