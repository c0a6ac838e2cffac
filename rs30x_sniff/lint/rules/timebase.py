"""Time-base rules (F): a capture whose clock runs backwards or faster than the bytes on the wire."""

from __future__ import annotations

from ...decode.framing import SEAM_RESTART, SEAM_SOURCE, TIME_BACKWARDS, TIME_TOO_CLOSE, Seam
from ...protocol.wire import encode_read, encode_short
from ..params import DURATION, TIME, Measured, Message, said_as
from ..registry import example, rule

_GOAL = encode_short(1, 0, 0x1E, b"\x84\x03")  # goal_position 90.0 deg on ID 1
_READ = encode_read(1, 0x2A, 2)                # present_position of ID 1


def _times(n: int) -> str:
    return "once" if n == 1 else f"{n} times"


def _chunks(n: int) -> str:
    return f"{n} chunk{'s' if n > 1 else ''}"


@rule("F005", "time-went-backwards", "warning", "The capture's timestamps go back in time.", f"""
## What it does
Flags a timestamped capture in which a chunk is stamped earlier than the chunk before it, by up to
10 ms, once, at the first place it happens, with how often it happened. Such chunks are placed at the
previous chunk's time, so the clock the other rules and figures use never runs backwards, and replies
placed so get no latency. A jump back by more than that is a restarted clock (F010), not a fault.

## Why it matters
Bytes cannot arrive before the bytes ahead of them. Backwards times come from a logger that merged
several reads out of order, a clock that was stepped (NTP, a laptop waking up) or a file edited by hand.
Read as they stand they give negative latencies, a zero-length capture and a bus load of 100 %.

## Example
{example((0.2, _GOAL), (0.195, _READ), note="the second line is stamped 5 ms before the first:")}
""", kinds=("close",), needs_time=True, column="silent")
def time_went_backwards(lint):
    fault = lint.time_faults.get(TIME_BACKWARDS)
    if fault is not None:
        # How often is counted in words ("once"), yet measured: the key masks it.
        lint.emit_at("F005", fault.offset, fault.placed, said_as(
            "the capture's clock goes backwards {count}: first here, stamped {t} s, {back} ms before the previous "
            "bytes ended (held at the previous chunk's time, so no time runs backwards)",
            {"count": Measured(fault.count), "t": Measured(fault.t, TIME),
             "back": Measured(fault.earliest - fault.t, DURATION)},
            {"count": _times(fault.count)}))


@rule("F006", "time-too-close", "warning",
      "Chunks stamped closer together than their bytes could travel at the baud rate.", f"""
## What it does
Flags a timestamped capture in which a chunk is stamped after the one before it but before that one's
bytes could have crossed the wire at the baud rate (10 bits a byte, 8N1), once, at the first place,
with how often it happened. Their times are kept, and a reply's latency is never taken below zero.

## Why it matters
Either the times mark when each read returned (the end of its last byte, as serial loggers such as
socat, interceptty or pyserial's spy:// stamp them) and should be read with `--time-ref arrival`, or
the capture was made at another baud rate than the one given. Read as they stand, replies start
before their requests end and latencies come out negative.

## Example
{example((0.0, _GOAL), (0.0005, _READ), note="a 10-byte write at 115200 bit/s takes 0.868 ms; the next line is stamped 0.5 ms after it began:")}
""", kinds=("close",), needs_time=True, column="silent")
def time_too_close(lint):
    fault = lint.time_faults.get(TIME_TOO_CLOSE)
    if fault is not None:
        early = fault.earliest - fault.t
        # The count with its noun's plural, and the lead in microseconds (it is below a byte time or two).
        lint.emit_at("F006", fault.offset, fault.placed, said_as(
            "{count} stamped before the bytes ahead could have crossed the wire at {baud} bit/s (first here, "
            "{early} us early): are the times each read's arrival (--time-ref arrival), or is the baud rate another?",
            {"count": Measured(fault.count), "baud": lint.config.baud, "early": Measured(early, DURATION)},
            {"count": _chunks(fault.count), "early": f"{early * 1e6:.0f}"}))


@rule("F010", "capture-seam", "info", "The capture's clock restarts, or resumes after a long silence.", f"""
## What it does
Notes each place where a timestamped capture's times jump back by more than 10 ms (two captures
joined with `cat`, a logger restarted) or forward by more than 10 s of silence (a capture stopped and
resumed). A new time segment begins there: nothing is paired, timed or counted across the seam, a
request still waiting for its reply at the seam is left unknown, not missing, and the first reply after
it may answer a request from before. Durations add up over the segments; rates, latencies and the bus
load are computed within them.

## Why it matters
Nothing is wrong on the bus: the capture has two parts. Read as one clock, its figures would come out
false (a duration of half the traffic, a bus load of 100 %, latencies of 0 ms) and its findings too.

## Example
{example((3.0, _GOAL), (0.0, _READ), note="a capture that ended at 3 s joined to one that starts at 0 s:")}
""", kinds=("seam",), needs_time=True, column="silent")
def capture_seam(lint, seam):
    lint.emit_at("F010", seam.offset, seam.t_start, _seam_message(seam))


def _seam_message(seam: Seam) -> Message:
    """F010's text: where the new time segment begins and why, with the span across the seam in seconds."""
    params: dict = {}
    shown: dict = {}
    t_end = seam.t_end
    timed = t_end is not None
    if t_end is not None:
        # Back by how much at a restart, forward by how much elsewhere.
        gap = t_end - seam.t_start if seam.kind == SEAM_RESTART else seam.t_start - t_end
        params["gap"], shown["gap"] = Measured(gap, DURATION), f"{gap:.3f}"
    if seam.kind == SEAM_SOURCE:
        # The note is the source's own words, no measurement (sources.reconnect: why the port was lost).
        params["note"] = seam.note
        return said_as("{note}" + (" ({gap} s from the last byte before)" if timed else "")
                       + ": a new time segment begins (nothing is paired or timed across it)", params, shown)
    if seam.kind == SEAM_RESTART:
        params["t"] = Measured(seam.t_start, TIME)
        return said_as("the capture's clock restarts here (stamped {t} s" + (", {gap} s back" if timed else "")
                       + "): a new time segment begins", params, shown)
    return said_as("the capture resumes here" + (" after {gap} s without bytes" if timed else "")
                   + ": a new time segment begins (nothing is timed across the gap)", params, shown)
