"""Bus rules (B): request/reply pairing, timing and collisions on the half-duplex line."""

from __future__ import annotations

import numpy as np

from ...decode.pairing import ANSWERED, EXTRA, MISSING, PAIRED, UNSOLICITED
from ...protocol.events import OFFSET, RAW, T_END, T_START
from ...protocol.wire import ACK, BROADCAST_ID, FRAME_OVERHEAD, NACK, encode_read, encode_return, encode_short
from ..batch import UNKNOWN
from ..params import DURATION, Measured, said, said_as, said_keyed
from ..params import OFFSET as AT
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
    rr = req.read_range  # by table 4.3, or by its servo model's return_areas
    size = 1 if rr is None else FRAME_OVERHEAD + rr[1]
    due = expected_latency(rd) + size * lint.byte_time + lint.config.latency_margin
    return min(due, lint.config.reply_timeout)


# Messages are made by said() (lint.params): a stream offset (unit AT: events.OFFSET is the event's field), a
# time or a count this capture measured is a Measured value (``*`` in the finding's key, which a baseline
# fingerprints); IDs, register names and the rule's words name the behaviour and stay in the key.

def _asked(rec) -> str:
    if rec.expects == "ack":
        return "an ACK"
    names = rec.read_names
    if len(names) > 3:  # the whole range, never cut ("..."): machine formats carry the message as it is
        address, length = rec.read_range
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
        params = {"gap": Measured(gap, DURATION), "offset": Measured(p.offset, AT), "id": p.id}
        # A gap the clock puts at or below zero is no duration to print (F005/F006 say why): the words say
        # "right after", the key stays that of any gap.
        lint.emit("B001", rec, said(_B001, params) if gap > 0 else said_as(_B001, params, {"gap": "right"}))


_B001 = "sent {gap} after request @{offset} to ID {id}, whose reply was still due"


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
    lint.emit("B002", rec, said("ID {id} did not answer{late}; the request asked for {asked}",
                                {"id": ev.id, "late": late, "asked": _asked(rec)}))


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
    # An ACK or NACK names no ID.
    head, params = ("return from ID {id}", {"id": ev.id}) if ev.kind == "return" else (ev.kind.upper(), {})
    req = lint.last_request
    if req is None:  # none in this capture, or since the seam
        lint.emit("B003", rec, said(head + _B003, params))
        return
    since, gap = _since_request(req, ev, params)
    key = head + _B003 + "; after " + since
    # The gap is left out of the key: a held clock (or a capture without times) leaves it out of the words.
    text = head + _B003 + ("; {gap} after " if gap is not None and gap > 0 else "; after ") + since
    lint.emit("B003", rec, said_keyed(text, key, params))


_B003 = " that no request asked for"


def _since_request(req, ev, params: dict) -> tuple[str, float | None]:
    """How an unsolicited reply stands to the latest request before it, what the pairing saw in facts the
    bytes show: the template's words after "after" (their values put in ``params``), and the gap."""
    r = req.event
    gap = None if ev[T_START] is None or r[T_END] is None else ev[T_START] - r[T_END]
    params.update(offset=Measured(req.offset, AT), asked=r.id)
    if gap is not None:
        params["gap"] = Measured(gap, DURATION)
    to = "request @{offset} to ID {asked}" if r.kind == "short" else "long packet @{offset}"
    if req.status == ANSWERED:
        return to + ", which had its reply", gap
    if req.status == MISSING:  # ended by time: a later request would be the latest one
        return to + ", past its reply timeout", gap
    if req.expects is None:
        return to + ", which asked for no reply", gap
    return to, gap


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
        lint.emit("B004", rec, said("return from ID {id} answers request @{offset} to ID {asked}",
                                    {"id": ev.id, "offset": Measured(req.offset, AT), "asked": req.event.id}))


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
    # The addresses and lengths name the mismatch (a firmware's or a host's): they stay in the key.
    offset = Measured(req.offset, AT)
    if ev.kind == "ack":
        if req.expects == "return":
            lint.emit("B005", rec, said("ACK where request @{offset} asked for a return", {"offset": offset}))
        return
    if req.expects == "ack":
        lint.emit("B005", rec, said("return where request @{offset} asked for an ACK", {"offset": offset}))
        return
    rr = req.read_range  # by table 4.3, or by its servo model's return_areas (RS204MD's 0x0D: 60-127)
    if rr is not None and (ev.address, ev.length) != rr:
        lint.emit("B005", rec, said("returns {length} byte(s) from address {address}; request @{offset} asked for "
                                    "{asked_length} from {asked_address}",
                                    {"length": ev.length, "address": ev.address, "offset": offset,
                                     "asked_length": rr[1], "asked_address": rr[0]}))


def latency_off(lint, latency, expected):
    """Whether a reply's latency (or each of a column of them) is off the expected one by more than
    latency-margin: B006's test, on the record path and the column path alike."""
    return abs(latency - expected) > lint.config.latency_margin


def _return_latency_columns(view) -> bool | np.ndarray:
    """B006 on a Block: the replies whose latency is off the margin of their servo's return delay (their rows:
    a late reply now and then on a live port is cut out of its Block, Linter.feed_block)."""
    if not view.timed:
        return True
    replies, lat = view.blk.reply_latencies()
    if not replies.size:
        return True
    # The answering servos' return delay (0 while unknown), as return_latency reads it.
    rd = view.shadows("return_delay")[view.ids[replies]]
    return replies[latency_off(view.lint, lat, expected_latency(np.where(rd == UNKNOWN, 0, rd)))]


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
        # return_delay is a register value this capture showed (written or read); unseen, the manual's
        # default is assumed, in words that stay in the key.
        params = {"latency": Measured(lat, DURATION),
                  "return_delay": Measured(rd) if rd is not None else "0 (assumed)",
                  "expected": Measured(expected, DURATION)}
        lint.emit("B006", rec, said("reply {latency} after the request; return_delay {return_delay} means {expected}",
                                    params), sid=sid)


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
    # Where the other frame was cut (so its length) is the collision's timing: measured.
    lint.emit("B007", rec, said("frame starts inside the {size}-byte frame cut short at @{offset}",
                                {"size": Measured(len(pe[RAW])), "offset": Measured(pe[OFFSET], AT)}))


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
    if req is None:
        lint.emit("B008", rec, said("NACK", {}))
    else:
        lint.emit("B008", rec, said("NACK from ID {id} to request @{offset}",
                                    {"id": req.event.id, "offset": Measured(req.offset, AT)}))


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
    what = "return from ID {id}" if ev.kind == "return" else ev.kind.upper()
    lat = rec.latency
    params = {"id": sid, "offset": Measured(req.offset, AT), "asked": req.event.id}
    if lat is not None:
        params["latency"] = Measured(lat, DURATION)
    # The latency is left out of the key: a reply too soon after the request to time has none.
    key = what + _B009
    text = key if lat is None else what + _B009_TIMED
    lint.emit("B009", rec, said_keyed(text, key, params), sid=sid)


_B009 = " is a second reply to request @{offset} to ID {asked}: two servos answer to ID {id}"
_B009_TIMED = " is a second reply to request @{offset} to ID {asked}, {latency} after it: two servos answer to ID {id}"


_ = ACK  # (ACK is the byte the ACK events carry; kept for readers of the examples)
