"""Framing rules (F): bytes that do not make clean frames."""

from __future__ import annotations

from ...protocol.baud import BaudEstimate
from ...protocol.chunks import UART_ERRORS
from ...protocol.events import CAPTURE_EDGES, RAW, REASON, T_END, T_START, TRUNCATED
from ...protocol.wire import AT_ID, BAUD_RATES, SUM_SIZE, encode_short
from ..params import DURATION, Measured, Message, said, said_as
from ..registry import example, rule

_GOAL = encode_short(1, 0, 0x1E, b"\x84\x03")  # goal_position 90.0 deg on ID 1


@rule("F001", "checksum-mismatch", "error", "A packet's Sum is not the XOR of its ID through data bytes.", f"""
## What it does
Flags a request or return whose last byte is not the XOR of every byte from ID to the end of the data
(the Sum of the packet formats in chapter 4). Only this rule, F004 and B007 look at such a packet: its
other bytes cannot be trusted.

## Why it matters
A servo silently drops a packet whose Sum is wrong, so the command never happens; a host that ignores a
bad Sum on a return acts on corrupted positions or temperatures. Repeated mismatches point at noise,
a weak pull-up, a long cable, or two talkers at once.

## Example
{example(_GOAL[:-1] + bytes((_GOAL[-1] ^ 0x01,)), note="goal_position 90.0 deg with the Sum off by one bit:")}
""", kinds=("corrupt",), column="silent")
def checksum_mismatch(lint, rec, ev):
    raw = ev.raw
    # Both Sums follow from the packet's data: measured, so a corrupted packet of other data is the same finding.
    lint.emit("F001", rec, said("Sum is 0x{sum:02X} but the bytes from ID on XOR to 0x{xor:02X}",
                                {"sum": Measured(raw[-1]), "xor": Measured(_xor(raw[AT_ID:-SUM_SIZE]))}))


def _xor(data: bytes) -> int:
    x = 0
    for b in data:
        x ^= b
    return x


@rule("F002", "garbage-bytes", "warning", "Bytes on the bus that belong to no frame.", f"""
## What it does
Flags a run of bytes with no frame header in it (noise), or with a header whose length could not be a
real frame (more than 1024 data bytes). Not the tail of a frame that began before the capture did (the
bytes before its first frame), nor a frame the capture's end cut off: those are the capture's edges.

## Why it matters
The RS30x bus is quiet between frames: stray bytes mean electrical noise, a baud-rate mismatch (a servo
answering at its old rate), or another device on the line. Each stray byte can also desynchronise a
servo's own parser and cost the next command.

## Example
{example(_GOAL, bytes.fromhex("123456"), _GOAL, note="three stray bytes between two goal_position writes:")}
""", kinds=("garbage",), column="silent")
def garbage_bytes(lint, rec, ev):
    # Cut-short frames are F003's, bytes the capturing UART flagged are F008's (rs30x_sniff.protocol.chunks), and
    # frames the capture's own start or end cut are no fault of the bus.
    if ev.reason == "truncated" or ev.reason in UART_ERRORS or ev.reason in CAPTURE_EDGES:
        return
    prev = lint.prev
    if prev is not None and prev.event.kind == "garbage" and prev.event.end_offset == ev.offset \
            and prev.event.reason != "truncated" and prev.event.reason not in UART_ERRORS:
        return  # the next piece of a long run (the decoder hands runs out in pieces): said once
    what = "no frame header" if ev.reason == "noise" else "a header whose length cannot be a frame"
    lint.emit("F002", rec, said("{count} byte(s) with {what}", {"count": Measured(len(ev.raw)), "what": what}))


@rule("F003", "truncated-frame", "error", "A frame that was cut short.", f"""
## What it does
Flags a frame header followed by fewer bytes than its Length and Count promise: the sender stopped
(an idle gap of more than the decoder's gap, 20 byte times by default) or another frame started inside it.
A frame cut by the capture's own start or end (or a seam of its clock) is not flagged: the bus did not
cut it.

## Why it matters
A servo that receives half a packet waits for the rest and may swallow the start of the next packet
as its tail, so two commands are lost instead of one. A host that stops mid-frame usually crashed,
was pre-empted, or filled a transmit buffer.

## Example
{example((0.0, _GOAL[:8]), (0.01, _GOAL), note="a goal_position write that stops after 8 of its 10 bytes, then another:")}
""", kinds=("garbage",), column="silent")
def truncated_frame(lint, rec, ev):
    if ev.reason == "truncated":
        raw = ev.raw
        lint.emit("F003", rec, said("frame cut short after {count} byte(s)", {"count": Measured(len(raw))}),
                  sid=raw[AT_ID] if len(raw) > AT_ID else None)


def _inter_byte_gap_columns(view) -> bool:
    """F004 on a Block: no row's bytes took longer than their count needs by more than the gap."""
    if not view.timed:
        return True
    lint, blk = view.lint, view.blk
    bt = lint.byte_time
    idle = (blk.t1 - blk.t0) - (view.ends - view.starts) * bt
    return not (idle > lint.config.inter_byte_gap * bt).any()


@rule("F004", "inter-byte-gap", "warning", "Idle time inside a frame, between two of its bytes.", f"""
## What it does
Flags a frame whose bytes took longer on the wire than their count needs, by more than `inter-byte-gap`
byte times (default 5) of idle line somewhere inside it. Needs timestamps. A gap long enough to end
the frame (the decoder's gap, 20 byte times by default) makes it F003 instead.

## Why it matters
The servos expect a packet's bytes back to back; a host that pauses inside a packet (a slow loop
writing byte by byte, a USB adapter flushing half a packet) risks the servo giving up on the packet
or merging it with the next one.

## Example
{example((0.0, _GOAL[:5]), (0.001, _GOAL[5:]), note="a goal_position write with 1 ms of silence after its fifth byte:")}
""", kinds=("packet", "corrupt"), needs_time=True, column=_inter_byte_gap_columns)
def inter_byte_gap(lint, rec, ev):
    t0, t1 = ev[T_START], ev[T_END]
    if t0 is None or t1 is None:
        return
    bt = lint.byte_time
    idle = (t1 - t0) - len(ev[RAW]) * bt
    if idle > lint.config.inter_byte_gap * bt:
        lint.emit("F004", rec, said("{idle} ms ({byte_times:.1f} byte times) of idle line inside the frame",
                                    {"idle": Measured(idle, DURATION), "byte_times": Measured(idle / bt, "byte times")}))


_ONE_FRAME = (TRUNCATED, *CAPTURE_EDGES)


class _Stretch:
    """F007's memory: the current run of garbage with no valid frame, and the records' timing."""

    def __init__(self) -> None:
        from ...decode.autobaud import BaudFromTimes, NoFrameStretch

        self.run = NoFrameStretch()
        self.last = -1  # lint.records count of the last garbage (or corrupt) record of the run
        self.times = BaudFromTimes(keep=512)


# 18 goal writes sent back to back at 115200 bit/s, as a receiver at 57600 reads them (made with
# rs30x_sniff.sim.wire.retime): 180 bytes on the line, 73 bytes of garbage read.
_WRONG_BAUD = bytes.fromhex(
    "3E84611EBC080B84300061 0DCE090BB4684261 08CA090BE4004261 09CB080BF4C48461 1C3E080BA4948061"
    "1FE6090B94B48061 0ECC090BC43E8061 0BC90A0BD4E68561 0ACB0A0B84FE")


def _wrong_baud_rate_columns(st, view) -> bool:
    """F007 on a Block: a Block holds valid frames only, which end a stretch and (timed) feed the rate
    estimate, as the check of each packet does."""
    if view.timed:
        view.when_quiet(lambda: st.times.chunks(view.ends - view.starts, view.blk.t0))
    return True


@rule("F007", "wrong-baud-rate", "error", "A long run of bytes with no valid frame: the bus is at another baud rate.", f"""
## What it does
Flags a stretch of traffic that holds no checksum-valid frame where a healthy bus would have had
several: 64 bytes of garbage in a row, or half a second of it (at least 16 bytes) in a timed capture.
Said once per stretch, as soon as the stretch is that long; a valid frame ends the stretch. A byte
capture cannot tell which rate the bus is at, so the finding names the rates of table 4.7 to try;
a timed capture whose bytes came back to back at another rate than the one decoded names that rate.

## Why it matters
A receiver set to the wrong rate still delivers bytes (with framing errors), so a capture at the
wrong rate looks like a busy bus of noise: no packets, nothing else to see. The usual causes are a
servo whose baud_rate was changed, flashed and rebooted (table 4.7, No. 6), or a sniffer left at the
factory default 115200 on a bus that runs at another rate. `--baud auto` on a port finds the rate.

## Example
{example(_WRONG_BAUD, note="18 goal writes sent at 115200 bit/s, read at 57600:")}
""", kinds=("garbage", "corrupt", "packet", "ack", "nack"), state=_Stretch, column=_wrong_baud_rate_columns)
def wrong_baud_rate(st, lint, rec, ev):
    # Garbage: the run grows. Runs of garbage are split where the decoder found a (corrupt) frame
    # header or an idle gap, so consecutive garbage records are one stretch.
    n = lint.records
    if st.last != n - 1:
        st.run.reset()
    st.last = n
    t0 = ev[T_START]
    if t0 is not None:
        st.times.chunk(ev[RAW], t0)
    # One cut frame is F003's (or the capture's edge), not a stretch at another rate: its bytes do not
    # count, though it does not end the stretch either.
    if ev.kind != "garbage" or ev[REASON] in _ONE_FRAME or not st.run.garbage(len(ev[RAW]), t0, ev[T_END]):
        return
    est = st.times.estimate if lint.timed else None
    lint.emit("F007", rec, _wrong_baud_message(st.run.bytes, st.run.span, lint.config.baud, est), sid=None)


def _wrong_baud_message(nbytes: int, span: float | None, baud: int, estimate: BaudEstimate | None = None) -> Message:
    """F007's text: what was seen, and which rates to try (``estimate``: the rate the timestamps give,
    rs30x_sniff.decode.autobaud.BaudFromTimes; None for a capture without times)."""
    where = "no valid frame in {bytes} bytes" + (" ({span} s)" if span is not None else "") + " read at {baud} bit/s: "
    params = {"bytes": Measured(nbytes), "baud": baud, "rates": ", ".join(str(r) for r in BAUD_RATES if r != baud)}
    shown = {}
    if span is not None:  # a stretch is long: written in seconds
        params["span"], shown["span"] = Measured(span, DURATION), f"{span:.2f}"
    if estimate is None:
        return said_as(where + "is the bus at another rate? The bytes alone cannot tell which; "
                       "try --baud auto on a port, or the other rates of table 4.7 ({rates})", params, shown)
    if estimate.baud is not None and estimate.baud != baud and estimate.per_byte is not None:
        # The rate the times give names the fault (the bus is at that rate): it stays in the key.
        return said_as(where + "the timestamps put bytes {per_byte} us apart, a byte time of {line} bit/s: "
                       "try --baud {line}", {**params, "per_byte": Measured(estimate.per_byte, DURATION),
                                             "line": estimate.baud},
                       {**shown, "per_byte": f"{estimate.per_byte * 1e6:.1f}"})
    if estimate.baud == baud:
        # A receiver at the wrong rate still delivers its bytes at its own pace, so its timestamps
        # show the rate it was set to, not the line's.
        return said_as(where + "the bytes arrived at the reader's own pace, which says nothing of the bus's rate; "
                       "try --baud auto on a port, or the other rates of table 4.7 ({rates})", params, shown)
    return said_as(where + "is the bus at another rate? The timestamps do not tell which; "
                   "try --baud auto on a port, or the other rates of table 4.7 ({rates})", params, shown)


@wrong_baud_rate.on("packet", "ack", "nack")
def _wrong_baud_valid_frame(st, lint, rec, ev):
    # A valid frame ends the stretch; its time still helps the estimate of the line's rate.
    t0 = ev[T_START]
    if t0 is not None:
        st.times.chunk(ev[RAW], t0)
