"""Time-base rules (F): a capture whose clock runs backwards or faster than the bytes on the wire."""

from __future__ import annotations

from ...decode.framing import TIME_BACKWARDS, TIME_TOO_CLOSE
from ...protocol.wire import encode_read, encode_short
from ..registry import example, rule

_GOAL = encode_short(1, 0, 0x1E, b"\x84\x03")  # goal_position 90.0 deg on ID 1
_READ = encode_read(1, 0x2A, 2)                # present_position of ID 1


def _times(n: int) -> str:
    return "once" if n == 1 else f"{n} times"


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
    fault = getattr(lint, "time_faults", {}).get(TIME_BACKWARDS)
    if fault is not None:
        lint.emit_at("F005", fault.offset, fault.placed,
                     f"the capture's clock goes backwards {_times(fault.count)}: first here, stamped "
                     f"{fault.t:.6f} s, {(fault.earliest - fault.t) * 1e3:.3f} ms before the previous bytes "
                     f"ended (held at the previous chunk's time, so no time runs backwards)")


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
    fault = getattr(lint, "time_faults", {}).get(TIME_TOO_CLOSE)
    if fault is not None:
        lint.emit_at("F006", fault.offset, fault.placed,
                     f"{fault.count} chunk{'s' if fault.count > 1 else ''} stamped before the bytes ahead "
                     f"could have crossed the wire at {lint.config.baud} bit/s (first here, "
                     f"{(fault.earliest - fault.t) * 1e6:.0f} us early): are the times each read's arrival "
                     f"(--time-ref arrival), or is the baud rate another?")


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
    lint.emit_at("F010", seam.offset, seam.t_start, seam.describe())
