"""Serial loggers' logs written from simulator traffic, and the real tools run on a replay of it (tests, samples).

Each writer follows its tool's own printing code (pyserial's protocol_spy.py, socat's xiotransfer,
interceptty's dumpbuff, jpnevulator's read mode as it prints, slsnif's outputData) and is written
apart from the readers in rs30x_sniff.sources.serial_logs, so a round trip checks one against the other.

Run as a program it makes the samples in captures/foreign (see serial-logs.md there):
``python -m tests.sources.serial_log_writers DIR [spy socat jpnevulator interceptty slsnif]``.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
import tty
from datetime import datetime, timedelta
from pathlib import Path

from rs30x_sniff.protocol.chunks import HOST, SERVO
from rs30x_sniff.sim import SimBus, run
from rs30x_sniff.protocol.wire import byte_time

Sent = tuple[bytes, float, str]  # (bytes, time of their first byte, "host" or "servo")

START = datetime(2026, 11, 22, 14, 14, 50, 529)  # wall clock of the logs' first entry (local time)
SAMPLE_SCENARIO, SAMPLE_SECONDS, SAMPLE_BAUD = "hexapod", 0.1, 115200


def simulated(scenario: str = SAMPLE_SCENARIO, *, baud: int = SAMPLE_BAUD, seconds: float = SAMPLE_SECONDS,
              seed: int = 0) -> list[Sent]:
    """Every transmission of a simulated bus, in time order, with who sent it."""
    bus = SimBus(baud)
    bus.log = []
    for _ in run(scenario, baud=baud, seed=seed, duration=seconds, bus=bus):
        pass
    out = []
    for tx in sorted(bus.log, key=lambda x: x.start):
        if tx.source == "noise":
            raise ValueError(f"{scenario}: noise has no sender; use a scenario without it")
        out.append((tx.data, tx.start, HOST if tx.source == "host" else SERVO))
    return out


def arrivals(sent: list[Sent], baud: int) -> list[tuple[bytes, float, str]]:
    """The same transmissions stamped when their last byte had arrived, as a logger stamps a read."""
    bt = byte_time(baud)
    return [(d, t + len(d) * bt, who) for d, t, who in sent]


def _wall(t: float, start: datetime = START) -> datetime:
    return start + timedelta(seconds=t)


# ---- pyserial spy:// -------------------------------------------------------------------------------
def _spy_rows(data: bytes):
    """pyserial's hexdump(): (offset, row) per 16 bytes."""
    for off in range(0, len(data), 16):
        piece = data[off:off + 16]
        values, chars = [], []
        n = 0
        for b in piece:
            values.append(f"{b:02X} ")
            chars.append(chr(b) if 32 <= b < 127 else ".")
            n += 1
            if n == 8:
                values.append(" ")
        while n < 16:
            n += 1
            if n == 8:
                values.append(" ")
            values.append("   ")
            chars.append(" ")
        yield off, "".join(values) + " " + "".join(chars)


def spy_log(sent: list[Sent], baud: int, *, echo: bool = False) -> str:
    """A spy:// log of the host program: its writes (TX, stamped before they go out) and reads (RX,
    stamped when they return); ``echo`` adds the read-back of a one-wire adapter after each write."""
    bt = byte_time(baud)
    calls = []
    for data, t, who in sent:
        if who == HOST:
            calls.append((t, "TX", data))
            if echo:
                calls.append((t + len(data) * bt, "RX", data))
        else:
            calls.append((t + len(data) * bt, "RX", data))
    calls.sort(key=lambda c: c[0])
    lines = []
    for t, label, data in calls:
        for off, row in _spy_rows(data):
            lines.append("{:010.3f} {:4} {}{}\n".format(t, label, "{:04X}  ".format(off), row))
    return "".join(lines)


# ---- socat -x -v ---------------------------------------------------------------------------------
def socat_log(sent: list[Sent], baud: int, *, host_left: bool = True, verbose: bool = True,
              start: datetime = START) -> str:
    """socat's dump of a relay between the host's pty and the bus: a block per read, stamped at arrival."""
    out = []
    counts = {">": 0, "<": 0}
    for data, t, who in arrivals(sent, baud):
        arrow = ">" if (who == HOST) == host_left else "<"
        w = _wall(t, start)
        # socat 1.7.4 prints tv_nsec/1000 with a 9-digit format: microseconds, zero-padded.
        stamp = f"{w:%Y/%m/%d %H:%M:%S}.{w.microsecond:09d}"
        out.append(f"{arrow} {stamp}  length={len(data)} from={counts[arrow]} to={counts[arrow] + len(data) - 1}\n")
        counts[arrow] += len(data)
        if not verbose:
            out.append("".join(f" {b:02x}" for b in data) + "\n")
            continue
        s = 0
        while s < len(data):
            j = min(16, len(data) - s)
            row = []
            i = 0
            while i < j:
                c = data[s + i]
                row.append(f" {c:02x}")
                i += 1
                if c == 0x0A:
                    break
            chars = "".join("." if c == 0x0A or not 32 <= c < 127 else chr(c) for c in data[s:s + i])
            out.append("".join(row) + "   " * (16 - i) + "  " + chars + "\n")
            s += i
        out.append("--\n")
    return "".join(out)


# ---- interceptty ---------------------------------------------------------------------------------
_CTRL = ["[NUL]", "[SOH]", "[STX]", "[ETX]", "[EOT]", "[ENQ]", "[ACK]", "[BEL]", "[BS]", "[TAB]", "[LF]", "[VT]",
         "[FF]", "[CR]", "[SO]", "[SI]", "[DLE]", "[DC1]", "[DC2]", "[DC3]", "[DC4]", "[NAK]", "[SYN]", "[ETB]",
         "[CAN]", "[EM]", "[SUB]", "[ESC]", "[FS]", "[GS]", "[RS]", "[US]"]


def interceptty_log(sent: list[Sent], baud: int, *, stamps: bool = True, start: datetime = START) -> bytes:
    """interceptty's dump: a line per byte, '< ' from the program (host), '> \\t' from the device.

    With ``stamps``, the timestamped build: '[HH:MM SS.uuuuuu]' on a read's first line (spaces on the
    others) and every byte's character shown; without, the classic build: printable bytes only.
    """
    out = bytearray()
    for data, t, who in arrivals(sent, baud):
        tstamp = b""
        if stamps:
            w = _wall(t, start)
            tstamp = f"[{w:%H:%M %S}.{w.microsecond:06d}]".encode()
        for i, b in enumerate(data):
            if stamps:
                out += tstamp if i == 0 else b" " * len(tstamp)
            out += b"< " if who == HOST else b"> \t"
            out += b"0x%02x" % b
            if stamps:
                shown = _CTRL[b].encode() if b < 32 else b"[DEL]" if b == 127 else b"' '" if b == 32 else bytes((b,))
                out += b" (" + shown + b")"
            elif 33 <= b <= 126:
                out += b" (" + bytes((b,)) + b")"
            out += b"\n"
    return bytes(out)


# ---- jpnevulator ---------------------------------------------------------------------------------
def jpnevulator_log(sent: list[Sent], baud: int, *, names: tuple[str, str] | None = ("host", "servo"),
                    ascii: bool = False, byte_count: bool = False, width: int = 16,
                    start: datetime = START) -> str:
    """jpnevulator --read --timing-print: a timing line per read (the device's name too when it reads
    several), then the bytes, ``width`` a line; --ascii and --byte-count columns on request."""
    out = []
    counts = {HOST: 0, SERVO: 0}
    for data, t, who in arrivals(sent, baud):
        w = _wall(t, start)
        out.append(f"{w:%Y-%m-%d %H:%M:%S}.{w.microsecond:06d}:" + (f" {names[who != HOST]}" if names else "") + "\n")
        key = who if names else HOST
        for s in range(0, len(data), width):
            piece = data[s:s + width]
            line = " ".join(f"{b:02X}" for b in piece)
            if byte_count:
                line = f"{counts[key]:08X}\t" + line
            if ascii:
                line += " " * (3 * (width - len(piece))) + "\t" + "".join(chr(b) if 32 <= b < 127 else "." for b in piece)
            counts[key] += len(piece)
            out.append(line + "\n")
    return "".join(out)


# ---- slsnif --------------------------------------------------------------------------------------
_SLS_CTRL = ["<NUL>", "<SOH>", "<STX>", "<ETX>", "<EOT>", "<ENQ>", "<ACK>", "<BEL>", "<BS>", "<HT>", "<LF>",
             "<VT>", "<FF>", "<CR>", "<SO>", "<SI>", "<DLE>", "<DC1>", "<DC2>", "<DC3>", "<DC4>", "<NAK>", "<SYN>",
             "<ETB>", "<CAN>", "<EM>", "<SUB>", "<ESC>", "<FS>", "<GS>", "<RS>", "<US>", "<SPACE>"]


def slsnif_log(sent: list[Sent], baud: int, *, hex: bool = True, stamps: bool = True, totals: bool = False,
               start: datetime = START) -> bytes:
    """slsnif's log: reads of at most 32 bytes, each 'Host   --> ' or 'Device --> ' and 'c (xx) ' items
    ('c (ddd) ' without -x), after a ctime stamp with -t; -b adds the byte total of each read."""
    out = bytearray()
    for data, t, who in arrivals(sent, baud):
        for s in range(0, len(data), 32):
            piece = data[s:s + 32]
            if stamps:
                w = _wall(t, start)
                ms = w.microsecond // 1000
                # ctime, then ".%2u" of the milliseconds cut to 3 characters, the year, and a NUL.
                stamp = f"{w:%a %b} {w.day:2d} {w:%H:%M:%S}" + (".%2u" % ms)[:3] + f" {w.year}"
                out += b"\n\n" + stamp.encode() + b"\x00"
            else:
                out += b"\n"
            out += b"\nHost   --> " if who == HOST else b"\nDevice --> "
            for b in piece:
                shown = _SLS_CTRL[b].encode() if b < 33 else b"<DEL>" if b == 127 else bytes((b,))
                out += shown + (b" (%02x) " % b if hex else b" (%03d) " % b)
            if totals:
                out += b"\nTotal bytes transmitted: %d" % len(piece)
    return bytes(out + b"\n")


# ---- the real tools, on a real-time replay of the simulated bus -----------------------------------
def _raw_pty() -> tuple[int, str]:
    """A pty's controlling end and the path of its terminal end, in raw mode (bytes pass unchanged)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    return master, path


def replay(sent: list[Sent], baud: int, write_host, write_servo, *, host_first: bool = False) -> None:
    """Write each transmission when its last byte would have arrived, in real time, so the logger in
    between stamps it as the wire would have; with ``host_first`` the host's at their first byte (a
    program's write happens before its bytes go out). Each writer returns once the bytes went through."""
    bt = byte_time(baud)
    t0 = time.monotonic() + 0.5  # the tool settles into its loop first
    for data, t, who in sent:
        due = t0 + t + (0.0 if who == HOST and host_first else len(data) * bt)
        left = due - time.monotonic()
        if left > 0:
            time.sleep(left)
        (write_host if who == HOST else write_servo)(data)
        # Late (this process, or the tool in passing the bytes on): the rest of the schedule moves
        # with it, so no gap between two stamps comes out shorter than on the wire.
        t0 += max(0.0, time.monotonic() - due)
    time.sleep(0.2)


def _through(fd_in: int, fd_out: int, data: bytes) -> None:
    """Write to one end of a relay and wait for the bytes at the other: one read at a time, so a tool
    that selects on both sides cannot log a later write before an earlier one."""
    os.write(fd_in, data)
    got = 0
    while got < len(data):
        if not select.select([fd_out], [], [], 5.0)[0]:
            raise TimeoutError("the relay did not pass the bytes on")
        got += len(os.read(fd_out, 65536))


def real_spy(sent: list[Sent], baud: int, out: Path) -> None:
    """A host program that opens its port through pyserial's spy://, replaying the simulated host; the
    servos' bytes come in at the other end of a pty (the RX the program reads)."""
    import serial

    master, path = _raw_pty()
    port = serial.serial_for_url(f"spy://{path}?file={out}", baudrate=baud, timeout=0.5)
    try:
        def to_servos(data: bytes) -> None:
            port.write(data)
            got = 0
            while got < len(data):
                got += len(os.read(master, 65536))  # the bus takes the host's bytes

        def from_servo(data: bytes) -> None:
            os.write(master, data)
            port.read(len(data))  # the host reads the reply as it arrives

        replay(sent, baud, to_servos, from_servo, host_first=True)
    finally:
        port.close()
        port.formatter.output.close()
        os.close(master)


def real_socat(sent: list[Sent], baud: int, out: Path) -> None:
    """socat -x -v relaying between a pty for the host and a pty for the bus; its dump (stderr) is the log."""
    with tempfile.TemporaryDirectory() as tmp:
        host, bus = f"{tmp}/host", f"{tmp}/bus"
        with open(out, "wb") as log:
            proc = subprocess.Popen(["socat", "-x", "-v", f"PTY,link={host},raw,echo=0",
                                     f"PTY,link={bus},raw,echo=0"], stderr=log)
            try:
                _wait_for(host, bus)
                h = os.open(host, os.O_RDWR | os.O_NOCTTY)
                b = os.open(bus, os.O_RDWR | os.O_NOCTTY)
                tty.setraw(h)
                tty.setraw(b)
                replay(sent, baud, lambda d: _through(h, b, d), lambda d: _through(b, h, d))
                os.close(h)
                os.close(b)
            finally:
                proc.terminate()
                proc.wait(5)


def real_jpnevulator(sent: list[Sent], baud: int, out: Path) -> None:
    """jpnevulator --read --pass --timing-print between a pty for the host and one for the bus, aliased
    host and servo (--timing-delta shorter than the bus's gaps, so each read gets its own timing line)."""
    mh, ph = _raw_pty()
    ms, ps = _raw_pty()
    with open(out, "wb") as log:
        proc = subprocess.Popen(["jpnevulator", "--read", "--pass", "--timing-print", "--timing-delta=100",
                                 f"--tty={ph}:host", f"--tty={ps}:servo"], stdout=log)
        try:
            replay(sent, baud, lambda d: _through(mh, ms, d), lambda d: _through(ms, mh, d))
        finally:
            proc.terminate()
            proc.wait(5)
            os.close(mh)
            os.close(ms)


def _wait_for(*paths: str, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not all(os.path.exists(p) for p in paths):
        if time.monotonic() > end:
            raise TimeoutError(f"{' '.join(paths)} did not appear")
        time.sleep(0.02)


def swapped(sent: list[Sent]) -> list[Sent]:
    """The same traffic with the parties' roles swapped: a logger attached on the servos' side."""
    return [(d, t, SERVO if who == HOST else HOST) for d, t, who in sent]


def make_samples(out_dir: Path, which: list[str]) -> None:
    sent = simulated()
    out_dir.mkdir(parents=True, exist_ok=True)
    makers = {  # name: (how it is made, the findings it must show)
        "spy": (lambda p: real_spy(sent, SAMPLE_BAUD, p), []),
        # pyserial's spy:// on a program that plays the servos: every packet comes from the "wrong" side.
        "spy-swapped": (lambda p: real_spy(swapped(sent), SAMPLE_BAUD, p), ["F009"]),
        "socat": (lambda p: real_socat(sent, SAMPLE_BAUD, p), []),
        "jpnevulator": (lambda p: real_jpnevulator(sent, SAMPLE_BAUD, p), []),
        "interceptty": (lambda p: p.write_bytes(interceptty_log(sent, SAMPLE_BAUD)), []),
        "slsnif": (lambda p: p.write_bytes(slsnif_log(sent, SAMPLE_BAUD)), []),
    }
    for name in which or list(makers):
        if name in ("socat", "jpnevulator") and shutil.which(name) is None:
            print(f"{name} is not installed: skipped", file=sys.stderr)
            continue
        make, expected = makers[name]
        path = out_dir / f"{name}.log"
        for attempt in range(1, 31):
            make(path)
            # A real-time replay on a busy machine can hold a write back long enough to show in the
            # stamps (a late reply, a long gap): such a take is made again, so the sample lints as meant.
            findings = _lint(path)
            if findings == expected:
                break
            print(f"{path}: take {attempt} shows {', '.join(findings)}: again", file=sys.stderr)
        print(f"{path}: {path.stat().st_size} bytes", file=sys.stderr)


def _lint(path: Path) -> list[str]:
    from rs30x_sniff.sources.inputs import read_input
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import drive

    from rs30x_sniff.lint import LintConfig
    from rs30x_sniff.decode.decoder import DecodeOptions

    chunks = read_input(str(path), baud=SAMPLE_BAUD, warn=None, options={"baud": SAMPLE_BAUD})
    dec = drive(chunks, Decoder(DecodeOptions(baud=SAMPLE_BAUD), Linter(LintConfig(baud=SAMPLE_BAUD))))
    return sorted({f.code for f in dec.linter.findings})


if __name__ == "__main__":
    make_samples(Path(sys.argv[1]), sys.argv[2:])
