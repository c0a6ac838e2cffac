"""Bus rules (B): request/reply pairing, timing and collisions on the half-duplex line."""

from __future__ import annotations

import numpy as np

from ...decode.pairing import ANSWERED, EXTRA, MISSING, PAIRED, UNSOLICITED
from ...protocol.events import OFFSET, RAW, T_END, T_START
from ...protocol.wire import ACK, BROADCAST_ID, FRAME_OVERHEAD, NACK, encode_read, encode_return, encode_short
from ..batch import UNKNOWN
from ..registry import example, follows_cut, rule

_READ = encode_read(1, 0x2A, 2)              # present_position of ID 1
_RET = encode_return(1, 0x2A, bytes.fromhex("8403"))
_POLL2 = encode_read(2, 0x2A, 2)
_TIMING = """
Without timestamps a request that got no reply is always B002 (unless other bytes came back in its
place, which F002, F003 and B007 describe). With them, B001 and B002 are told apart by the time the reply
was due: the servo's return delay (100 us + 50 us x return_delay, the last value seen, else 0), plus the
reply's own transmission time, plus `latency-margin` (default 2 ms), and never more than the reply timeout
(`reply-timeout`, default 0.05 s). A next request inside that window is the host's fault (B001); a later
one, or none, is the servo's (B002).
"""


def expected_latency(return_delay):
    """The reply latency a return_delay means (table 4.6, No. 7): 100 us + 50 us x return_delay, in
    seconds; for one servo, or a column of them."""
    return 100e-6 + 50e-6 * return_delay


def reply_due(lint, req) -> float:
    """Seconds after the end of ``req`` until which its reply was still due (see _TIMING)."""
    ev = req.event
    sh = lint.servos.get(ev.id)
    rd = sh.return_delay if sh is not None and sh.return_delay is not None else 0
    rr = ev.read_range
    size = 1 if rr is None else FRAME_OVERHEAD + rr[1]
    due = expected_latency(rd) + size * lint.byte_time + lint.config.latency_margin
    return min(due, lint.config.reply_timeout)


def _asked(rec) -> str:
    if rec.expects == "ack":
        return "an ACK"
    names = rec.read_names
    if len(names) > 3:  # the whole range, never cut ("..."): machine formats carry the message as it is
        address, length = rec.event.read_range
        named = [n for n in names if not n.startswith("reserved")] or names
        return f"a return of addresses {address}-{address + length - 1} ({named[0]} to {named[-1]})"
    return f"a return of {', '.join(names)}"


@rule("B001", "request-before-return", "error", "A new request while a reply was still due.", f"""
## What it does
Flags a request sent while an earlier request's reply was still due and had not come yet. The finding is on the new request. Needs timestamps.
{_TIMING}
## Why it matters
The bus is half duplex: the manual says not to send anything until the return has been received. The
servo's reply and the host's next packet collide, both are lost, and the host may blame the servo.

## Example
{example((0.0, _READ), (0.0012, _POLL2), note="two polls 0.5 ms apart, the first never answered:")}
""", kinds=("request",), needs_time=True, when="settles", column="silent")
def request_before_return(lint, rec, ev):
    p = lint.missing
    if p is None or p.resolved_by is not rec or not p.event.checksum_ok:
        return
    t1 = p.event[T_END]
    if t1 is None or ev[T_START] is None:
        return
    gap = ev[T_START] - t1
    if gap <= reply_due(lint, p):
        # A gap the clock puts at or below zero is no duration to print (F005/F006 say why).
        when = f"{gap * 1e3:.3f} ms after" if gap > 0 else "right after"
        lint.emit("B001", rec, f"sent {when} request @{p.offset} to ID {p.id}, whose reply was still due")


@rule("B002", "missing-return", "error", "A request that asked for a reply got none.", f"""
## What it does
Flags a request that asked for an ACK/NACK or a return when no reply followed before the next request
or the reply timeout. A request still waiting when the capture (or a time segment, F010) ends is not
flagged, unless the capture ran on past its reply timeout: its reply may have come after the capture
stopped. Broadcast requests are P010's business.
{_TIMING}
## Why it matters
A servo that does not answer is unpowered, on another ID or baud rate, has rejected the packet, or
is answering too late (return_delay). A control loop that waits for it stalls or runs on old data.

## Example
{example(_READ, _POLL2, encode_return(2, 0x2A, bytes.fromhex("0000")), note="ID 1 never answers; ID 2 does:")}
""", kinds=("short",), when="unpaired", column="silent")
def missing_return(lint, rec, ev):
    if rec.status != MISSING or ev.id == BROADCAST_ID:
        return
    by = rec.resolved_by
    if by is not None:
        if by.event[OFFSET] > ev.end_offset:
            return  # bytes came back in the reply's place: the framing and collision rules describe them
        if lint.timed and by.is_request and by.event[T_START] is not None and ev[T_END] is not None \
                and by.event[T_START] - ev[T_END] <= reply_due(lint, rec):
            return  # the host did not wait: B001
    # Ended by time (a later record past the reply timeout, or the end of a capture that ran on past it):
    # whatever comes later, even from this ID, came too late to be its reply (B003 says so).
    late = " within the reply timeout" if by is None or not by.is_request else ""
    lint.emit("B002", rec, f"ID {ev.id} did not answer{late}; the request asked for {_asked(rec)}")


@rule("B003", "unsolicited-return", "warning", "A reply no request asked for.", f"""
## What it does
Flags a return, ACK or NACK that no request asked for: the latest request asked for none, or its reply
timeout had passed, or it had its reply already and this one is no second reply to it (a return from an
ID that was neither asked nor answered; B009 is for a second one). The message says how the reply
stands to the latest request. Not the first reply of a capture (or of a time segment, F010) that comes
within the reply timeout of its start: that one answers a request sent before the capture began.

## Why it matters
Either a second host is on the bus, a servo answers to the wrong packets, or a reply came so late that
the host had given up on it and will read it as the answer to its next question.

## Example
{example(encode_short(1, 0, 0x1E, bytes.fromhex("8403")), _RET, note="a write that asked for nothing, then a return:")}
""", kinds=("reply",), when="unpaired", column="silent")
def unsolicited_return(lint, rec, ev):
    if rec.status != UNSOLICITED:
        return
    who = f" from ID {ev.id}" if ev.kind == "return" else ""
    what = ev.kind.upper() if ev.kind != "return" else "return"
    lint.emit("B003", rec, f"{what}{who} that no request asked for{_since_request(lint.last_request, ev)}")


def _since_request(req, ev) -> str:
    """How an unsolicited reply stands to the latest request before it (None: none in this capture, or
    since the seam): what the pairing saw, in facts the bytes show."""
    if req is None:
        return ""
    r = req.event
    gap = None if ev[T_START] is None or r[T_END] is None else ev[T_START] - r[T_END]
    when = f"{gap * 1e3:.3f} ms after" if gap is not None and gap > 0 else "after"  # never a held clock's 0
    to = f"request @{req.offset} to ID {r.id}" if r.kind == "short" else f"long packet @{req.offset}"
    if req.status == ANSWERED:
        return f"; {when} {to}, which had its reply"
    if req.status == MISSING:  # ended by time: a later request would be the latest one
        return f"; {when} {to}, past its reply timeout"
    if req.expects is None:
        return f"; {when} {to}, which asked for no reply"
    return f"; {when} {to}"


@rule("B004", "return-id-mismatch", "error", "A return from another ID than the one asked.", f"""
## What it does
Flags a return whose ID differs from the ID of the request it answers: the first reply within that
request's reply timeout. A return from another ID after the request had its reply, or after the timeout,
answers nothing: B003.

## Why it matters
Two servos share a bus position in the host's map, a servo's ID was changed without the host knowing,
or a servo answered a packet meant for another: the host files data under the wrong joint.

## Example
{example(_READ, encode_return(2, 0x2A, bytes.fromhex("8403")))}
""", kinds=("return",), column="header")
def return_id_mismatch(lint, rec, ev):
    req = rec.request
    if rec.status == PAIRED and req is not None and req.event.id != BROADCAST_ID and req.event.id != ev.id:
        lint.emit("B004", rec, f"return from ID {ev.id} answers request @{req.offset} to ID {req.event.id}")


@rule("B005", "return-range-mismatch", "error", "A reply that does not carry what was asked.", f"""
## What it does
Flags a return whose address or length differs from the range the request's flag asked for (table 4.3,
or the flag-0F address and length), a return where an ACK was asked, and an ACK where a return was
asked.

## Why it matters
The host parses the data at the offsets it asked for; a different range puts positions in the
temperature field and so on. It means a firmware difference, or a reply to some other request.

## Example
{example(_READ, encode_return(1, 0x2C, bytes.fromhex("0000")))}
""", kinds=("return", "ack"), column="header")
def return_range_mismatch(lint, rec, ev):
    req = rec.request
    if rec.status != PAIRED or req is None:
        return
    if ev.kind == "ack":
        if req.expects == "return":
            lint.emit("B005", rec, f"ACK where request @{req.offset} asked for a return")
        return
    if req.expects == "ack":
        lint.emit("B005", rec, f"return where request @{req.offset} asked for an ACK")
        return
    rr = req.event.read_range
    if rr is not None and (ev.address, ev.length) != rr:
        lint.emit("B005", rec, f"returns {ev.length} byte(s) from address {ev.address}; request @{req.offset} "
                               f"asked for {rr[1]} from {rr[0]}")


def latency_off(lint, latency, expected):
    """Whether a reply's latency (or each of a column of them) is off the expected one by more than
    latency-margin: B006's test, on the record path and the column path alike."""
    return abs(latency - expected) > lint.config.latency_margin


def _return_latency_columns(view) -> bool:
    """B006 on a Block: every reply's latency within the margin of its servo's return delay."""
    if not view.timed:
        return True
    replies, lat = view.blk.reply_latencies()
    if not replies.size:
        return True
    # The answering servos' return delay (0 while unknown), as return_latency reads it.
    rd = view.shadows("return_delay")[view.ids[replies]]
    return not latency_off(view.lint, lat, expected_latency(np.where(rd == UNKNOWN, 0, rd))).any()


@rule("B006", "return-latency", "warning", "A reply much earlier or later than the servo's return delay.", f"""
## What it does
Flags a reply whose latency (from the end of the request to the start of the reply) differs from the
servo's return delay, 100 us + 50 us x return_delay (table 4.6, No. 7), by more than `latency-margin`
(default 2 ms). The return_delay the linter last saw written or read for the servo that answered (the
ID its return names; for an ACK/NACK, the ID asked) is used, or the default 0. Needs timestamps.

## Why it matters
A host loop budgets its cycle on the reply delay; a servo that answers late (a larger return_delay
than the host expects, an overloaded servo) eats into the next cycle and eventually causes B001 or
B002. An impossibly early reply points at wrong timestamps or a second host.

## Example
{example((0.0, _READ), (0.0106, _RET), note="a return 10 ms after the request, with return_delay 0:")}
""", kinds=("reply",), needs_time=True, column=_return_latency_columns)
def return_latency(lint, rec, ev):
    lat = rec.latency
    if lat is None or rec.status != PAIRED:
        return
    req = rec.request
    # The servo that answered sets the delay (a return names it; an ACK/NACK is the asked servo's).
    sid = ev.id if ev.kind == "return" else req.event.id if req is not None else None
    sh = lint.servos.get(sid)
    rd = sh.return_delay if sh is not None and sh.return_delay is not None else None
    expected = expected_latency(rd or 0)
    if latency_off(lint, lat, expected):
        lint.emit("B006", rec, f"reply {lat * 1e3:.3f} ms after the request; return_delay "
                               f"{rd if rd is not None else '0 (assumed)'} means {expected * 1e3:.3f} ms", sid=sid)


@rule("B007", "bus-collision", "error", "A frame that starts inside another.", f"""
## What it does
Flags a frame whose first byte comes right where a cut-short frame stopped, with no idle gap between
them: the new frame began while the other was still on the wire. With timestamps, an idle gap longer
than the decoder's gap (20 byte times) means the first sender stopped on its own (F003 alone).
The finding is on the frame that started inside the other; the cut frame gets F003.

## Why it matters
Two devices talked at once on the half-duplex line: a host that did not wait for a return, two
servos with one ID, or a second host. Both frames are damaged; the one that survives may be misread.

## Example
{example(encode_short(1, 0x09, 0, b"", length=0, count=1)[:6] + _RET, note="a poll of ID 1 cut off by a return that started inside it:")}
""", kinds=("packet", "corrupt"), when="after-cut", column="silent")
def bus_collision(lint, rec, ev):
    if not follows_cut(lint.prev, ev[OFFSET]):
        return
    pe = lint.prev.event
    if pe[T_END] is not None and ev[T_START] is not None \
            and ev[T_START] - pe[T_END] > lint.config.gap_bytes * lint.byte_time:
        return
    lint.emit("B007", rec, f"frame starts inside the {len(pe[RAW])}-byte frame cut short at @{pe[OFFSET]}")


@rule("B008", "nack", "warning", "A servo answered NACK.", f"""
## What it does
Flags a NACK byte (08) that a servo sent in answer to a request asking for ACK/NACK (table 4.3, 0001).

## Why it matters
The servo received the packet but refused it: the host's write did not happen. Repeated NACKs mean a
malformed packet the host keeps sending.

## Example
{example(encode_short(1, 0x01, 0x1E, bytes.fromhex("8403")), bytes((NACK,)))}
""", kinds=("nack",), column="silent")
def nack(lint, rec, ev):
    req = rec.request
    lint.emit("B008", rec, f"NACK{f' from ID {req.event.id} to request @{req.offset}' if req is not None else ''}")


@rule("B009", "multiple-returns", "error", "Two replies to one request: two servos share an ID.", f"""
## What it does
Flags a second (or later) reply to a request that had its reply already, within the request's reply
timeout, from the ID asked or the ID whose return came first (an ACK or NACK carries no ID: a second one
to a request that asked for one). A return from another ID, or one after the timeout, is no second answer
to that request but a reply nobody asked for (B003). A request to ID 255 is P010's business instead.

## Why it matters
Only one servo should answer. Two answers mean two servos with the same ID: every write moves both
and every read is a collision waiting to happen.

## Example
{example(_READ, _RET, encode_return(1, 0x2A, bytes.fromhex("8003")))}
""", kinds=("reply",), when="unpaired", column="silent")
def multiple_returns(lint, rec, ev):
    req = rec.request
    if rec.status != EXTRA or req is None or req.event.id == BROADCAST_ID:
        return
    sid = ev.id if ev.kind == "return" else req.event.id  # an ACK/NACK names no ID: the one asked
    what = f"return from ID {sid}" if ev.kind == "return" else ev.kind.upper()
    lat = rec.latency
    when = f", {lat * 1e3:.3f} ms after it" if lat is not None else ""
    lint.emit("B009", rec, f"{what} is a second reply to request @{req.offset} to ID {req.event.id}{when}: "
                           f"two servos answer to ID {sid}", sid=sid)


_ = ACK  # (ACK is the byte the ACK events carry; kept for readers of the examples)
